#pragma once
// The fitted-model file (proto/model_format.md): effects and parameter values (with standard
// deviations when known) as JSON. `zerog fit` writes it, `zerog sim` writes the truth in it,
// compare/diagnose/ladder/report read it.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "zerog/model/effects.hpp"

namespace zerog::io {

inline constexpr int kModelFormatVersion = 1;

struct ModelFile {
  model::ModelParams params;
  /// Standard deviation of each parameter (same layout as params.values); absent for truth files.
  std::optional<std::array<std::array<double, model::kMaxEffectParams>, model::kEffectCount>> std;
  /// Standard deviation of each user term's coefficient (params.user); empty if unknown.
  std::vector<double> user_std;
  std::string rig_name;
  nlohmann::json extra = nlohmann::json::object();  ///< provenance: fit statistics, sim seed, …
};

nlohmann::json to_json(const ModelFile& m);
/// Parses a model document; throws std::runtime_error naming `source` and the bad key.
ModelFile model_from_json(const nlohmann::json& j, const std::string& source);
ModelFile read_model(const std::filesystem::path& path);
/// Atomic write; refuses to overwrite one of `inputs`.
void write_model(const ModelFile& m, const std::filesystem::path& path,
                 const std::vector<std::filesystem::path>& inputs = {});

/// Parses a comma-separated effect list ("bias,gravity,cable"); throws naming an unknown effect.
model::EffectSet parse_effect_list(const std::string& list);
std::string effect_list_string(const model::EffectSet& effects);

}  // namespace zerog::io
