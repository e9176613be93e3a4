#pragma once
// What a diagnosis or a ladder was made for ("made_for", proto/json_output.md): the model's
// effects (sorted names, user effects as "@name") and its file's CRC-32, and the log with its rig
// (paths as given, CRC-32 of their bytes). zerog diagnose and zerog ladder write it; zerog report
// checks it against the model and log it reports on.
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "zerog/model/effects.hpp"
#include "zerog/model/user_effects.hpp"

namespace zerog::cli {

/// CRC-32 of a file's bytes (infer::crc32, as in the deploy file's header) as 8 lowercase hex
/// digits. Throws std::runtime_error if the file cannot be read.
std::string file_crc32(const std::filesystem::path& path);

/// {"effects": [names, sorted; user effects "@name"], "file": path|null, "crc32": hex|null}; the
/// file and its CRC-32 when `model_path` is not empty.
nlohmann::json model_identity(const model::EffectSet& effects, const model::UserEffects& user,
                              const std::string& model_path = "");

/// {"file": path, "crc32": hex, "rig_file": path, "rig_crc32": hex}: the log and its rig sidecar.
nlohmann::json log_identity(const std::string& log_path);

enum class Match { same, other, unknown };

struct MadeForCheck {
  Match match = Match::unknown;
  /// "for model fit.json [bias,gravity] on run.csv" ("on run.csv" for a ladder); empty when
  /// unknown. CRC-32s are added where they are what tells two apart.
  std::string made_for;
  std::string report_for;  ///< the same words for the report's model and log
};

/// Compares `doc["made_for"]` with the report's model and log identities. With `check_model`
/// false (a ladder, which climbs from its own start) only the log counts. A document without
/// "made_for" (written before it existed) is Match::unknown. Throws formats::InputError naming
/// `doc_path` if "made_for" is malformed.
MadeForCheck check_made_for(const nlohmann::json& doc, const std::string& doc_path,
                            const nlohmann::json& report_model, const nlohmann::json& report_log,
                            bool check_model);

}  // namespace zerog::cli
