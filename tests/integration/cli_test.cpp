// The `zerog` program as a user runs it: every subcommand has --help, --json output parses,
// errors name file, line and column, inputs are never overwritten, failed runs write nothing.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include <unistd.h>

#include "zerog/infer/deploy_file.hpp"

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

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
  // What it was made for: the model (sorted names, its file and CRC-32) and the log.
  EXPECT_EQ(j["version"], 3);
  EXPECT_EQ(j["events"].size(), 0u);
  EXPECT_EQ(j["made_for"]["model"]["effects"],
            nlohmann::json({"bias", "gravity", "linear_inertia", "rotational_inertia"}));
  EXPECT_EQ(j["made_for"]["model"]["file"], model);
  EXPECT_EQ(j["made_for"]["model"]["crc32"].get<std::string>().size(), 8u);
  EXPECT_EQ(j["made_for"]["log"]["file"], log());
  {
    // The log's CRC-32 (read a MiB at a time) is that of its whole contents (many MiB).
    std::ifstream in(log(), std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    ASSERT_GT(bytes.size(), 3u << 20);
    char hex[9];
    std::snprintf(hex, sizeof hex, "%08x", zerog::infer::crc32(bytes));
    EXPECT_EQ(j["made_for"]["log"]["crc32"], hex);
  }
  EXPECT_EQ(j["made_for"]["log"]["rig_file"], (dir() / "run.rig.toml").string());
  // Candidates screened by default; --exact-candidates refits each, to the same verdict.
  EXPECT_EQ(j["candidate_evaluation"]["method"], "screened");
  r = run("diagnose " + log() + " --model " + model + " --block 20 --exact-candidates --json -q");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto exact = nlohmann::json::parse(r.out);
  EXPECT_EQ(exact["candidate_evaluation"]["method"], "refitted");
  EXPECT_EQ(exact["verdict"]["command"], j["verdict"]["command"]);

  r = run("ladder " + log() + " --block 20 --json -q");
  ASSERT_EQ(r.status, 0) << r.err;
  j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["kind"], "zerog-ladder");
  r = run("ladder " + log() + " --block 20 --exact-candidates --json -q");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["steps"], j["steps"]);
  ASSERT_GE(j["steps"].size(), 3u);
  EXPECT_TRUE(j["steps"][0]["added"].is_null());
  EXPECT_TRUE(j["made_for"]["model"].is_null());  // a ladder is made for its log
  EXPECT_EQ(j["made_for"]["start"], nlohmann::json({"bias", "gravity"}));
  EXPECT_EQ(j["made_for"]["log"]["file"], log());
}

// --engine on fit (and diagnose, ladder): the normal equations (the default), the block
// statistics and the per-sample reference give the same parameters and standard deviations
// through the CLI, and the fit says which engine ran; an engine the fit does not know is refused.
TEST_F(Cli, FitEnginesGiveTheSameParameters) {
  const std::string fit = "fit " + log() +
                          " --effects bias,gravity,linear_inertia,rotational_inertia,cable"
                          " --json -q";
  Result r = run(fit);
  ASSERT_EQ(r.status, 0) << r.err;
  const nlohmann::json by_default = nlohmann::json::parse(r.out);
  EXPECT_EQ(by_default["extra"]["fit"]["engine"], "normal");
  r = run(fit + " --engine normal");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["parameters"], by_default["parameters"]);  // deterministic
  r = run(fit + " --engine samples");
  ASSERT_EQ(r.status, 0) << r.err;
  const nlohmann::json samples = nlohmann::json::parse(r.out);
  EXPECT_EQ(samples["extra"]["fit"]["engine"], "samples");
  r = run(fit + " --engine block_stats");
  ASSERT_EQ(r.status, 0) << r.err;
  const nlohmann::json block_stats = nlohmann::json::parse(r.out);
  EXPECT_EQ(block_stats["extra"]["fit"]["engine"], "block_stats");

  for (const nlohmann::json* engine : {&block_stats, &by_default}) {
    SCOPED_TRACE(engine == &block_stats ? "block_stats" : "normal");
    const auto& got = (*engine)["parameters"];
    const auto& ref = samples["parameters"];
    ASSERT_EQ(got.size(), 5u);
    ASSERT_EQ(ref.size(), got.size());
    int compared = 0;
    for (const auto& [effect, block] : ref.items()) {
      ASSERT_TRUE(got.contains(effect)) << effect;
      for (const auto& [name, p] : block.items()) {
        const auto& q = got[effect][name];
        ASSERT_TRUE(p["std"].is_number() && q["std"].is_number()) << effect << "." << name;
        const double sd = p["std"].get<double>();
        // Relative to the value, or to its standard deviation for a value near zero.
        const double scale = std::max(std::abs(p["value"].get<double>()), sd);
        EXPECT_NEAR(q["value"].get<double>(), p["value"].get<double>(), 1e-6 * scale)
            << effect << "." << name;
        EXPECT_NEAR(q["std"].get<double>(), sd, 1e-6 * sd) << "std of " << effect << "." << name;
        ++compared;
      }
    }
    // bias 6, gravity 4, linear_inertia none (it uses the mass), rotational_inertia 6, cable 36.
    EXPECT_EQ(compared, 6 + 4 + 6 + 36);
  }

  for (const char* sub : {"fit", "diagnose", "ladder"})
    EXPECT_THAT(run(std::string(sub) + " --help").out, HasSubstr("--engine")) << sub;
  r = run("fit " + log() + " --engine exact -q");
  EXPECT_NE(r.status, 0);
  EXPECT_THAT(r.err, HasSubstr("--engine"));
  r = run("diagnose " + log() + " --engine exact -q");
  EXPECT_NE(r.status, 0);
}

// zerog sim writes the clean log beside the log and names it in the truth; compare and ladder
// --truth give both floors (all, static, moving), the sensor floor below the reference; a truth
// that names no clean log gives the reference only and says why.
TEST_F(Cli, SimWritesTheCleanLogAndCompareAndLadderGiveBothFloors) {
  ASSERT_TRUE(fs::exists(dir() / "run.clean.csv"));
  ASSERT_TRUE(fs::exists(dir() / "run.clean.rig.toml"));
  const std::string truth = (dir() / "run.truth.json").string();
  auto t = nlohmann::json::parse(slurp(truth));
  EXPECT_EQ(t["extra"]["clean_signals_log"], "run.clean.csv");
  const std::string model = (dir() / "floors_fit.json").string();
  Result r = run("fit " + log() +
                 " -q --effects bias,gravity,linear_inertia,rotational_inertia,"
                 "cable --out " +
                 model);
  ASSERT_EQ(r.status, 0) << r.err;

  r = run("compare " + log() + " --model " + model + " --truth " + truth + " --json -q");
  ASSERT_EQ(r.status, 0) << r.err;
  auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["kind"], "zerog-compare");
  EXPECT_EQ(j["version"], 2);
  EXPECT_FALSE(j.contains("noise_floor"));
  for (const char* g : {"all", "static", "moving"}) {
    const auto& ref = j["true_model_reference"][g];
    const auto& sensor = j["sensor_floor"][g];
    ASSERT_TRUE(ref.is_object() && sensor.is_object()) << g;
    EXPECT_EQ(ref["count"], j["samples"][g == std::string("all") ? "total" : g]) << g;
    EXPECT_LT(sensor["force_rms"].get<double>(), ref["force_rms"].get<double>()) << g;
    EXPECT_LT(sensor["torque_rms"].get<double>(), ref["torque_rms"].get<double>()) << g;
  }
  // The F/T noise: 0.25 N and 0.03 N·m white, plus the Omega191's steps.
  EXPECT_NEAR(j["sensor_floor"]["all"]["force_rms"].get<double>(), 0.285, 0.03);
  EXPECT_EQ(j["clean_signals_log"], (dir() / "run.clean.csv").string());
  EXPECT_TRUE(j["sensor_floor_note"].is_null());

  r = run("compare " + log() + " --model " + model + " --truth " + truth + " -q");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("true-model reference: force"));
  EXPECT_THAT(r.out, HasSubstr("sensor floor: force"));

  r = run("ladder " + log() + " --block 20 --truth " + truth + " --json -q");
  ASSERT_EQ(r.status, 0) << r.err;
  j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["kind"], "zerog-ladder");
  EXPECT_EQ(j["version"], 3);
  EXPECT_LT(j["sensor_floor"]["moving"]["force_rms"].get<double>(),
            j["true_model_reference"]["moving"]["force_rms"].get<double>());

  // An older truth (no clean log named): the reference only, and why.
  t["extra"].erase("clean_signals_log");
  const std::string old_truth = (dir() / "old.truth.json").string();
  std::ofstream(old_truth) << t.dump(2);
  r = run("compare " + log() + " --model " + model + " --truth " + old_truth + " --json -q");
  ASSERT_EQ(r.status, 0) << r.err;
  j = nlohmann::json::parse(r.out);
  EXPECT_TRUE(j["true_model_reference"]["moving"].is_object());
  EXPECT_TRUE(j["sensor_floor"].is_null());
  EXPECT_THAT(j["sensor_floor_note"].get<std::string>(), HasSubstr("names no noise-free log"));
  r = run("compare " + log() + " --model " + model + " --truth " + old_truth + " -q");
  EXPECT_THAT(r.out, HasSubstr("sensor floor: not known"));

  // Without --truth: neither.
  r = run("compare " + log() + " --model " + model + " --json -q");
  j = nlohmann::json::parse(r.out);
  EXPECT_TRUE(j["true_model_reference"].is_null());
  EXPECT_TRUE(j["sensor_floor"].is_null());
}

TEST_F(Cli, ReportShowsBothFloors) {
  const std::string model = (dir() / "report_fit.json").string();
  Result r = run("fit " + log() + " -q --out " + model);
  ASSERT_EQ(r.status, 0) << r.err;
  const fs::path out = dir() / "report";
  r = run("report " + log() + " --model " + model + " --truth " +
          (dir() / "run.truth.json").string() + " --out " + out.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string page = slurp(out / "index.html");
  EXPECT_THAT(page, HasSubstr("true-model reference RMS"));
  EXPECT_THAT(page, HasSubstr("sensor floor RMS"));
  EXPECT_THAT(page, HasSubstr("<b>Sensor floor</b>"));
  EXPECT_THAT(page, ::testing::Not(HasSubstr("No sensor floor")));
}

// zerog report takes a diagnosis as its verdict only when it was made for the model and log it
// reports on ("made_for"); one of another model or log is refused with exit status 2 naming both,
// or, with --allow-other-diagnosis, shown labelled and never as the "Missing effect" box; one
// without "made_for" (an older zerog) is labelled as made for an unknown model. Likewise a ladder
// of another log.
class CliReportMadeFor : public Cli {
 protected:
  static void SetUpTestSuite() {
    Cli::SetUpTestSuite();
    // run.csv hides `cable`: the default model's diagnosis names it; the model with it does not.
    Result r = run("fit " + log() + " -q --out " + path("default.json"));
    ASSERT_EQ(r.status, 0) << r.err;
    r = run("fit " + log() +
            " -q --effects bias,gravity,linear_inertia,rotational_inertia,cable --out " +
            path("cable.json"));
    ASSERT_EQ(r.status, 0) << r.err;
    for (const char* m : {"default", "cable"}) {
      r = run("diagnose " + log() + " --model " + path(std::string(m) + ".json") +
              " --block 20 --no-discover --json -q");
      ASSERT_EQ(r.status, 0) << r.err;
      std::ofstream(path(std::string("diag_") + m + ".json")) << r.out;
    }
    r = run("ladder " + log() + " --block 20 -q --out " + path("ladder.json"));
    ASSERT_EQ(r.status, 0) << r.err;
  }
  static std::string path(const std::string& name) { return (dir() / name).string(); }
  static nlohmann::json doc(const std::string& name) {
    return nlohmann::json::parse(slurp(path(name)));
  }
  static void write(const std::string& name, const nlohmann::json& j) {
    std::ofstream(path(name)) << j.dump(2);
  }
  // zerog report on the model with cable; `extra` adds --diagnosis/--ladder and flags.
  static Result report(const std::string& out, const std::string& extra) {
    return run("report " + log() + " --model " + path("cable.json") + " --out " + path(out) + " " +
               extra);
  }
};

TEST_F(CliReportMadeFor, TheDiagnosisOfItsOwnModelIsTheVerdict) {
  const auto d = doc("diag_cable.json");
  ASSERT_NE(d["verdict"]["kind"], "effect") << d["verdict"]["text"];
  const Result r = report(
      "rep_own", "--diagnosis " + path("diag_cable.json") + " --ladder " + path("ladder.json"));
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string page = slurp(dir() / "rep_own" / "index.html");
  EXPECT_THAT(page, HasSubstr("id=\"verdict\""));
  EXPECT_THAT(page, HasSubstr("Diagnosis: which effect is missing"));
  EXPECT_THAT(page, HasSubstr("Ladder of effects"));
  EXPECT_THAT(page, ::testing::Not(HasSubstr("class=\"foreign\"")));
  EXPECT_THAT(page, ::testing::Not(HasSubstr("Missing effect: <b>cable")));
}

TEST_F(CliReportMadeFor, ADiagnosisOfAnotherModelIsRefusedNamingBoth) {
  const Result r = report("rep_refused", "--diagnosis " + path("diag_default.json"));
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_THAT(r.err, HasSubstr(path("diag_default.json") + ": this diagnosis was made for model " +
                               path("default.json") +
                               " [bias,gravity,linear_inertia,rotational_inertia] on " + log()));
  EXPECT_THAT(r.err,
              HasSubstr("the report is for model " + path("cable.json") +
                        " [bias,cable,gravity,linear_inertia,rotational_inertia] on " + log()));
  EXPECT_THAT(r.err, HasSubstr("zerog diagnose " + log() + " --model " + path("cable.json")));
  EXPECT_THAT(r.err, HasSubstr("--allow-other-diagnosis"));
  EXPECT_FALSE(fs::exists(dir() / "rep_refused"));

  // Same effects, another fit (the model file's bytes differ): refused, the CRC-32s tell them
  // apart. Another log: refused, naming it.
  auto d = doc("diag_cable.json");
  d["made_for"]["model"]["crc32"] = "00000000";
  write("diag_refit.json", d);
  Result r2 = report("rep_refused", "--diagnosis " + path("diag_refit.json"));
  EXPECT_EQ(r2.status, 2) << r2.err;
  EXPECT_THAT(r2.err, HasSubstr("(crc32 00000000)"));
  d = doc("diag_cable.json");
  d["made_for"]["log"]["file"] = "elsewhere/run7.csv";
  d["made_for"]["log"]["crc32"] = "00000000";
  write("diag_run7.json", d);
  r2 = report("rep_refused", "--diagnosis " + path("diag_run7.json"));
  EXPECT_EQ(r2.status, 2) << r2.err;
  EXPECT_THAT(r2.err, HasSubstr("on elsewhere/run7.csv (crc32 00000000"));
  EXPECT_FALSE(fs::exists(dir() / "rep_refused"));
}

TEST_F(CliReportMadeFor, WithTheFlagADiagnosisOfAnotherModelIsLabelledNotTheVerdict) {
  const auto d = doc("diag_default.json");
  ASSERT_EQ(d["verdict"]["effect"], "cable") << d["verdict"]["text"];
  const Result r =
      report("rep_other", "--diagnosis " + path("diag_default.json") + " --allow-other-diagnosis");
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string page = slurp(dir() / "rep_other" / "index.html");
  EXPECT_THAT(
      page, HasSubstr("<b>Diagnosis of another model or log</b>: made for model " +
                      path("default.json") + " [bias,gravity,linear_inertia,rotational_inertia]"));
  EXPECT_THAT(page, HasSubstr("<h2 id=\"diagnosis\">Diagnosis of another model or log</h2>"));
  EXPECT_THAT(page, ::testing::Not(HasSubstr("id=\"verdict\"")));
  EXPECT_THAT(page, ::testing::Not(HasSubstr("Missing effect: <b>cable")));
  EXPECT_THAT(page, ::testing::Not(HasSubstr("Diagnosis: which effect is missing")));
}

TEST_F(CliReportMadeFor, AnOlderDiagnosisWithoutMadeForIsLabelledUnknown) {
  auto d = doc("diag_default.json");
  d.erase("made_for");
  d["version"] = 1;
  write("diag_old.json", d);
  const Result r = report("rep_old", "--diagnosis " + path("diag_old.json"));
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string page = slurp(dir() / "rep_old" / "index.html");
  EXPECT_THAT(page, HasSubstr("<b>Diagnosis made for an unknown model</b>: it does not say"));
  EXPECT_THAT(page, ::testing::Not(HasSubstr("id=\"verdict\"")));
  EXPECT_THAT(page, ::testing::Not(HasSubstr("Missing effect: <b>cable")));
}

TEST_F(CliReportMadeFor, ALadderOfAnotherLogIsRefusedOrLabelled) {
  auto l = doc("ladder.json");
  l["made_for"]["log"]["rig_crc32"] = "00000000";
  write("ladder_other.json", l);
  Result r = report("rep_ladder", "--ladder " + path("ladder_other.json"));
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_THAT(r.err, HasSubstr("this ladder was made on " + log() + " (crc32 "));
  EXPECT_THAT(r.err, HasSubstr("rig 00000000)"));
  EXPECT_THAT(r.err, HasSubstr("--allow-other-ladder"));
  EXPECT_FALSE(fs::exists(dir() / "rep_ladder"));
  r = report("rep_ladder", "--ladder " + path("ladder_other.json") + " --allow-other-ladder");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_THAT(slurp(dir() / "rep_ladder" / "index.html"),
              HasSubstr("<h2 id=\"ladder\">Ladder of another log</h2>"));
  // A diagnosis is not a ladder.
  r = report("rep_ladder2", "--ladder " + path("diag_cable.json"));
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_THAT(r.err, HasSubstr("not a zerog-ladder document"));
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

// Default outputs go beside the input, never into the current folder (proto/paths.md): diagnose's
// discovered law, the command it prints (a new file that is no input) and report's folder, with
// the log named by a relative path from an empty folder.
TEST_F(Cli, DefaultOutputsGoBesideTheInputNotIntoTheCurrentFolder) {
  const fs::path in = dir() / "beside", cwd = dir() / "cwd";
  fs::create_directories(in);
  fs::create_directories(cwd);
  Result r = run("sim --kind random --points 24 --seed 4 --effects joint6_friction -q --out " +
                 (in / "run.csv").string());
  ASSERT_EQ(r.status, 0) << r.err;
  // From cwd, the inputs as ../beside/…; the model named run.fit.json, which the suggested
  // command must not overwrite.
  const auto from_cwd = [&](const std::string& args) {
    const std::string cmd = "cd " + cwd.string() + " && " + std::string(ZEROG_EXE) + " " + args +
                            " >" + (dir() / "cwd_out.txt").string() + " 2>" +
                            (dir() / "cwd_err.txt").string();
    const int rc = std::system(cmd.c_str());
    return Result{WIFEXITED(rc) ? WEXITSTATUS(rc) : -1, slurp(dir() / "cwd_out.txt"),
                  slurp(dir() / "cwd_err.txt")};
  };
  r = from_cwd("fit ../beside/run.csv -q --out ../beside/run.fit.json");
  ASSERT_EQ(r.status, 0) << r.err;
  r = from_cwd("diagnose ../beside/run.csv --model ../beside/run.fit.json --json -q");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto d = nlohmann::json::parse(r.out);
  ASSERT_EQ(d["verdict"]["kind"], "discovered") << d["verdict"]["text"];
  EXPECT_EQ(d["verdict"]["effect_file"], "../beside/run.discovered.toml");
  EXPECT_TRUE(fs::exists(in / "run.discovered.toml"));
  const std::string command = d["verdict"]["command"];
  EXPECT_NE(command.find(" --out ../beside/run.fit2.json"), std::string::npos) << command;
  r = from_cwd("report ../beside/run.csv --model ../beside/run.fit.json");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(fs::exists(in / "run.report" / "index.html"));
  EXPECT_TRUE(fs::is_empty(cwd)) << "a tool wrote into the current folder";
}

// The loop iterates (issue 25's "diagnose -> add -> diagnose -> add"): a model fitted with a law
// discovered on one log is diagnosed on a log that hides a second law; the second law gets its
// own name and file, the printed command runs as printed with both, and no input changes.
TEST_F(Cli, ALawFoundOnTopOfAnEarlierOneGetsItsOwnNameAndFile) {
  const fs::path a = dir() / "loop_a.csv", b = dir() / "loop_b.csv";
  Result r = run("sim --kind random --points 24 --seed 6 --effects joint6_friction -q --out " +
                 a.string());
  ASSERT_EQ(r.status, 0) << r.err;
  r =
      run("sim --kind random --points 24 --seed 7 --effects joint6_friction,dress_pack_bend -q "
          "--out " +
          b.string());
  ASSERT_EQ(r.status, 0) << r.err;
  // As printed, from the test's folder.
  const auto run_printed = [&](const std::string& command) {
    const std::string shell = "cd " + dir().string() + " && " + std::string(ZEROG_EXE) +
                              command.substr(5) + " -q >/dev/null 2>" +
                              (dir() / "cmd_err.txt").string();
    return std::system(shell.c_str());
  };
  r = run("diagnose " + a.string() + " --json -q");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto first = nlohmann::json::parse(r.out);
  ASSERT_EQ(first["verdict"]["kind"], "discovered") << first["verdict"]["text"];
  ASSERT_EQ(run_printed(first["verdict"]["command"]), 0) << slurp(dir() / "cmd_err.txt");
  const fs::path model_a = dir() / "loop_a.fit.json";
  ASSERT_TRUE(fs::exists(model_a));

  const std::vector<fs::path> inputs = {a, b, model_a, dir() / "loop_a.discovered.toml"};
  std::vector<std::string> before;
  for (const fs::path& p : inputs) before.push_back(slurp(p));
  r = run("diagnose " + b.string() + " --model " + model_a.string() + " --json -q");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto second = nlohmann::json::parse(r.out);
  ASSERT_EQ(second["verdict"]["kind"], "discovered") << second["verdict"]["text"];
  EXPECT_EQ(second["verdict"]["effect_file"], (dir() / "loop_b.discovered.toml").string());
  EXPECT_THAT(slurp(dir() / "loop_b.discovered.toml"), HasSubstr("name = \"discovered_2\""));
  const std::string command = second["verdict"]["command"];
  ASSERT_EQ(run_printed(command), 0) << command << "\n" << slurp(dir() / "cmd_err.txt");
  const auto m = nlohmann::json::parse(slurp(dir() / "loop_b.fit.json"));
  ASSERT_EQ(m["user_effects"].size(), 2u) << m["user_effects"].dump();
  EXPECT_EQ(m["user_effects"][0]["name"], "discovered");
  EXPECT_EQ(m["user_effects"][1]["name"], "discovered_2");
  for (std::size_t k = 0; k < inputs.size(); ++k)
    EXPECT_EQ(slurp(inputs[k]), before[k]) << inputs[k] << " changed";
}

// A touch is not physics, through the program: zerog sim --contact on top of a law outside the
// library; diagnose names the event and prints the refit without it; the printed command runs; its
// model remembers the span, so diagnose of it goes on to the law (not to the push), and compare
// shows the span in time. No input changes.
TEST_F(Cli, AnEventIsNamedRefittedWithoutAndTheLoopGoesOnToThePhysics) {
  const fs::path log = dir() / "touch.csv";
  Result r =
      run("sim --kind oa --seed 4 --effects joint6_friction --contact 250.4:3:0,0,-12 -q "
          "--out " +
          log.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const auto truth = nlohmann::json::parse(slurp(dir() / "touch.truth.json"));
  ASSERT_EQ(truth["extra"]["contacts"].size(), 1u);
  const auto run_printed = [&](const std::string& command) {
    const std::string shell = "cd " + dir().string() + " && " + std::string(ZEROG_EXE) +
                              command.substr(5) + " -q >/dev/null 2>" +
                              (dir() / "cmd_err.txt").string();
    return std::system(shell.c_str());
  };
  const std::vector<fs::path> inputs = {log, dir() / "touch.rig.toml"};
  std::vector<std::string> before;
  for (const fs::path& p : inputs) before.push_back(slurp(p));

  r = run("diagnose " + log.string() + " --json -q");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto first = nlohmann::json::parse(r.out);
  ASSERT_EQ(first["verdict"]["kind"], "event") << first["verdict"]["text"];
  ASSERT_EQ(first["events"].size(), 1u);
  EXPECT_NEAR(first["events"][0]["t0_s"].get<double>(), 250.4, 0.2);
  EXPECT_NEAR(first["events"][0]["mean_wrench"][2].get<double>(), -12.0, 1.8);
  // The law found without the span is the friction's, not the push's.
  if (!first["discovery"].is_null()) {
    for (const auto& t : first["discovery"]["terms"])
      EXPECT_EQ(t["basis"], "tanh(qd6/0.02)") << first["discovery"].dump();
  }
  // An event's diagnosis writes no law file (the law comes on a later turn, fitted without it).
  EXPECT_FALSE(fs::exists(dir() / "touch.discovered.toml"));
  const std::string command = first["verdict"]["command"];
  EXPECT_THAT(command, HasSubstr("--exclude"));
  ASSERT_EQ(run_printed(command), 0) << command << "\n" << slurp(dir() / "cmd_err.txt");
  const fs::path model = dir() / "touch.fit.json";
  ASSERT_TRUE(fs::exists(model));
  const auto m = nlohmann::json::parse(slurp(model));
  EXPECT_EQ(m["extra"]["fit"]["exclude"]["spans"], first["exclude"]);

  // The next turn leaves the span out and finds the law.
  r = run("diagnose " + log.string() + " --model " + model.string() + " --json -q");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto second = nlohmann::json::parse(r.out);
  EXPECT_EQ(second["verdict"]["kind"], "discovered") << second["verdict"]["text"];
  EXPECT_EQ(second["exclude"], first["exclude"]);
  const std::string command2 = second["verdict"]["command"];
  EXPECT_THAT(command2, HasSubstr("--exclude"));
  ASSERT_EQ(run_printed(command2), 0) << command2 << "\n" << slurp(dir() / "cmd_err.txt");
  const fs::path model2 = dir() / "touch.fit2.json";
  ASSERT_TRUE(fs::exists(model2));

  // compare of the model with the law says where it fails in time: the push.
  r = run("compare " + log.string() + " --model " + model2.string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("in time: 1 span(s) stand out"));
  // Without the law the friction's steps recur at every move of A6: the model's, not events.
  r = run("compare " + log.string() + " --model " + model.string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("recurring through the log"));
  r = run("compare " + log.string() + " --model " + model2.string() + " --json");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto cmp = nlohmann::json::parse(r.out);
  EXPECT_EQ(cmp["timeline"].size(), 60u);
  ASSERT_EQ(cmp["span_scan"]["spans"].size(), 1u);

  // A bad --exclude names what is wrong.
  r = run("fit " + log.string() + " --exclude 5:1 -q");
  EXPECT_NE(r.status, 0) << r.out;
  EXPECT_THAT(r.err, HasSubstr("--exclude item '5:1'"));
  r = run("fit " + log.string() + " --exclude 5000:5001 -q");
  EXPECT_NE(r.status, 0);
  EXPECT_THAT(r.err, HasSubstr("no row of"));
  for (std::size_t k = 0; k < inputs.size(); ++k)
    EXPECT_EQ(slurp(inputs[k]), before[k]) << inputs[k] << " changed";
}

// The discovery loop as a user runs it: diagnose finds a law outside the library, writes the effect
// file and prints a command; the command runs as printed and fits the law; compare, report and
// export take the fitted model with its user-defined effect.
TEST_F(Cli, DiscoveredLawFitsWithThePrintedCommandAndTravelsToReportAndExport) {
  const fs::path log = dir() / "j6.csv";
  Result r = run("sim --kind oa --seed 3 --effects joint6_friction -q --out " + log.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const fs::path found = dir() / "found.toml";
  r = run("diagnose " + log.string() + " --json -q --discovered-out " + found.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const auto d = nlohmann::json::parse(r.out);
  ASSERT_EQ(d["verdict"]["kind"], "discovered") << d["verdict"]["text"];
  EXPECT_EQ(d["verdict"]["effect_file"], found.string());
  ASSERT_TRUE(fs::exists(found));
  ASSERT_EQ(d["discovery"]["terms"].size(), 1u) << d["discovery"].dump();
  EXPECT_EQ(d["discovery"]["terms"][0]["basis"], "tanh(qd6/0.02)");
  EXPECT_EQ(d["discovery"]["terms"][0]["axis"], "Mz");
  const std::string command = d["verdict"]["command"];
  ASSERT_EQ(command.rfind("zerog fit ", 0), 0u) << command;
  // As printed, from the folder it names its output in.
  const std::string shell = "cd " + dir().string() + " && " + std::string(ZEROG_EXE) +
                            command.substr(5) + " -q >/dev/null 2>" +
                            (dir() / "cmd_err.txt").string();
  ASSERT_EQ(std::system(shell.c_str()), 0) << slurp(dir() / "cmd_err.txt");
  // Beside the log, a new file (proto/paths.md): not the current folder, no input overwritten.
  const fs::path fitted = dir() / "j6.fit.json";
  EXPECT_NE(command.find(" --out " + fitted.string()), std::string::npos) << command;
  ASSERT_TRUE(fs::exists(fitted));
  const auto m = nlohmann::json::parse(slurp(fitted));
  ASSERT_EQ(m["user_effects"].size(), 1u);
  EXPECT_NEAR(m["user_effects"][0]["terms"][0]["value"].get<double>(), 1.5, 0.075);

  r = run("compare " + log.string() + " --model " + fitted.string() + " --json -q");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto c = nlohmann::json::parse(r.out);
  EXPECT_LT(c["segments"]["all"]["torque_rms"].get<double>(), 0.45);
  r = run("report " + log.string() + " --model " + fitted.string() + " --out " +
          (dir() / "rep").string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(slurp(dir() / "rep" / "index.html").find("@discovered"), std::string::npos);
  r = run("export --model " + fitted.string() + " --rig " + (dir() / "j6.rig.toml").string() +
          " --out " + (dir() / "deployed.zgm").string() + " -q");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(slurp(dir() / "deployed.zgm").find("tanh(qd6/0.02)"), std::string::npos);
}

// The loop as printed (issue 25, item 3): two and three laws outside the library hidden together,
// and a library effect with a law outside it, on two seeds each: diagnose, run the printed
// command, diagnose its model, ... until nothing is left; the model then matches the true-model
// reference within 1.1x (force and torque RMS over the log), no command fails, and no file any
// turn read (the log, its rig, every model and law of earlier turns) is changed.
// Issue 28, items 3 and 4, as a user runs them: a run on the elastic robot imported again with
// kinematics = "fused" (the mapping reads the zerog log as a file, proto/import_mapping.md), fitted
// and compared. On this 24-point random design the fused log's model is within 1.6x the sensor
// floor in force and 2.6x in torque (measured 1.45x, 2.28x; the IMU's 4.6x and 11x; the OA run of
// the demo gives 1.20x, 1.69x: robot_kinematics.md), the F/T-only floor compare prints without a
// truth is the simulator's sensor floor within 10 % (force), and the inputs stay as they were.
// Two seeds.
TEST_F(Cli, FusedKinematicsBringTheElasticRobotsFitToTheSensorFloor) {
  for (int seed : {3, 9}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const fs::path sub = dir() / ("fused_" + std::to_string(seed));
    fs::create_directories(sub);
    const fs::path log = sub / "run.csv";
    Result r = run("sim --kind random --points 24 --real-robot --seed " + std::to_string(seed) +
                   " -q --out " + log.string());
    ASSERT_EQ(r.status, 0) << r.err;
    const std::string before = slurp(log);
    // The simulator's mountings, which the mapping's rig repeats with the robot file.
    const std::string rig = slurp(sub / "run.rig.toml");
    ASSERT_THAT(rig, HasSubstr("[flange_sensor]  # sensor frame S in the flange frame F\np_m = "
                               "[0.0, 0.0, 0.06]\nq_wxyz = [1.0, 0.0, 0.0, 0.0]"));
    ASSERT_THAT(rig, HasSubstr("[sensor_imu]  # IMU frame I in the sensor frame S\np_m = [0.0, "
                               "0.0, 0.0]\nq_wxyz = [1.0, 0.0, 0.0, 0.0]"));
    std::ofstream(sub / "fused.toml")
        << "format = \"zerog-import\"\nversion = 1\nkinematics = \"fused\"\n"
           "[rig]\nname = \"elastic\"\nrobot = \"KR 210 R2700\"\nrobot_file = \""
        << ZEROG_SOURCE_DIR << "/calib/robots/kr210_r2700.robot.toml\"\n"
        << "[rig.flange_sensor]\np_m = [0.0, 0.0, 0.06]\nq_wxyz = [1.0, 0.0, 0.0, 0.0]\n"
           "[rig.sensor_imu]\np_m = [0.0, 0.0, 0.0]\nq_wxyz = [1.0, 0.0, 0.0, 0.0]\n"
           "[files.log]\npath = \"run.csv\"\ntime = { column = \"t_s\", unit = \"s\" }\n"
           "force = { columns = [\"Fx_N\", \"Fy_N\", \"Fz_N\"], unit = \"N\" }\n"
           "torque = { columns = [\"Mx_Nm\", \"My_Nm\", \"Mz_Nm\"], unit = \"N*m\" }\n"
           "joints = { columns = [\"q1_rad\", \"q2_rad\", \"q3_rad\", \"q4_rad\", \"q5_rad\", "
           "\"q6_rad\"], unit = \"rad\" }\n"
           "specific_force = { columns = [\"imu_fx_mps2\", \"imu_fy_mps2\", \"imu_fz_mps2\"], "
           "unit = \"m/s^2\" }\n"
           "angular_rate = { columns = [\"imu_wx_radps\", \"imu_wy_radps\", \"imu_wz_radps\"], "
           "unit = \"rad/s\" }\n";
    r = run("import --mapping " + (sub / "fused.toml").string() + " --out " +
            (sub / "fused.csv").string());
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_THAT(r.out, HasSubstr("kinematics = \"fused\""));
    EXPECT_THAT(r.out, HasSubstr("the link's deflection from the robot file's elasticity"));
    EXPECT_THAT(slurp(sub / "fused.rig.toml"), HasSubstr("mode = \"fused\""));
    const std::string truth = (sub / "run.truth.json").string();
    nlohmann::json cmp[2];
    const char* names[2] = {"run", "fused"};
    for (int k = 0; k < 2; ++k) {
      const std::string csv = (sub / (std::string(names[k]) + ".csv")).string();
      const std::string model = (sub / (std::string(names[k]) + "_fit.json")).string();
      r = run("fit " + csv + " -q --effects bias,gravity,linear_inertia,rotational_inertia --out " +
              model);
      ASSERT_EQ(r.status, 0) << r.err;
      r = run("compare " + csv + " --model " + model + " --truth " + truth + " --json -q");
      ASSERT_EQ(r.status, 0) << r.err;
      cmp[k] = nlohmann::json::parse(r.out);
    }
    const auto rms = [](const nlohmann::json& j, const char* what, const char* key) {
      return j[what]["all"][key].get<double>();
    };
    const double floor_f = rms(cmp[1], "sensor_floor", "force_rms");
    const double floor_m = rms(cmp[1], "sensor_floor", "torque_rms");
    const double imu_f = rms(cmp[0], "segments", "force_rms") / floor_f;
    const double imu_m = rms(cmp[0], "segments", "torque_rms") / floor_m;
    const double fused_f = rms(cmp[1], "segments", "force_rms") / floor_f;
    const double fused_m = rms(cmp[1], "segments", "torque_rms") / floor_m;
    std::printf(
        "seed %d: force / torque over the sensor floor: IMU %.2f / %.2f, fused %.2f / %.2f\n", seed,
        imu_f, imu_m, fused_f, fused_m);
    EXPECT_GT(imu_f, 3.0);
    EXPECT_LT(fused_f, 1.6);
    EXPECT_LT(fused_m, 2.6);
    EXPECT_LT(fused_m, 0.25 * imu_m);
    const nlohmann::json& ft = cmp[1]["ft_floor"];
    ASSERT_TRUE(ft["known"].get<bool>()) << ft.dump();
    EXPECT_NEAR(ft["force_rms"].get<double>(), floor_f, 0.1 * floor_f);
    EXPECT_LT(ft["ratio"]["force_rest"].get<double>(), 1.5);
    EXPECT_EQ(slurp(log), before);
  }
}

TEST_F(Cli, TheLoopAsPrintedReachesTheTrueModelReferenceWithoutTouchingItsInputs) {
  struct Case {
    std::string effects;
    std::string design;  // zerog sim's design options
    std::vector<int> seeds;
  };
  // 3-min runs of 24 random poses, and the 15-min OA run of the README (where cable's gravity
  // once misled the search for the law: three turns), also on the elastic robot.
  const std::vector<Case> hidden = {
      {"joint6_friction,dress_pack_bend", "--kind random --points 24", {4, 5}},
      {"joint6_friction,dress_pack_bend,swivel_viscous", "--kind random --points 24", {4, 5}},
      {"cable,joint6_friction", "--kind random --points 24", {4, 5}},
      {"cable,joint6_friction", "--kind oa", {2, 3}},
      // The robot that is not rigid (proto/sim_robot.md): elastic joints, encoder steps, IMU bias.
      {"cable,joint6_friction", "--kind oa --real-robot", {7}}};
  for (const Case& hide : hidden) {
    const std::string& effects = hide.effects;
    for (int seed : hide.seeds) {
      SCOPED_TRACE(effects + ", " + hide.design + ", seed " + std::to_string(seed));
      const fs::path sub =
          dir() / ("loop_" + std::to_string(seed) + "_" +
                   std::to_string(std::hash<std::string>{}(effects + hide.design)));
      fs::create_directories(sub);
      const fs::path log = sub / "run.csv";
      Result r = run("sim " + hide.design + " --seed " + std::to_string(seed) +
                     " --effects rotational_inertia," + effects + " -q --out " + log.string());
      ASSERT_EQ(r.status, 0) << r.err;
      std::vector<fs::path> inputs = {log, sub / "run.rig.toml"};
      std::vector<std::string> before = {slurp(inputs[0]), slurp(inputs[1])};
      std::string model;
      int turns = 0;
      for (; turns < 5; ++turns) {
        r = run("diagnose " + log.string() + (model.empty() ? "" : " --model " + model) +
                " --json -q");
        ASSERT_EQ(r.status, 0) << r.err;
        const auto d = nlohmann::json::parse(r.out);
        if (d["verdict"]["command"].is_null()) {
          EXPECT_EQ(d["verdict"]["kind"], "nothing_left") << d["verdict"]["text"];
          break;
        }
        if (!d["verdict"]["effect_file"].is_null()) {
          inputs.push_back(d["verdict"]["effect_file"].get<std::string>());
          before.push_back(slurp(inputs.back()));
        }
        const std::string command = d["verdict"]["command"];
        const std::string shell = "cd " + sub.string() + " && " + std::string(ZEROG_EXE) +
                                  command.substr(5) + " -q --no-consistency >/dev/null 2>" +
                                  (sub / "err.txt").string();
        ASSERT_EQ(std::system(shell.c_str()), 0) << command << "\n" << slurp(sub / "err.txt");
        const std::size_t at = command.find("--out ") + 6;
        model = command.substr(at, command.find(' ', at) - at);
        if (!fs::path(model).is_absolute()) model = (sub / model).string();
        inputs.push_back(model);
        before.push_back(slurp(model));
      }
      ASSERT_LT(turns, 5) << "the loop did not end";
      ASSERT_FALSE(model.empty());
      r = run("compare " + log.string() + " --model " + model + " --truth " +
              (sub / "run.truth.json").string() + " --json");
      ASSERT_EQ(r.status, 0) << r.err;
      const auto c = nlohmann::json::parse(r.out);
      const double force = c["segments"]["all"]["force_rms"].get<double>();
      const double torque = c["segments"]["all"]["torque_rms"].get<double>();
      const double ref_force = c["true_model_reference"]["all"]["force_rms"].get<double>();
      const double ref_torque = c["true_model_reference"]["all"]["torque_rms"].get<double>();
      // A library effect with a law outside it: in at most two turns.
      if (effects == "cable,joint6_friction") {
        EXPECT_LE(turns, 2);
      }
      EXPECT_LE(force, 1.1 * ref_force) << turns << " turns";
      EXPECT_LE(torque, 1.1 * ref_torque) << turns << " turns";
      std::printf(
          "loop %s (%s) seed %d: %d turns, force %.3f / reference %.3f N, torque %.4f / %.4f "
          "N*m\n",
          effects.c_str(), hide.design.c_str(), seed, turns, force, ref_force, torque, ref_torque);
      for (std::size_t k = 0; k < inputs.size(); ++k)
        EXPECT_EQ(slurp(inputs[k]), before[k]) << inputs[k] << " changed";
    }
  }
}

// A drift over a static table's rows is per row: the table is diagnosed, the drift fits, and
// zerog export refuses to deploy it as a drift in time (the mutant: without static_rows in the
// model file, the export goes through).
TEST_F(Cli, ADriftFittedOverATablesRowsIsNotDeployed) {
  const fs::path src = fs::path(ZEROG_SOURCE_DIR) / "calib/static_table";
  for (const char* f : {"mapping.toml", "rig.rig.toml", "table.csv"})
    fs::copy_file(src / f, dir() / f, fs::copy_options::overwrite_existing);
  const fs::path log = dir() / "table_log.csv";
  Result r =
      run("import --mapping " + (dir() / "mapping.toml").string() + " --out " + log.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const fs::path model = dir() / "drift.json";
  r = run("fit " + log.string() + " --effects bias,gravity,bias_drift -q --out " + model.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string export_cmd = "export --model " + model.string() + " --rig " +
                                 (dir() / "rig.rig.toml").string() + " --out " +
                                 (dir() / "drift.zgm").string() + " -q";
  r = run(export_cmd);
  EXPECT_NE(r.status, 0);
  EXPECT_THAT(r.err, HasSubstr("fitted over a static table's rows"));
  EXPECT_FALSE(fs::exists(dir() / "drift.zgm"));
  auto m = nlohmann::json::parse(slurp(model));
  m["extra"]["fit"]["static_rows"] = false;  // the mutant
  std::ofstream(model) << m.dump(2);
  r = run(export_cmd);
  EXPECT_EQ(r.status, 0) << r.err;
}

// A model fitted on an ω̇ other than the one zerog-rt's cycle computes (the 5-point difference
// of the gyro): the simulator's log imported with kinematics = "auto" carries the gyro's
// Savitzky–Golay derivative as imu_dw*_radps2. export warns, naming both (also with -q), and
// the deploy file records them; the log as simulated (no imu_dw*) deploys without a warning.
TEST_F(Cli, ExportSaysWhenTheModelWasFittedOnAnotherAngularAccelerationThanTheCycle) {
  const fs::path map = dir() / "auto_map.toml";
  std::ofstream(map) << "format = \"zerog-import\"\nversion = 1\nrig_file = \"run.rig.toml\"\n"
                        "kinematics = \"auto\"\n[files.run]\npath = \"run.csv\"\n"
                        "time = { column = \"t_s\", unit = \"s\" }\n"
                        "force = { columns = [\"Fx_N\", \"Fy_N\", \"Fz_N\"], unit = \"N\" }\n"
                        "torque = { columns = [\"Mx_Nm\", \"My_Nm\", \"Mz_Nm\"], unit = \"N*m\" }\n"
                        "position = { columns = [\"px_m\", \"py_m\", \"pz_m\"], unit = \"m\" }\n"
                        "orientation = { type = \"quaternion\", columns = [\"qw\", \"qx\", \"qy\", "
                        "\"qz\"] }\n"
                        "specific_force = { columns = [\"imu_fx_mps2\", \"imu_fy_mps2\", "
                        "\"imu_fz_mps2\"], unit = \"m/s2\" }\n"
                        "angular_rate = { columns = [\"imu_wx_radps\", \"imu_wy_radps\", "
                        "\"imu_wz_radps\"], unit = \"rad/s\" }\n";
  Result r = run("import --mapping " + map.string() + " --out " + (dir() / "sg.csv").string());
  ASSERT_EQ(r.status, 0) << r.err;
  ASSERT_NE(slurp(dir() / "sg.csv").find("imu_dwx_radps2"), std::string::npos);
  const std::string effects = " -e bias,gravity,linear_inertia,rotational_inertia -q -o ";
  r = run("fit " + (dir() / "sg.csv").string() + effects + (dir() / "fit_sg.json").string());
  ASSERT_EQ(r.status, 0) << r.err;
  r = run("fit " + log() + effects + (dir() / "fit_5p.json").string());
  ASSERT_EQ(r.status, 0) << r.err;
  const auto provenance = [](const fs::path& deployed) {
    const std::string text = slurp(deployed);
    return nlohmann::json::parse(text.substr(text.find('\n') + 1))["provenance"];
  };

  r = run("export --model " + (dir() / "fit_sg.json").string() + " --rig " +
          (dir() / "sg.rig.toml").string() + " --out " + (dir() / "sg.zgm").string() + " -q");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("warning: " + (dir() / "fit_sg.json").string() +
                               " was fitted on the angular acceleration from "
                               "'gyro_savitzky_golay'"));
  EXPECT_THAT(r.err, HasSubstr("zerog-rt's cycle computes it as 'gyro_5point'"));
  EXPECT_THAT(r.err, HasSubstr("linear_inertia, rotational_inertia will run on another"));
  EXPECT_THAT(r.err, HasSubstr("import with kinematics = \"imu\""));
  nlohmann::json p = provenance(dir() / "sg.zgm");
  EXPECT_EQ(p["omega_dot"]["fit"], "gyro_savitzky_golay") << p.dump();
  EXPECT_EQ(p["omega_dot"]["cycle"], "gyro_5point");
  EXPECT_EQ(p["omega_dot"]["matches"], false);
  EXPECT_THAT(p["omega_dot"]["fit_method"].get<std::string>(), HasSubstr("Savitzky-Golay"));

  r = run("export --model " + (dir() / "fit_5p.json").string() + " --rig " +
          (dir() / "run.rig.toml").string() + " --out " + (dir() / "5p.zgm").string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_THAT(r.err, Not(HasSubstr("warning")));
  EXPECT_THAT(r.err, HasSubstr("omega_dot: fitted on 'gyro_5point', the cycle computes "
                               "'gyro_5point' (the same)"));
  p = provenance(dir() / "5p.zgm");
  EXPECT_EQ(p["omega_dot"]["fit"], "gyro_5point") << p.dump();
  EXPECT_EQ(p["omega_dot"]["matches"], true);
}

}  // namespace
