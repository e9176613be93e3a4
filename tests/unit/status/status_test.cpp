// zerog::Status: success allocates nothing; a failure keeps its code, setting and message apart;
// within() names the setting from an enclosing structure; copies are deep.
#include "zerog/status.hpp"

#include <gtest/gtest.h>

#include "alloc_count.hpp"

namespace zerog {
namespace {

Status succeed() { return {}; }
Status refuse_port() { return Status::invalid("port", "must be 0..65535, is 70000"); }

TEST(Status, SuccessHoldsNothingAndAllocatesNothing) {
  test::AllocGuard guard("Status success", test::AllocGuard::Mode::abort);
  const Status st = succeed();
  const Status moved = Status(succeed());
  const bool ok = st.ok() && moved.ok() && st.code() == StatusCode::ok && st.setting().empty() &&
                  st.message().empty();
  guard.stop();
  EXPECT_TRUE(ok);
  EXPECT_EQ(guard.allocations(), 0u);
  EXPECT_EQ(st.text(), "");
}

TEST(Status, AFailureKeepsCodeSettingAndMessageApart) {
  const Status st = refuse_port();
  EXPECT_FALSE(st.ok());
  EXPECT_EQ(st.code(), StatusCode::invalid_setting);
  EXPECT_STREQ(status_code_name(st.code()), "invalid_setting");
  EXPECT_EQ(st.setting(), "port");
  EXPECT_EQ(st.message(), "must be 0..65535, is 70000");
  EXPECT_EQ(st.text(), "port: must be 0..65535, is 70000");

  const Status io(StatusCode::system_error, "cannot bind 127.0.0.1:502: Permission denied");
  EXPECT_EQ(io.setting(), "");
  EXPECT_EQ(io.text(), "cannot bind 127.0.0.1:502: Permission denied");
  // A failure is never ok, whatever code it was given.
  EXPECT_FALSE(Status(StatusCode::ok, "x", "y").ok());
}

TEST(Status, WithinNamesTheSettingFromTheEnclosingTableOrPrefixesTheMessage) {
  const Status setting = refuse_port().within("modbus");
  EXPECT_EQ(setting.setting(), "modbus.port");
  EXPECT_EQ(setting.message(), "must be 0..65535, is 70000");
  const Status plain =
      Status(StatusCode::system_error, "dds_create_domain failed").within("telemetry");
  EXPECT_EQ(plain.setting(), "");
  EXPECT_EQ(plain.text(), "telemetry: dds_create_domain failed");
  EXPECT_TRUE(succeed().within("modbus").ok());
}

TEST(Status, CopiesAreIndependent) {
  Status a = refuse_port();
  Status b = a;
  a = std::move(a).within("modbus");
  EXPECT_EQ(a.setting(), "modbus.port");
  EXPECT_EQ(b.setting(), "port");
  b = Status{};
  EXPECT_TRUE(b.ok());
  b = a;
  EXPECT_EQ(b.text(), a.text());
}

}  // namespace
}  // namespace zerog
