#include "made_for.hpp"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <vector>

#include "zerog/formats/log.hpp"
#include "zerog/infer/deploy_file.hpp"
#include "zerog/io/effect_file.hpp"

namespace zerog::cli {
namespace {

using nlohmann::json;

// A key of "made_for" that must be a string (or null where `nullable`).
bool is_text(const json& j, const char* key, bool nullable) {
  return j.contains(key) && (j[key].is_string() || (nullable && j[key].is_null()));
}

void check_model_identity(const json& m, const std::string& doc_path) {
  const auto bad = [&](const std::string& why) {
    throw formats::InputError(doc_path, 0, 0, "made_for.model: " + why);
  };
  if (!m.is_object()) bad("expected an object or null");
  if (!m.contains("effects") || !m["effects"].is_array()) bad("\"effects\" must be a list");
  for (const auto& e : m["effects"])
    if (!e.is_string()) bad("\"effects\" must be a list of names");
  if (!is_text(m, "file", true) || !is_text(m, "crc32", true))
    bad("\"file\" and \"crc32\" must be strings or null");
}

void check_log_identity(const json& l, const std::string& doc_path) {
  if (!l.is_object() || !is_text(l, "file", false) || !is_text(l, "crc32", false) ||
      !is_text(l, "rig_file", false) || !is_text(l, "rig_crc32", false))
    throw formats::InputError(doc_path, 0, 0,
                              "made_for.log: expected {\"file\", \"crc32\", \"rig_file\", "
                              "\"rig_crc32\"}, all strings");
}

std::string model_words(const json& m, bool with_crc) {
  std::string names;
  for (const auto& e : m["effects"]) names += (names.empty() ? "" : ",") + e.get<std::string>();
  std::string out = "for model ";
  if (m["file"].is_string()) out += m["file"].get<std::string>() + " ";
  out += "[" + names + "]";
  if (with_crc && m["crc32"].is_string()) out += " (crc32 " + m["crc32"].get<std::string>() + ")";
  return out;
}

std::string log_words(const json& l, bool with_crc) {
  std::string out = "on " + l["file"].get<std::string>();
  if (with_crc)
    out += " (crc32 " + l["crc32"].get<std::string>() + ", rig " +
           l["rig_crc32"].get<std::string>() + ")";
  return out;
}

}  // namespace

std::string file_crc32(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path.string() + ": cannot open");
  // A piece at a time: a log of 10^6 rows is some 300 MB (read whole, it was the peak memory of
  // diagnose).
  std::vector<char> piece(std::size_t{1} << 20);
  std::uint32_t crc = 0;
  while (in) {
    in.read(piece.data(), static_cast<std::streamsize>(piece.size()));
    crc = infer::crc32(std::string_view(piece.data(), static_cast<std::size_t>(in.gcount())), crc);
  }
  if (in.bad()) throw std::runtime_error(path.string() + ": read failed");
  char hex[9];
  std::snprintf(hex, sizeof hex, "%08x", crc);
  return hex;
}

json model_identity(const model::EffectSet& effects, const model::UserEffects& user,
                    const std::string& model_path) {
  std::vector<std::string> names;
  for (model::Effect e : model::kAllEffects)
    if (effects.has(e)) names.emplace_back(model::info(e).name);
  for (int k = 0; k < user.num_effects; ++k) names.push_back("@" + io::user_effect_name(user, k));
  std::sort(names.begin(), names.end());
  json j;
  j["effects"] = names;
  j["file"] = model_path.empty() ? json(nullptr) : json(model_path);
  j["crc32"] = model_path.empty() ? json(nullptr) : json(file_crc32(model_path));
  return j;
}

json log_identity(const std::string& log_path) {
  const std::filesystem::path rig = formats::rig_path_for(log_path);
  return {{"file", log_path},
          {"crc32", file_crc32(log_path)},
          {"rig_file", rig.string()},
          {"rig_crc32", file_crc32(rig)}};
}

MadeForCheck check_made_for(const json& doc, const std::string& doc_path, const json& report_model,
                            const json& report_log, bool check_model) {
  MadeForCheck c;
  if (!doc.is_object() || !doc.contains("made_for")) {  // written before "made_for" existed
    c.report_for = (check_model ? model_words(report_model, false) + " " : std::string()) +
                   log_words(report_log, false);
    return c;
  }
  const json& f = doc["made_for"];
  if (!f.is_object() || !f.contains("log") || !f.contains("model"))
    throw formats::InputError(doc_path, 0, 0, "made_for: expected {\"model\", \"log\"}");
  check_log_identity(f["log"], doc_path);
  if (!f["model"].is_null()) check_model_identity(f["model"], doc_path);
  const json& l = f["log"];
  const bool same_log =
      l["crc32"] == report_log["crc32"] && l["rig_crc32"] == report_log["rig_crc32"];
  // A diagnosis is of one model: its effects, and its file's bytes when both name a file (the
  // diagnosis starts from the fitted values). A ladder climbs from its own start: the log only.
  const json& m = f["model"];
  const bool with_model = check_model && !m.is_null();  // null says nothing about the model
  bool same_effects = true, same_file = true;
  if (with_model) {
    same_effects = m["effects"] == report_model["effects"];
    same_file = m["crc32"].is_null() || report_model["crc32"].is_null() ||
                m["crc32"] == report_model["crc32"];
    const bool model_crc = same_effects && !same_file;  // the crc32 is what tells them apart
    c.made_for = model_words(m, model_crc) + " ";
    c.report_for = model_words(report_model, model_crc) + " ";
  }
  c.made_for += log_words(l, !same_log);
  c.report_for += log_words(report_log, !same_log);
  if (!same_log || !same_effects || !same_file)
    c.match = Match::other;
  else
    c.match = check_model && !with_model ? Match::unknown : Match::same;
  return c;
}

}  // namespace zerog::cli
