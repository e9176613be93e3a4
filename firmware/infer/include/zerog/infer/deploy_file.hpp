#pragma once
// The deployed-model file (proto/deploy_format.md): a one-line header (magic, version, content
// length, CRC-32) followed by a JSON content. The writer is for host tools (`zerog export`); the
// loader runs at firmware start-up: it may allocate and uses exceptions internally, but returns
// every failure as a LoadError with a message naming what is wrong, and hands over a model only
// when it is complete and checked. Not real-time safe.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

#include "zerog/infer/deploy_model.hpp"
#include "zerog/status.hpp"

namespace zerog::infer {

/// File extension used by `zerog export` (any name loads).
inline constexpr const char* kDeployFileExtension = ".zgm";

enum class LoadError : std::uint8_t {
  none,
  io,                  ///< the file cannot be read
  not_deploy_file,     ///< no `zerog-deploy` header
  truncated,           ///< fewer bytes than the header declares (or the header is cut)
  corrupt,             ///< CRC-32 mismatch, or bytes after the declared content
  wrong_version,       ///< a format version this firmware does not load
  wrong_rig,           ///< fitted for another rig than the one the caller runs on
  unknown_effect,      ///< an effect (or a parameter of one) this firmware does not know
  unknown_feature,     ///< a network input feature this firmware does not know
  unknown_activation,  ///< an activation function this firmware does not know
  inconsistent_sizes,  ///< layer widths, weight counts, scales or normalisation do not agree
  invalid_value,       ///< malformed JSON, a missing key, a non-finite or out-of-range number
};
const char* load_error_name(LoadError e);

struct LoadResult {
  LoadError error = LoadError::none;
  std::string message;                 ///< empty on success; else names the source and the fault
  std::optional<DeployedModel> model;  ///< set only on success
  bool ok() const { return error == LoadError::none; }
};

/// Parses and checks a deployed-model file's bytes. `running_rig` is the rig this process runs
/// on; a model fitted for another rig is refused (LoadError::wrong_rig). `source` names the
/// input in messages. Never throws (except std::bad_alloc).
LoadResult load_deployed_model(std::string_view bytes, const RigDescription& running_rig,
                               std::string_view source = "deployed model");
/// Reads `path` and calls load_deployed_model.
LoadResult load_deployed_model_file(const std::filesystem::path& path,
                                    const RigDescription& running_rig);

/// The file's bytes for `model` (header + JSON). Throws std::invalid_argument naming the fault
/// if the model fails validate_model. Host side.
std::string serialise_deployed_model(const DeployedModel& model);

/// Internal consistency of a model (everything the loader checks except the rig and the bytes):
/// ok(), or invalid_setting naming the field as a path in the file's content ("rig.name",
/// "physics.parameters.gravity.mass", "network.layers[1]", "network.quantisation.weight_bits")
/// and why, without the field's name. `kind`, if given, receives the loader's category of the
/// refusal (LoadError::none when ok). Start-up only (a refusal allocates).
zerog::Status validate_model(const DeployedModel& model, LoadError* kind = nullptr);

/// CRC-32 (IEEE 802.3 / zlib: reflected polynomial 0xEDB88320, initial and final XOR 0xFFFFFFFF).
/// `crc`: the CRC of the bytes before these (as zlib's crc32(crc, …)), so that a file can be
/// checked a piece at a time: crc32(b, crc32(a)) == crc32(a + b).
std::uint32_t crc32(std::string_view bytes, std::uint32_t crc = 0);

}  // namespace zerog::infer
