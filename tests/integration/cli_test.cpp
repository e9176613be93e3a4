// The `zerog` program as a user runs it: every subcommand has --help, --json output parses,
// errors name file, line and column, inputs are never overwritten, failed runs write nothing.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include <unistd.h>

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

struct Result {
  int status = -1;
  std::string out, err;
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

class Cli : public ::testing::Test {
 protected:
  // One folder per process: ctest runs each test in its own process, possibly in parallel.
  static fs::path dir() {
    return fs::temp_directory_path() / ("zerog_cli_test_" + std::to_string(getpid()));
  }
  static void TearDownTestSuite() { fs::remove_all(dir()); }
  static void SetUpTestSuite() {
    fs::remove_all(dir());
    fs::create_directories(dir());
    const Result r = run("sim --kind random --points 24 --seed 5 --effects cable --out " +
                         (dir() / "run.csv").string());
    ASSERT_EQ(r.status, 0) << r.err;
  }
  static Result run(const std::string& args) {
    const fs::path out = dir() / "stdout.txt", err = dir() / "stderr.txt";
    const std::string cmd =
        std::string(ZEROG_EXE) + " " + args + " >" + out.string() + " 2>" + err.string();
    const int rc = std::system(cmd.c_str());
    return {WIFEXITED(rc) ? WEXITSTATUS(rc) : -1, slurp(out), slurp(err)};
  }
  static std::string log() { return (dir() / "run.csv").string(); }
};

TEST_F(Cli, EverySubcommandHasHelp) {
  for (const char* sub : {"import", "design", "sim", "fit", "compare", "diagnose", "ladder",
                          "report", "train", "results", "export", "decode-can"}) {
    const Result r = run(std::string(sub) + " --help");
    EXPECT_EQ(r.status, 0) << sub;
    EXPECT_THAT(r.out, HasSubstr(sub)) << sub;
    EXPECT_THAT(r.out, HasSubstr("--")) << sub;
  }
  EXPECT_EQ(run("--help").status, 0);
  EXPECT_NE(run("no-such-command").status, 0);
}

TEST_F(Cli, FitCompareDiagnoseLadderPrintJsonOfTheDocumentedKinds) {
  const std::string model = (dir() / "fit.json").string();
  Result r = run("fit " + log() + " --json -q --out " + model);
  ASSERT_EQ(r.status, 0) << r.err;
  auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["kind"], "zerog-fit");
  EXPECT_TRUE(j["extra"]["fit"]["usable"].get<bool>());
  EXPECT_TRUE(fs::exists(model));

  r = run("compare " + log() + " --model " + model + " --json -q");
  ASSERT_EQ(r.status, 0) << r.err;
  j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["kind"], "zerog-compare");
  EXPECT_EQ(j["segments"]["all"]["rms"].size(), 6u);
  EXPECT_EQ(j["joint_bins"].size(), 6u);

  r = run("diagnose " + log() + " --model " + model + " --block 20 --json -q");
  ASSERT_EQ(r.status, 0) << r.err;
  j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["kind"], "zerog-diagnosis");
  EXPECT_EQ(j["verdict"]["kind"], "effect");
  EXPECT_EQ(j["verdict"]["effect"], "cable");
  EXPECT_THAT(j["verdict"]["command"].get<std::string>(),
              HasSubstr("--effects bias,gravity,linear_inertia,rotational_inertia,cable"));

  r = run("ladder " + log() + " --block 20 --json -q");
  ASSERT_EQ(r.status, 0) << r.err;
  j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["kind"], "zerog-ladder");
  ASSERT_GE(j["steps"].size(), 3u);
  EXPECT_TRUE(j["steps"][0]["added"].is_null());
}

TEST_F(Cli, NeverOverwritesItsInput) {
  const std::string before = slurp(log());
  const Result r = run("fit " + log() + " -q --out " + log());
  EXPECT_NE(r.status, 0);
  EXPECT_THAT(r.err, HasSubstr("input"));
  EXPECT_EQ(slurp(log()), before);
}

TEST_F(Cli, AFailedFitWritesNothing) {
  const fs::path model = dir() / "never.json";
  Result r = run("fit " + log() + " -q --effects bias,gravity,warp_drive --out " + model.string());
  EXPECT_NE(r.status, 0);
  EXPECT_THAT(r.err, HasSubstr("unknown effect 'warp_drive'"));
  EXPECT_FALSE(fs::exists(model));
  // An effect without the effect it builds on is refused, naming both.
  r = run("fit " + log() + " -q --effects bias,gravity,imu_time_offset --out " + model.string());
  EXPECT_NE(r.status, 0);
  EXPECT_THAT(r.err, HasSubstr("'imu_time_offset' builds on 'linear_inertia'"));
  EXPECT_FALSE(fs::exists(model));
  for (const auto& e : fs::directory_iterator(dir()))
    EXPECT_THAT(e.path().filename().string(), ::testing::Not(HasSubstr(".tmp")));
}

TEST_F(Cli, ABadCellIsReportedWithFileLineAndColumn) {
  // Copy the log and its rig, break one cell on data line 7, keep the rest.
  const fs::path bad = dir() / "bad.csv";
  fs::copy_file(dir() / "run.rig.toml", dir() / "bad.rig.toml",
                fs::copy_options::overwrite_existing);
  std::istringstream in(slurp(log()));
  std::ofstream out(bad);
  std::string line;
  int n = 0, target_line = 0;
  while (std::getline(in, line)) {
    ++n;
    if (n > 2 && line[0] != '#' && target_line == 0 && n >= 9) {
      const auto comma = line.find(',');
      line = line.substr(0, comma + 1) + "1.2.3" + line.substr(line.find(',', comma + 1));
      target_line = n;
    }
    out << line << "\n";
  }
  out.close();
  const Result r = run("fit " + bad.string() + " -q");
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr(bad.string() + ":" + std::to_string(target_line) + ":"));
  EXPECT_THAT(r.err, HasSubstr("1.2.3"));
}

}  // namespace
