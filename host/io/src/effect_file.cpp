#include "zerog/io/effect_file.hpp"

#include <cmath>
#include <cstring>
#include <sstream>
#include <stdexcept>

#include "zerog/formats/log.hpp"
#include "zerog/formats/toml_table.hpp"
#include "zerog/io/model_file.hpp"

namespace zerog::io {

using formats::InputError;
using formats::number_text;
using formats::parse_toml_file;
using formats::TomlTable;
using formats::write_file_atomic;
namespace {

namespace fs = std::filesystem;

constexpr const char* kDoc = "proto/user_effects.md";

std::string unit_in_parentheses(const std::string& u) {
  return (u.find('/') != std::string::npos || u.find('*') != std::string::npos) ? "(" + u + ")" : u;
}

bool valid_name(const std::string& s) {
  if (s.empty() || s.size() >= static_cast<std::size_t>(model::kUserNameSize)) return false;
  for (char c : s) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '_' || c == '-';
    if (!ok) return false;
  }
  return true;
}

int add_effect_name(model::UserEffects& u, const std::string& name) {
  for (int k = 0; k < u.num_effects; ++k)
    if (user_effect_name(u, k) == name)
      throw std::runtime_error("user effect '" + name + "' is given twice");
  if (model::effect_from_name(name))
    throw std::runtime_error("user effect '" + name +
                             "' has the name of a library effect: choose another");
  if (u.num_effects >= model::kMaxUserEffects)
    throw std::runtime_error("more than " + std::to_string(model::kMaxUserEffects) +
                             " user effects in one model");
  auto& slot = u.names[static_cast<std::size_t>(u.num_effects)];
  slot.fill('\0');
  std::memcpy(slot.data(), name.data(), name.size());
  return u.num_effects++;
}

}  // namespace

std::string term_axis_name(const model::UserTerm& t) {
  return std::string(model::kWrenchAxisNames[t.axis]) +
         (t.frame == model::TermFrame::base ? "_B" : "");
}

std::string basis_text(const model::Basis& b) {
  char buf[128];
  model::format_basis(b, buf, sizeof buf);
  return buf;
}

std::string coefficient_unit(const model::UserTerm& t) {
  char buf[64];
  model::basis_unit(t.basis, buf, sizeof buf);
  const std::string axis_unit = t.axis < 3 ? "N" : "N*m";
  if (std::strcmp(buf, "1") == 0) return axis_unit;
  return axis_unit + "/" + unit_in_parentheses(buf);
}

std::string user_effect_name(const model::UserEffects& u, int k) {
  return std::string(u.names[static_cast<std::size_t>(k)].data());
}

std::string term_label(const model::UserEffects& u, int term) {
  const model::UserTerm& t = u.terms[static_cast<std::size_t>(term)];
  return user_effect_name(u, t.effect) + "." + term_axis_name(t) + "*" + basis_text(t.basis) +
         " [" + coefficient_unit(t) + "]";
}

void read_effect_file(const fs::path& path, model::UserEffects& into) {
  const toml::table root = parse_toml_file(path);
  const TomlTable top(root, path, "", {"format", "version", "name", "description", "term"}, kDoc);
  if (top.string("format") != "zerog-effect")
    top.fail("format", "must be \"zerog-effect\" (this is not an effect file)");
  const std::int64_t version = top.integer("version");
  if (version != kEffectFileVersion)
    top.fail("version", "version " + std::to_string(version) +
                            " is not supported (this zerog reads " +
                            std::to_string(kEffectFileVersion) + ")");
  const std::string name = top.string("name");
  if (!valid_name(name))
    top.fail("name", "must be 1 to " + std::to_string(model::kUserNameSize - 1) +
                         " letters, digits, '_' or '-'");
  const toml::node& terms_node = top.require("term");
  const toml::array* terms = terms_node.as_array();
  if (terms == nullptr || !terms->is_array_of_tables() || terms->empty())
    top.fail("term", "must be one or more [[term]] tables");

  model::UserEffects u = into;  // all or nothing
  int effect = 0;
  try {
    effect = add_effect_name(u, name);
  } catch (const std::runtime_error& e) {
    top.fail("name", e.what());
  }
  for (std::size_t i = 0; i < terms->size(); ++i) {
    const toml::table& tt = *terms->get(i)->as_table();
    const TomlTable t(tt, path, "term[" + std::to_string(i + 1) + "].",
                      {"axis", "vector", "frame", "basis", "value", "std", "unit"}, kDoc);
    model::TermFrame frame = model::TermFrame::sensor;
    const std::string frame_text = t.optional_string("frame", "sensor");
    if (frame_text == "base") {
      frame = model::TermFrame::base;
    } else if (frame_text != "sensor") {
      t.fail("frame", "must be \"sensor\" or \"base\"");
    }
    // The basis: its error points at the character where parsing stopped.
    const std::string basis_str = t.string("basis");
    model::Basis basis;
    const char* error = nullptr;
    std::size_t error_pos = 0;
    if (!model::parse_basis(basis_str, basis, error, error_pos)) {
      const toml::source_region& where = t.where("basis");
      throw InputError(path, static_cast<int>(where.begin.line),
                       static_cast<int>(where.begin.column + 1 + error_pos),
                       "'" + t.name("basis") + "' \"" + basis_str + "\": " + error + " (" + kDoc +
                           " lists the signals)");
    }
    std::vector<int> axes;
    const bool has_axis = t.find("axis") != nullptr, has_vector = t.find("vector") != nullptr;
    if (has_axis == has_vector)
      t.fail(has_axis ? "vector" : "axis",
             "give either 'axis' (Fx, Fy, Fz, Mx, My, Mz) or 'vector' (force, torque)");
    if (has_axis) {
      const int k = model::wrench_axis_from_name(t.string("axis"));
      if (k < 0) t.fail("axis", "must be one of Fx, Fy, Fz, Mx, My, Mz");
      axes.push_back(k);
    } else {
      const std::string v = t.string("vector");
      if (v != "force" && v != "torque") t.fail("vector", "must be \"force\" or \"torque\"");
      for (int q = 0; q < 3; ++q) axes.push_back(v == "force" ? q : 3 + q);
    }
    std::vector<double> values(axes.size(), 0.0);
    if (const toml::node* node = t.find("value")) {
      if (axes.size() == 1) {
        values[0] = t.number(*node, "value");
      } else {
        values = t.numbers("value", 3);
      }
    }
    if (t.find("std")) {
      if (axes.size() == 1)
        t.number("std", 0.0, false);
      else
        t.numbers("std", 3);
    }
    for (std::size_t q = 0; q < axes.size(); ++q) {
      model::UserTerm term;
      term.basis = basis;
      term.axis = static_cast<std::uint8_t>(axes[q]);
      term.frame = frame;
      term.effect = static_cast<std::uint8_t>(effect);
      if (t.find("unit") && t.string("unit") != coefficient_unit(term))
        t.fail("unit", "is \"" + t.string("unit") + "\" but " + term_axis_name(term) + " · " +
                           basis_str + " needs a coefficient in \"" + coefficient_unit(term) +
                           "\"");
      for (int j = 0; j < u.num_terms; ++j) {
        const auto& other = u.terms[static_cast<std::size_t>(j)];
        if (other.basis == term.basis && other.axis == term.axis && other.frame == term.frame)
          t.fail("basis", "the term " + term_axis_name(term) + " · " + basis_str +
                              " is already in the model (" + user_effect_name(u, other.effect) +
                              ")");
      }
      if (u.num_terms >= model::kMaxUserTerms)
        t.fail("basis",
               "more than " + std::to_string(model::kMaxUserTerms) + " user terms in one model");
      u.terms[static_cast<std::size_t>(u.num_terms)] = term;
      u.coeff[static_cast<std::size_t>(u.num_terms)] = values[q];
      ++u.num_terms;
    }
  }
  into = u;
}

std::string effect_file_text(const model::UserEffects& u, int k, const std::vector<double>* std,
                             const std::string& description,
                             const std::vector<std::string>& comment) {
  std::ostringstream os;
  for (const std::string& line : comment) os << "# " << line << "\n";
  os << "format = \"zerog-effect\"\n";
  os << "version = " << kEffectFileVersion << "\n";
  os << "name = \"" << user_effect_name(u, k) << "\"\n";
  if (!description.empty()) {
    std::string d;
    for (char c : description) {
      if (c == '"' || c == '\\') d += '\\';
      d += c;
    }
    os << "description = \"" << d << "\"\n";
  }
  for (int j = 0; j < u.num_terms; ++j) {
    const model::UserTerm& t = u.terms[static_cast<std::size_t>(j)];
    if (t.effect != k) continue;
    os << "\n[[term]]\n";
    os << "axis = \"" << model::kWrenchAxisNames[t.axis] << "\"\n";
    if (t.frame == model::TermFrame::base) os << "frame = \"base\"\n";
    os << "basis = \"" << basis_text(t.basis) << "\"\n";
    os << "unit = \"" << coefficient_unit(t) << "\"\n";
    os << "value = " << number_text(u.coeff[static_cast<std::size_t>(j)]) << "\n";
    if (std && static_cast<std::size_t>(j) < std->size() && std::isfinite((*std)[j]))
      os << "std = " << number_text((*std)[j]) << "\n";
  }
  return os.str();
}

void write_effect_file(const fs::path& path, const std::string& text,
                       const std::vector<fs::path>& inputs) {
  write_file_atomic(path, text, inputs);
}

void append_user_effects(model::UserEffects& into, const model::UserEffects& from) {
  model::UserEffects u = into;
  for (int k = 0; k < from.num_effects; ++k) {
    const int idx = add_effect_name(u, user_effect_name(from, k));
    for (int j = 0; j < from.num_terms; ++j) {
      model::UserTerm t = from.terms[static_cast<std::size_t>(j)];
      if (t.effect != k) continue;
      if (u.num_terms >= model::kMaxUserTerms)
        throw std::runtime_error("more than " + std::to_string(model::kMaxUserTerms) +
                                 " user terms in one model");
      t.effect = static_cast<std::uint8_t>(idx);
      u.terms[static_cast<std::size_t>(u.num_terms)] = t;
      u.coeff[static_cast<std::size_t>(u.num_terms)] = from.coeff[static_cast<std::size_t>(j)];
      ++u.num_terms;
    }
  }
  into = u;
}

std::vector<std::string> split_list(const std::string& list) {
  std::vector<std::string> out;
  std::stringstream ss(list);
  std::string item;
  while (std::getline(ss, item, ',')) {
    while (!item.empty() && item.front() == ' ') item.erase(item.begin());
    while (!item.empty() && item.back() == ' ') item.pop_back();
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

ModelSpec parse_model_spec(const std::string& list) {
  ModelSpec spec;
  std::string library;
  for (const std::string& item : split_list(list)) {
    if (item.front() == '@') {
      const fs::path file = item.substr(1);
      if (file.empty())
        throw std::runtime_error("'@' needs an effect file's path (@my_effect.toml)");
      if (file.extension() == ".json") {
        // A model file (zerog fit): its user-defined effects, with their values as start values.
        append_user_effects(spec.user, read_model(file).params.user);
      } else {
        read_effect_file(file, spec.user);
      }
      spec.files.push_back(file);
    } else {
      library += (library.empty() ? "" : ",") + item;
    }
  }
  spec.effects = parse_effect_list(library);
  return spec;
}

std::string model_spec_string(const model::EffectSet& effects, const model::UserEffects& user,
                              const std::vector<fs::path>& files) {
  std::string s = effect_list_string(effects);
  if (!files.empty()) {
    for (const fs::path& f : files) s += (s.empty() ? "@" : ",@") + f.string();
    return s;
  }
  for (int k = 0; k < user.num_effects; ++k)
    s += (s.empty() ? "@" : ",@") + user_effect_name(user, k);
  return s;
}

}  // namespace zerog::io
