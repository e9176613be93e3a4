// proto/modbus.md and the code agree: the register tables between the markers are exactly what
// register_map_markdown() produces from the one table in register_map.cpp.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>

#include "zerog/modbus/register_map.hpp"

namespace zerog::modbus {
namespace {

constexpr const char* kBegin = "<!-- BEGIN register map: generated from register_map.cpp -->\n";
constexpr const char* kEnd = "<!-- END register map -->";

TEST(ModbusDoc, RegisterTablesInProtoMatchTheCode) {
  const std::string path = ZEROG_SOURCE_DIR "/proto/modbus.md";
  std::ifstream in(path);
  ASSERT_TRUE(in) << "cannot read " << path;
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string doc = ss.str();
  const std::size_t begin = doc.find(kBegin);
  const std::size_t end = doc.find(kEnd);
  const std::string expected = register_map_markdown();
  // For a developer: the block to paste (also written next to the build).
  const std::string out_path = ZEROG_BINARY_DIR "/modbus_register_map.md";
  std::ofstream(out_path) << kBegin << "\n" << expected << kEnd << "\n";
  ASSERT_NE(begin, std::string::npos) << path << ": marker missing: " << kBegin;
  ASSERT_NE(end, std::string::npos) << path << ": marker missing: " << kEnd;
  ASSERT_LT(begin, end);
  const std::size_t from = begin + std::string(kBegin).size();
  std::string actual = doc.substr(from, end - from);
  // One blank line after the BEGIN marker is allowed.
  if (!actual.empty() && actual.front() == '\n') actual.erase(0, 1);
  EXPECT_EQ(actual, expected) << path
                              << " differs from the register map in the code; paste this "
                                 "between the markers (also in "
                              << out_path << "):\n"
                              << expected;
}

}  // namespace
}  // namespace zerog::modbus
