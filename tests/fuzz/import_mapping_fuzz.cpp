// `zerog import`: the TOML mapping (proto/import_mapping.md) and the user's delimited data files it
// names. import_recordings throws formats::InputError (file, line, column) for a bad mapping or
// data, and a plain std::runtime_error when no master row survives; any other exception (e.g. a
// std::filesystem_error), a crash or a hang is a finding.
//
// Input: the mapping text, optionally followed by a line `#@data` and the content of a data file
// `data.txt` beside the mapping. The calib/import_example files (mapping, three recordings, rig)
// are copied beside it too, so mappings can name them.
//
// Property: what imports is a valid log: write_log accepts it (finite values, increasing time)
// and read_log reads it back with as many rows.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string_view>
#include <typeinfo>

#include "fuzz_util.hpp"
#include "zerog/formats/log.hpp"
#include "zerog/io/import.hpp"

namespace fs = std::filesystem;
namespace io = zerog::io;
namespace formats = zerog::formats;

namespace {

constexpr std::string_view kDataSeparator = "\n#@data\n";

void copy_example_files(const fs::path& dir) {
  const fs::path example = fs::path(ZEROG_SOURCE_DIR) / "calib" / "import_example";
  for (const char* name : {"kr210.rig.toml", "wrench_1khz.csv", "imu_2khz.csv", "robot_83hz.txt"})
    fs::copy_file(example / name, dir / name, fs::copy_options::overwrite_existing);
}

/// Paths into the machine's special files would read forever (/dev/zero) or block (/dev/stdin):
/// a user's mistake, not the parser's, so the fuzzer does not go there.
bool names_special_files(std::string_view text) {
  for (std::string_view prefix : {"/dev", "/proc", "/sys"})
    if (text.find(prefix) != std::string_view::npos) return true;
  return false;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const fs::path& dir = zerog::fuzz::scratch_dir();
  static const bool examples_copied = (copy_example_files(dir), true);
  (void)examples_copied;

  const std::string_view input = zerog::fuzz::as_text(data, size);
  if (names_special_files(input)) return 0;
  const std::size_t split = input.find(kDataSeparator);
  const std::string_view mapping_text = input.substr(0, split);
  const std::string_view data_text = split == std::string_view::npos
                                         ? std::string_view{}
                                         : input.substr(split + kDataSeparator.size());
  const fs::path mapping = dir / "mapping.toml";
  zerog::fuzz::write_bytes(mapping, mapping_text);
  zerog::fuzz::write_bytes(dir / "data.txt", data_text);

  io::ImportResult result;
  try {
    result = io::import_recordings(mapping);
  } catch (const formats::InputError&) {
    return 0;
  } catch (const std::runtime_error& e) {
    // Documented only for "no master row survives"; a subclass (filesystem_error, …) escaped.
    if (typeid(e) != typeid(std::runtime_error)) {
      std::fprintf(stderr, "undocumented exception %s: %s\n", typeid(e).name(), e.what());
      __builtin_trap();
    }
    return 0;
  }
  ZEROG_FUZZ_CHECK(!result.log.samples.empty());
  ZEROG_FUZZ_CHECK(result.report.rows_out == result.log.samples.size());
  ZEROG_FUZZ_CHECK(result.report.rows_out <= result.report.master_rows);
  ZEROG_FUZZ_CHECK(!result.report.summary().empty());

  const fs::path out = dir / "imported.csv";
  try {
    formats::write_log(result.log, out, result.inputs);
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "import produced a log write_log refuses: %s\n", e.what());
    __builtin_trap();
  }
  const formats::Log back = formats::read_log(out);
  ZEROG_FUZZ_CHECK(back.samples.size() == result.log.samples.size());
  return 0;
}
