// The rig sidecar `NAME.rig.toml` (proto/log_format.md), read by every host tool with a log and by
// zerog-rt at start-up. read_rig throws formats::InputError (or its TomlError) naming file, line
// and column; any other exception, a crash or a hang is a finding.
//
// Property: a rig that reads writes back (write_rig) into a file that reads to the same rig.
#include <cstddef>
#include <cstdint>

#include "fuzz_util.hpp"
#include "io_compare.hpp"
#include "zerog/formats/log.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto& dir = zerog::fuzz::scratch_dir();
  const auto path = dir / "input.rig.toml";
  zerog::fuzz::write_bytes(path, zerog::fuzz::as_text(data, size));
  zerog::formats::Rig rig;
  try {
    rig = zerog::formats::read_rig(path);
  } catch (const zerog::formats::InputError&) {
    return 0;
  }
  const auto again = dir / "again.rig.toml";
  zerog::formats::write_rig(rig, again, {path});
  const zerog::formats::Rig back = zerog::formats::read_rig(again);
  ZEROG_FUZZ_CHECK(zerog::fuzz::same_rig(rig, back));
  return 0;
}
