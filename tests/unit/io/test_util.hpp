#pragma once
// Helpers of the zerog::io tests: a fresh temporary folder per test, file writing, and checks
// of InputError positions.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>

#include "zerog/formats/log.hpp"

namespace zerog::io::test {

class TempDirTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (std::filesystem::temp_directory_path() / "zerog_io_XXXXXX").string();
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
  }
  void TearDown() override {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  std::filesystem::path path(const std::string& name) const { return dir_ / name; }

  std::filesystem::path dir_;
};

inline void write_text(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  ASSERT_TRUE(out.good()) << path;
}

inline std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// Runs `fn`, expects an InputError at file:line:column whose message contains `part`.
inline void expect_input_error(const std::function<void()>& fn, const std::filesystem::path& file,
                               int line, int column, const std::string& part) {
  try {
    fn();
    ADD_FAILURE() << "no InputError thrown (expected " << file << ":" << line << ":" << column
                  << ": …" << part << "…)";
  } catch (const formats::InputError& e) {
    EXPECT_EQ(e.file(), file) << e.what();
    EXPECT_EQ(e.line(), line) << e.what();
    EXPECT_EQ(e.column(), column) << e.what();
    EXPECT_NE(std::string(e.what()).find(part), std::string::npos)
        << "message '" << e.what() << "' lacks '" << part << "'";
    const std::string prefix =
        file.string() + ":" + std::to_string(line) + ":" + std::to_string(column) + ": ";
    if (line > 0 && column > 0) {
      EXPECT_EQ(std::string(e.what()).rfind(prefix, 0), 0u) << e.what();
    }
  }
}

}  // namespace zerog::io::test
