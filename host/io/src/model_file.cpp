#include "zerog/io/model_file.hpp"

#include <algorithm>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "zerog/formats/log.hpp"
#include "zerog/io/effect_file.hpp"

namespace zerog::io {

using formats::write_file_atomic;

using model::Effect;
using model::info;

namespace {

// The "user_effects" list of a model file: effects with their terms (see to_json).
template <typename Fail>
void read_user_effects(const nlohmann::json& list, ModelFile& m, const Fail& fail) {
  if (!list.is_array()) fail("key 'user_effects' must be a list");
  model::UserEffects& u = m.params.user;
  bool any_std = false;
  std::vector<double> stds;
  for (std::size_t k = 0; k < list.size(); ++k) {
    const auto& e = list[k];
    const std::string where = "user_effects[" + std::to_string(k) + "]";
    if (!e.is_object() || !e.contains("name") || !e["name"].is_string() || !e.contains("terms") ||
        !e["terms"].is_array())
      fail("'" + where + "' needs a string 'name' and a list 'terms'");
    model::UserEffects one;
    const std::string name = e["name"].get<std::string>();
    if (name.empty() || name.size() >= static_cast<std::size_t>(model::kUserNameSize))
      fail("'" + where + ".name' must have 1 to " + std::to_string(model::kUserNameSize - 1) +
           " characters");
    std::copy(name.begin(), name.end(), one.names[0].begin());
    one.num_effects = 1;
    for (std::size_t t = 0; t < e["terms"].size(); ++t) {
      const auto& tj = e["terms"][t];
      const std::string tw = where + ".terms[" + std::to_string(t) + "]";
      if (!tj.is_object() || !tj.contains("axis") || !tj["axis"].is_string() ||
          !tj.contains("basis") || !tj["basis"].is_string() || !tj.contains("value") ||
          !tj["value"].is_number())
        fail("'" + tw + "' needs strings 'axis', 'basis' and a number 'value'");
      model::UserTerm term;
      const int a = model::wrench_axis_from_name(tj["axis"].get<std::string>());
      if (a < 0) fail("'" + tw + ".axis' must be one of Fx, Fy, Fz, Mx, My, Mz");
      term.axis = static_cast<std::uint8_t>(a);
      const std::string frame = tj.contains("frame") && tj["frame"].is_string()
                                    ? tj["frame"].get<std::string>()
                                    : std::string("sensor");
      if (frame != "sensor" && frame != "base") fail("'" + tw + ".frame' must be sensor or base");
      term.frame = frame == "base" ? model::TermFrame::base : model::TermFrame::sensor;
      const std::string basis = tj["basis"].get<std::string>();
      const char* error = nullptr;
      std::size_t pos = 0;
      if (!model::parse_basis(basis, term.basis, error, pos))
        fail("'" + tw + ".basis' \"" + basis + "\" at character " + std::to_string(pos + 1) + ": " +
             error);
      if (one.num_terms >= model::kMaxUserTerms) fail("too many user terms");
      one.terms[static_cast<std::size_t>(one.num_terms)] = term;
      one.coeff[static_cast<std::size_t>(one.num_terms)] = tj["value"].get<double>();
      ++one.num_terms;
      const bool has_std = tj.contains("std") && tj["std"].is_number();
      any_std = any_std || has_std;
      stds.push_back(has_std ? tj["std"].get<double>() : std::numeric_limits<double>::quiet_NaN());
    }
    try {
      append_user_effects(u, one);
    } catch (const std::runtime_error& ex) {
      fail("'" + where + "': " + ex.what());
    }
  }
  if (any_std) m.user_std = stds;
}

}  // namespace

nlohmann::json to_json(const ModelFile& m) {
  nlohmann::json j;
  j["format"] = "zerog-model";
  j["version"] = kModelFormatVersion;
  j["rig"] = m.rig_name;
  j["effects"] = nlohmann::json::array();
  j["parameters"] = nlohmann::json::object();
  for (Effect e : model::kAllEffects) {
    if (!m.params.effects.has(e)) continue;
    const auto& ei = info(e);
    j["effects"].push_back(ei.name);
    nlohmann::json block = nlohmann::json::object();
    for (int i = 0; i < ei.num_params; ++i) {
      nlohmann::json p;
      p["value"] = m.params.block(e)[i];
      p["unit"] = ei.params[i].unit;
      if (m.std) p["std"] = (*m.std)[model::index(e)][i];
      block[ei.params[i].name] = p;
    }
    j["parameters"][ei.name] = block;
  }
  // User-defined effects (proto/user_effects.md): each term with its basis, axis and value.
  if (m.params.user.num_effects > 0) {
    const model::UserEffects& u = m.params.user;
    nlohmann::json list = nlohmann::json::array();
    for (int k = 0; k < u.num_effects; ++k) {
      nlohmann::json e;
      e["name"] = user_effect_name(u, k);
      e["terms"] = nlohmann::json::array();
      for (int t = 0; t < u.num_terms; ++t) {
        const model::UserTerm& term = u.terms[static_cast<std::size_t>(t)];
        if (term.effect != k) continue;
        nlohmann::json tj;
        tj["axis"] = term_axis_name(term).substr(0, 2);
        tj["frame"] = term.frame == model::TermFrame::base ? "base" : "sensor";
        tj["basis"] = basis_text(term.basis);
        tj["unit"] = coefficient_unit(term);
        tj["value"] = u.coeff[static_cast<std::size_t>(t)];
        if (static_cast<std::size_t>(t) < m.user_std.size())
          tj["std"] = m.user_std[static_cast<std::size_t>(t)];
        e["terms"].push_back(tj);
      }
      list.push_back(e);
    }
    j["user_effects"] = list;
  }
  j["extra"] = m.extra;
  return j;
}

ModelFile model_from_json(const nlohmann::json& j, const std::string& source) {
  auto fail = [&](const std::string& why) -> void {
    throw std::runtime_error(source + ": " + why);
  };
  if (!j.is_object()) fail("not a JSON object");
  // Types are checked before values are taken: nlohmann's own exceptions (a type_error from
  // value() or get() on a number where a string belongs) would not name the file or the key.
  if (!j.contains("format") || !j["format"].is_string() || j["format"] != "zerog-model")
    fail("key 'format' must be \"zerog-model\"");
  if (!j.contains("version") || !j["version"].is_number_integer())
    fail("key 'version' missing or not an integer");
  // Compared as JSON numbers: get<int>() would wrap 4294967297 to 1.
  if (j["version"] != kModelFormatVersion) {
    fail("version " + j["version"].dump() + " is not supported (this zerog reads " +
         std::to_string(kModelFormatVersion) + ")");
  }
  ModelFile m;
  if (j.contains("rig") && !j["rig"].is_string()) fail("key 'rig' must be a string");
  m.rig_name = j.value("rig", "");
  if (!j.contains("effects") || !j["effects"].is_array())
    fail("key 'effects' missing or not a list");
  bool any_std = false;
  std::array<std::array<double, model::kMaxEffectParams>, model::kEffectCount> stds{};
  for (const auto& name : j["effects"]) {
    if (!name.is_string()) fail("'effects' holds a non-string");
    auto e = model::effect_from_name(name.get<std::string>());
    if (!e) fail("unknown effect '" + name.get<std::string>() + "' in 'effects'");
    m.params.effects.add(*e);
    const auto& ei = info(*e);
    if (ei.num_params == 0) continue;
    const auto params = j.contains("parameters") ? j["parameters"] : nlohmann::json::object();
    if (!params.contains(ei.name))
      fail("parameters of effect '" + std::string(ei.name) + "' missing");
    const auto& block = params[ei.name];
    for (int i = 0; i < ei.num_params; ++i) {
      const std::string key = std::string("parameters.") + ei.name + "." + ei.params[i].name;
      if (!block.contains(ei.params[i].name)) fail("key '" + key + "' missing");
      const auto& p = block[ei.params[i].name];
      if (!p.contains("value") || !p["value"].is_number())
        fail("key '" + key + ".value' missing or not a number");
      m.params.block(*e)[i] = p["value"].get<double>();
      if (p.contains("std") && p["std"].is_number()) {
        stds[model::index(*e)][i] = p["std"].get<double>();
        any_std = true;
      }
    }
  }
  if (any_std) m.std = stds;
  if (j.contains("user_effects")) read_user_effects(j["user_effects"], m, fail);
  if (j.contains("extra")) m.extra = j["extra"];
  return m;
}

ModelFile read_model(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path.string() + ": cannot open model file");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    // parse_error, and out_of_range for a number beyond double (1e400).
    throw std::runtime_error(path.string() + ": " + e.what());
  }
  return model_from_json(j, path.string());
}

void write_model(const ModelFile& m, const std::filesystem::path& path,
                 const std::vector<std::filesystem::path>& inputs) {
  write_file_atomic(path, to_json(m).dump(2) + "\n", inputs);
}

model::EffectSet parse_effect_list(const std::string& list) {
  model::EffectSet set;
  std::stringstream ss(list);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (item.empty()) continue;
    auto e = model::effect_from_name(item);
    if (!e) {
      std::string known;
      for (Effect k : model::kAllEffects)
        known += std::string(known.empty() ? "" : ", ") + info(k).name;
      throw std::runtime_error("unknown effect '" + item + "' (known: " + known + ")");
    }
    set.add(*e);
  }
  return set;
}

std::string effect_list_string(const model::EffectSet& effects) {
  std::string out;
  for (Effect e : model::kAllEffects) {
    if (!effects.has(e)) continue;
    if (!out.empty()) out += ",";
    out += info(e).name;
  }
  return out;
}

}  // namespace zerog::io
