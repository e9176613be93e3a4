#pragma once
// User-defined effect files (proto/user_effects.md): a named effect made of terms, each a
// coefficient times a basis from the signal dictionary, added to one wrench axis (sensor frame)
// or along a base-frame axis. TOML, versioned, strict: unknown keys, signals and functions are
// errors naming file, line and column. Host only (allocates, throws).
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "zerog/model/effects.hpp"
#include "zerog/model/user_effects.hpp"

namespace zerog::io {

inline constexpr int kEffectFileVersion = 1;

/// "Fx".."Mz" for a sensor-frame axis, "Fx_B".."Mz_B" for a base-frame one.
std::string term_axis_name(const model::UserTerm& t);
/// The basis as text (model::format_basis) and its coefficient's unit ("N*m/(rad/s)").
std::string basis_text(const model::Basis& b);
std::string coefficient_unit(const model::UserTerm& t);
/// "joint6_friction.Mz*tanh(qd6/0.02) [N*m]", for messages and tables.
std::string term_label(const model::UserEffects& u, int term);
/// The name of user effect k.
std::string user_effect_name(const model::UserEffects& u, int k);

/// Reads an effect file and appends its effect and terms to `into` (start values from `value`,
/// else 0). Throws InputError/TomlError naming file, line, column and why: unknown keys, signals
/// or functions, a wrong unit, a name already in `into`, more terms than kMaxUserTerms.
void read_effect_file(const std::filesystem::path& path, model::UserEffects& into);

/// The text of an effect file for user effect `k` of `u` with its coefficients as values (and
/// their standard deviations, if given, as `std`). `comment` lines are written first (# …).
std::string effect_file_text(const model::UserEffects& u, int k,
                             const std::vector<double>* std = nullptr,
                             const std::string& description = "",
                             const std::vector<std::string>& comment = {});
/// Writes it atomically; never over one of `inputs`.
void write_effect_file(const std::filesystem::path& path, const std::string& text,
                       const std::vector<std::filesystem::path>& inputs = {});

/// A model as the command line names it: library effects and user effect files,
/// "bias,gravity,linear_inertia,@friction.toml".
struct ModelSpec {
  model::EffectSet effects;
  model::UserEffects user;
  std::vector<std::filesystem::path> files;  ///< the effect files read, in order
};
/// The items of a comma-separated list, blanks around them removed, empty ones dropped.
std::vector<std::string> split_list(const std::string& list);

/// Parses the list; '@PATH' reads an effect file, or, for a PATH ending in .json, takes the user
/// effects of a model file (zerog fit's output). Throws naming an unknown effect or the file's
/// error.
ModelSpec parse_model_spec(const std::string& list);
/// "bias,gravity,@friction.toml" (files as given) or, without files, the user effects' names as
/// "@name".
std::string model_spec_string(const model::EffectSet& effects, const model::UserEffects& user,
                              const std::vector<std::filesystem::path>& files = {});

/// Appends the effects and terms of `from` to `into` (names must differ). Throws if they do
/// not fit (kMaxUserEffects, kMaxUserTerms).
void append_user_effects(model::UserEffects& into, const model::UserEffects& from);

}  // namespace zerog::io
