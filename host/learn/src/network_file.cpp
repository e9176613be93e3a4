#include "zerog/learn/network_file.hpp"

#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "zerog/formats/log.hpp"
#include "zerog/ident/compare.hpp"

namespace zerog::learn {

namespace {

constexpr std::array<const char*, 3> kKindNames = {"paper-bp", "paper-zp", "residual"};

void require(bool ok, const std::string& why) {
  if (!ok) throw std::invalid_argument("network: " + why);
}

bool all_finite(const std::vector<double>& v) {
  for (double x : v)
    if (!std::isfinite(x)) return false;
  return true;
}

}  // namespace

const char* kind_name(NetworkKind kind) { return kKindNames[static_cast<std::size_t>(kind)]; }

std::optional<NetworkKind> kind_from_name(std::string_view name) {
  for (std::size_t k = 0; k < kKindNames.size(); ++k)
    if (name == kKindNames[k]) return static_cast<NetworkKind>(k);
  return std::nullopt;
}

double ToolLoad::mass_kg() const { return gravity_base_N.norm() / model::kStandardGravity; }

void validate(const NetworkFile& n) {
  const auto& w = n.shape.width;
  require(w.size() >= 2, "needs at least an input and an output width");
  require(n.shape.activation.size() == w.size() - 1, "needs one activation per layer");
  require(n.shape.num_layers() <= model::kMaxNetworkLayers,
          "at most " + std::to_string(model::kMaxNetworkLayers) + " layers");
  for (int x : w)
    require(x >= 1 && x <= model::kMaxNetworkWidth,
            "layer widths must lie in 1.." + std::to_string(model::kMaxNetworkWidth));
  require(static_cast<int>(n.inputs.size()) == w.front(), "one input feature per input");
  require(static_cast<int>(n.output_axes.size()) == w.back(), "one output axis per output");
  for (std::size_t k = 0; k < n.output_axes.size(); ++k) {
    require(n.output_axes[k] >= 0 && n.output_axes[k] < 6, "output axes are 0..5 (Fx..Mz)");
    for (std::size_t m = 0; m < k; ++m)
      require(n.output_axes[m] != n.output_axes[k], "an output axis is listed twice");
  }
  require(static_cast<int>(n.params.size()) == n.shape.num_params(),
          "has " + std::to_string(n.params.size()) + " parameters, the shape needs " +
              std::to_string(n.shape.num_params()));
  require(all_finite(n.params), "a parameter is not finite");
  const auto& z = n.normalisation;
  const auto in = static_cast<std::size_t>(w.front()), out = static_cast<std::size_t>(w.back());
  require(z.input_mean.size() == in && z.input_scale.size() == in,
          "input normalisation needs one mean and scale per input");
  require(z.output_mean.size() == out && z.output_scale.size() == out,
          "output normalisation needs one mean and scale per output");
  for (const auto* v : {&z.input_mean, &z.input_scale, &z.output_mean, &z.output_scale})
    require(all_finite(*v), "a normalisation value is not finite");
  for (const auto* v : {&z.input_scale, &z.output_scale})
    for (double s : *v) require(s > 0, "normalisation scales must be positive");
  if (n.kind == NetworkKind::paper_zp) require(n.tool_load.has_value(), "paper-zp needs tool_load");
  if (n.kind == NetworkKind::residual) require(n.physics.has_value(), "residual needs physics");
}

nlohmann::json to_json(const NetworkFile& n) {
  validate(n);
  nlohmann::json j;
  j["format"] = "zerog-network";
  j["version"] = kNetworkFormatVersion;
  j["kind"] = kind_name(n.kind);
  j["shape"]["width"] = n.shape.width;
  j["shape"]["activation"] = nlohmann::json::array();
  for (auto a : n.shape.activation) j["shape"]["activation"].push_back(model::activation_name(a));
  j["normalisation"] = {{"input_mean", n.normalisation.input_mean},
                        {"input_scale", n.normalisation.input_scale},
                        {"output_mean", n.normalisation.output_mean},
                        {"output_scale", n.normalisation.output_scale}};
  j["inputs"] = nlohmann::json::array();
  for (auto f : n.inputs) j["inputs"].push_back(model::feature_name(f));
  j["outputs"] = nlohmann::json::array();
  for (int a : n.output_axes)
    j["outputs"].push_back(ident::kAxisNames[static_cast<std::size_t>(a)]);
  j["params"] = n.params;
  j["seed"] = n.seed;
  j["training"] = n.training;
  if (n.tool_load) {
    const ToolLoad& t = *n.tool_load;
    j["tool_load"] = {
        {"gravity_base_N", {t.gravity_base_N.x(), t.gravity_base_N.y(), t.gravity_base_N.z()}},
        {"cog_sensor_m", {t.cog_sensor_m.x(), t.cog_sensor_m.y(), t.cog_sensor_m.z()}},
        {"mass_kg", t.mass_kg()},
        {"poses", t.poses}};
  }
  if (n.physics) j["physics"] = io::to_json(*n.physics);
  return j;
}

NetworkFile network_from_json(const nlohmann::json& j, const std::string& source) {
  std::string key;
  try {
    NetworkFile n;
    key = "format";
    if (j.at("format").get<std::string>() != "zerog-network")
      throw std::runtime_error("is not \"zerog-network\"");
    key = "version";
    if (j.at("version").get<int>() != kNetworkFormatVersion)
      throw std::runtime_error("unsupported version (this program reads " +
                               std::to_string(kNetworkFormatVersion) + ")");
    key = "kind";
    const auto kind = kind_from_name(j.at("kind").get<std::string>());
    if (!kind) throw std::runtime_error("must be paper-bp, paper-zp or residual");
    n.kind = *kind;
    key = "shape.width";
    n.shape.width = j.at("shape").at("width").get<std::vector<int>>();
    key = "shape.activation";
    for (const auto& a : j.at("shape").at("activation")) {
      model::Activation act;
      if (!model::activation_from_name(a.get<std::string>().c_str(), act))
        throw std::runtime_error("unknown activation '" + a.get<std::string>() + "'");
      n.shape.activation.push_back(act);
    }
    key = "normalisation";
    const auto& z = j.at("normalisation");
    n.normalisation.input_mean = z.at("input_mean").get<std::vector<double>>();
    n.normalisation.input_scale = z.at("input_scale").get<std::vector<double>>();
    n.normalisation.output_mean = z.at("output_mean").get<std::vector<double>>();
    n.normalisation.output_scale = z.at("output_scale").get<std::vector<double>>();
    key = "inputs";
    for (const auto& f : j.at("inputs")) {
      model::Feature feat;
      if (!model::feature_from_name(f.get<std::string>(), feat))
        throw std::runtime_error("unknown feature '" + f.get<std::string>() + "'");
      n.inputs.push_back(feat);
    }
    key = "outputs";
    for (const auto& o : j.at("outputs")) {
      const std::string name = o.get<std::string>();
      int axis = -1;
      for (int a = 0; a < 6; ++a)
        if (name == ident::kAxisNames[static_cast<std::size_t>(a)]) axis = a;
      if (axis < 0) throw std::runtime_error("unknown axis '" + name + "' (Fx Fy Fz Mx My Mz)");
      n.output_axes.push_back(axis);
    }
    key = "params";
    n.params = j.at("params").get<std::vector<double>>();
    key = "seed";
    n.seed = j.at("seed").get<std::uint64_t>();
    key = "training";
    if (j.contains("training")) n.training = j.at("training");
    if (j.contains("tool_load")) {
      key = "tool_load";
      const auto& t = j.at("tool_load");
      ToolLoad tl;
      const auto g = t.at("gravity_base_N").get<std::array<double, 3>>();
      const auto r = t.at("cog_sensor_m").get<std::array<double, 3>>();
      tl.gravity_base_N = {g[0], g[1], g[2]};
      tl.cog_sensor_m = {r[0], r[1], r[2]};
      tl.poses = t.value("poses", 0);
      n.tool_load = tl;
    }
    if (j.contains("physics")) {
      key = "physics";
      n.physics = io::model_from_json(j.at("physics"), source + " (physics)");
    }
    key = "";
    validate(n);
    return n;
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error(source + ": key '" + key + "': " + e.what());
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(source + ": " + e.what());
  } catch (const std::runtime_error& e) {
    if (key.empty()) throw;
    throw std::runtime_error(source + ": key '" + key + "' " + e.what());
  }
}

NetworkFile read_network(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path.string() + ": cannot open");
  nlohmann::json j;
  try {
    in >> j;
  } catch (const nlohmann::json::parse_error& e) {
    throw std::runtime_error(path.string() + ": not valid JSON: " + e.what());
  }
  return network_from_json(j, path.string());
}

void write_network(const NetworkFile& n, const std::filesystem::path& path,
                   const std::vector<std::filesystem::path>& inputs) {
  formats::write_file_atomic(path, to_json(n).dump(1) + "\n", inputs);
}

void round_to_float(NetworkFile& n) {
  auto r = [](std::vector<double>& v) {
    for (double& x : v) x = static_cast<double>(static_cast<float>(x));
  };
  r(n.params);
  r(n.normalisation.input_mean);
  r(n.normalisation.input_scale);
  r(n.normalisation.output_mean);
  r(n.normalisation.output_scale);
}

}  // namespace zerog::learn
