// `zerog servo` as a user runs it (docs/zerog-rt.md, "Identifying the servo model"): a zerog-rt
// recording's cycles.csv in, the servo_hz to set (or why not) out, the exit status saying which,
// the recording untouched and nothing written beside it.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>

#include <unistd.h>

#include "servo_recording.hpp"
#include "zerog/formats/cycles_csv.hpp"

namespace fs = std::filesystem;
using ::testing::HasSubstr;

namespace {

struct Result {
  int status;
  std::string out, err;
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

class ServoCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("zerog_servo_cli_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "rec");
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path write_cycles(const std::vector<zerog::loop::CycleRecord>& records) {
    std::string text;
    zerog::formats::append_record_header(text);
    for (const auto& r : records) zerog::formats::append_record_row(r, text);
    const fs::path p = dir_ / "rec" / "cycles.csv";
    std::ofstream(p, std::ios::binary) << text;
    return p;
  }

  Result run(const std::string& args) {
    const fs::path out = dir_ / "stdout.txt", err = dir_ / "stderr.txt";
    const std::string cmd =
        std::string(ZEROG_EXE) + " " + args + " >" + out.string() + " 2>" + err.string();
    const int raw = std::system(cmd.c_str());
    Result r{WIFEXITED(raw) ? WEXITSTATUS(raw) : -1, slurp(out), slurp(err)};
    fs::remove(out);
    fs::remove(err);
    return r;
  }

  fs::path dir_;
};

TEST_F(ServoCli, PrintsTheServoHzToSetAndTouchesNothing) {
  const fs::path cycles =
      write_cycles(zerog::test::servo_recording(zerog::test::servo_pushes(2000, 8, 11), 6.5, 2));
  const std::string before = slurp(cycles);
  Result r = run("servo " + cycles.string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("L = 2 (as zerog-rt's servo model assumes)"));
  EXPECT_THAT(r.out, HasSubstr("set [filter] servo_hz = 6.5 in zerog-rt's configuration"));
  EXPECT_EQ(r.err, "");

  r = run("servo --json " + cycles.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["kind"], "zerog-servo");
  EXPECT_EQ(j["version"], 1);
  EXPECT_TRUE(j["known"].get<bool>());
  EXPECT_NEAR(j["servo_hz"].get<double>(), 6.5, 0.065);
  EXPECT_EQ(j["lag_rows"], 2);
  EXPECT_EQ(j["quarters"].size(), 4u);
  EXPECT_TRUE(j["rig"].is_null());  // AKorr: no robot needed, none beside the recording

  // Nothing written: the recording as it was, and nothing beside it.
  EXPECT_EQ(slurp(cycles), before);
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_ / "rec"), fs::directory_iterator{}), 1);
}

TEST_F(ServoCli, SaysWhyItCannotTellAndExitsOne) {
  const fs::path still =
      write_cycles(zerog::test::servo_recording(zerog::test::servo_pushes(2000, 0, 12), 6.5, 2));
  Result r = run("servo " + still.string());
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.err, HasSubstr("commanded no motion"));
  EXPECT_THAT(r.out, ::testing::Not(HasSubstr("set [filter] servo_hz")));
  r = run("servo --json " + still.string());
  EXPECT_EQ(r.status, 1);
  EXPECT_FALSE(nlohmann::json::parse(r.out)["known"].get<bool>());

  r = run("servo " + (dir_ / "rec" / "missing.csv").string());
  EXPECT_NE(r.status, 0);
  EXPECT_THAT(r.err, HasSubstr("missing.csv"));

  std::ofstream(dir_ / "rec" / "cycles.csv") << "cycle,ipoc\n1,2\n";
  r = run("servo " + (dir_ / "rec" / "cycles.csv").string());
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.err, HasSubstr("cycles.csv"));
}

}  // namespace
