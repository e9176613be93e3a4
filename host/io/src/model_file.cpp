#include "zerog/io/model_file.hpp"

#include <fstream>
#include <sstream>
#include <stdexcept>

#include "zerog/io/log.hpp"

namespace zerog::io {

using model::Effect;
using model::info;

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
