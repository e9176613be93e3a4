#pragma once
// The trained-network file (proto/network_format.md): kind, shape, activations, normalisation,
// input feature names, output axes, float parameters, training summary and seed; for paper-zp
// the least-squares tool load, for residual the physics model it corrects.
#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "zerog/io/model_file.hpp"
#include "zerog/model/features.hpp"
#include "zerog/model/network.hpp"

namespace zerog::learn {

inline constexpr int kNetworkFormatVersion = 1;

enum class NetworkKind : std::uint8_t {
  paper_bp,  ///< 000_… §3–4: pose + IMU → 6 F/T values, one sigmoid hidden layer
  paper_zp,  ///< 001_… §3.1–3.3: rotation matrix → zero point (5 axes), + least-squares tool load
  residual,  ///< ours: physics model + a small network on its residual
};
const char* kind_name(NetworkKind kind);  ///< "paper-bp", "paper-zp", "residual"
std::optional<NetworkKind> kind_from_name(std::string_view name);

/// Tool load of 001_… §3.2: gravity in the base frame (eq. 13) and centre of gravity in S
/// (eq. 14).
struct ToolLoad {
  Eigen::Vector3d gravity_base_N = Eigen::Vector3d::Zero();  ///< ᴮG*
  Eigen::Vector3d cog_sensor_m = Eigen::Vector3d::Zero();    ///< r*
  int poses = 0;                                             ///< static poses it was fitted on
  double mass_kg() const;                                    ///< |ᴮG*| / 9.80665
};

struct NetworkFile {
  NetworkKind kind = NetworkKind::residual;
  model::NetworkShape shape;
  model::NetworkNormalisation normalisation;
  std::vector<model::Feature> inputs;  ///< one per input, in order
  std::vector<int> output_axes;        ///< wrench axis of each output: 0..5 = Fx Fy Fz Mx My Mz
  std::vector<double> params;          ///< shape.num_params() values, each exactly a float
  std::uint64_t seed = 1;
  nlohmann::json training = nlohmann::json::object();  ///< summary: data, optimiser, errors, time
  std::optional<ToolLoad> tool_load;                   ///< paper-zp
  std::optional<io::ModelFile> physics;                ///< residual: the physics model
};

/// Throws std::invalid_argument if the parts do not fit together (sizes, axes, kind extras).
void validate(const NetworkFile& n);

nlohmann::json to_json(const NetworkFile& n);
/// Parses a network document; throws std::runtime_error naming `source` and the bad key.
NetworkFile network_from_json(const nlohmann::json& j, const std::string& source);
NetworkFile read_network(const std::filesystem::path& path);
/// Atomic write (formats::write_file_atomic); refuses to overwrite one of `inputs`.
void write_network(const NetworkFile& n, const std::filesystem::path& path,
                   const std::vector<std::filesystem::path>& inputs = {});

/// Rounds every parameter and normalisation value to the nearest float (the firmware's storage).
void round_to_float(NetworkFile& n);

}  // namespace zerog::learn
