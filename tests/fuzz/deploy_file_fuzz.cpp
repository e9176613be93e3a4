// The deployed-model file (proto/deploy_format.md) that zerog-rt loads at start-up.
// load_deployed_model returns every failure as a LoadError with a message and never throws;
// any exception, a crash, a leak or a hang is a finding. (An allocation far beyond the input's
// size is one too: libFuzzer's -malloc_limit_mb reports it.)
//
// Input: a whole file when it starts with the magic `zerog-deploy`; anything else is taken as
// the JSON content and given a correct header (length, CRC-32), so that the fuzzer reaches the
// content checks instead of stopping at the checksum.
//
// Property: a model that loads serialises (serialise_deployed_model does not refuse it), loads
// again, and serialises again to the same bytes.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>

#include "../unit/infer/infer_fixtures.hpp"
#include "fuzz_util.hpp"
#include "zerog/infer/deploy_file.hpp"

namespace infer = zerog::infer;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // The seeds are fitted for this rig, so the loader's checks past the rig comparison are reached.
  static const infer::RigDescription running_rig = infer::test::demo_rig();
  const std::string_view input = zerog::fuzz::as_text(data, size);

  std::string bytes;
  if (input.starts_with("zerog-deploy")) {
    bytes = input;
  } else {
    char header[96];
    std::snprintf(header, sizeof header, "zerog-deploy 1 length=%zu crc32=%08x\n", input.size(),
                  infer::crc32(input));
    bytes = std::string(header) + std::string(input);
  }

  const infer::LoadResult loaded = infer::load_deployed_model(bytes, running_rig, "fuzz input");
  if (!loaded.ok()) {
    ZEROG_FUZZ_CHECK(!loaded.message.empty() && !loaded.model.has_value());
    ZEROG_FUZZ_CHECK(infer::load_error_name(loaded.error) != nullptr);
    return 0;
  }
  ZEROG_FUZZ_CHECK(loaded.model.has_value() && loaded.message.empty());
  const std::string written = infer::serialise_deployed_model(*loaded.model);
  const infer::LoadResult again = infer::load_deployed_model(written, running_rig, "round trip");
  ZEROG_FUZZ_CHECK(again.ok());
  ZEROG_FUZZ_CHECK(infer::serialise_deployed_model(*again.model) == written);
  return 0;
}
