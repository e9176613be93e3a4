#include "zerog/infer/deploy_file.hpp"

#include "zerog/model/dictionary.hpp"

#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>

#include "zerog/infer/quant_math.hpp"

namespace zerog::infer {
namespace {

using nlohmann::json;
using nlohmann::ordered_json;

constexpr std::string_view kMagic = "zerog-deploy";
constexpr std::size_t kMaxHeader = 256;

struct Fail {
  LoadError error;
  std::string message;
};

[[noreturn]] void fail(LoadError e, std::string msg) { throw Fail{e, std::move(msg)}; }

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

const json& at(const json& j, const char* key, const std::string& where) {
  if (!j.is_object()) fail(LoadError::invalid_value, where + " is not an object");
  const auto it = j.find(key);
  if (it == j.end()) fail(LoadError::invalid_value, "missing key '" + where + "." + key + "'");
  return *it;
}

double number(const json& j, const std::string& where) {
  if (!j.is_number()) fail(LoadError::invalid_value, where + " is not a number");
  const double v = j.get<double>();
  if (!std::isfinite(v)) fail(LoadError::invalid_value, where + " is not finite");
  return v;
}

std::string text(const json& j, const std::string& where) {
  if (!j.is_string()) fail(LoadError::invalid_value, where + " is not a string");
  return j.get<std::string>();
}

std::vector<double> numbers(const json& j, const std::string& where) {
  if (!j.is_array()) fail(LoadError::invalid_value, where + " is not an array");
  std::vector<double> v;
  v.reserve(j.size());
  for (std::size_t i = 0; i < j.size(); ++i)
    v.push_back(number(j[i], where + "[" + std::to_string(i) + "]"));
  return v;
}

std::vector<std::int64_t> integers(const json& j, const std::string& where) {
  if (!j.is_array()) fail(LoadError::invalid_value, where + " is not an array");
  std::vector<std::int64_t> v;
  v.reserve(j.size());
  for (std::size_t i = 0; i < j.size(); ++i) {
    if (!j[i].is_number_integer())
      fail(LoadError::invalid_value, where + "[" + std::to_string(i) + "] is not an integer");
    v.push_back(j[i].get<std::int64_t>());
  }
  return v;
}

Eigen::Vector3d vec3(const json& j, const std::string& where) {
  const std::vector<double> v = numbers(j, where);
  if (v.size() != 3)
    fail(LoadError::inconsistent_sizes,
         where + " has " + std::to_string(v.size()) + " values, not 3");
  return {v[0], v[1], v[2]};
}

Eigen::Quaterniond quat(const json& j, const std::string& where) {
  const std::vector<double> v = numbers(j, where);
  if (v.size() != 4)
    fail(LoadError::inconsistent_sizes,
         where + " has " + std::to_string(v.size()) + " values, not 4");
  return {v[0], v[1], v[2], v[3]};
}

ordered_json pose_json(const Eigen::Vector3d& p, const Eigen::Quaterniond& q) {
  return {{"p_m", {p.x(), p.y(), p.z()}}, {"q_wxyz", {q.w(), q.x(), q.y(), q.z()}}};
}

ordered_json to_json(const DeployedModel& m) {
  ordered_json j;
  const RigDescription& r = m.rig;
  j["rig"] = {{"name", r.name},
              {"robot", r.robot},
              {"flange_sensor", pose_json(r.p_flange_sensor_m, r.q_flange_sensor)},
              {"sensor_imu", pose_json(r.p_sensor_imu_m, r.q_sensor_imu)},
              {"sample_period_s", r.sample_period_s}};
  ordered_json effects = ordered_json::array();
  ordered_json params = ordered_json::object();
  for (model::Effect e : model::kAllEffects) {
    if (!m.physics.effects.has(e)) continue;
    const model::EffectInfo& info = model::info(e);
    effects.push_back(info.name);
    if (info.num_params == 0) continue;
    ordered_json block = ordered_json::object();
    for (int k = 0; k < info.num_params; ++k) block[info.params[k].name] = m.physics.block(e)[k];
    params[info.name] = block;
  }
  j["physics"] = {{"effects", effects}, {"parameters", params}};
  // User-defined effects (proto/user_effects.md): one entry per term, in order.
  const model::UserEffects& u = m.physics.user;
  if (!u.empty()) {
    ordered_json terms = ordered_json::array();
    for (int t = 0; t < u.num_terms; ++t) {
      const model::UserTerm& term = u.terms[static_cast<std::size_t>(t)];
      char basis[128];
      model::format_basis(term.basis, basis, sizeof basis);
      terms.push_back({{"effect", std::string(u.names[term.effect].data())},
                       {"axis", model::kWrenchAxisNames[term.axis]},
                       {"frame", term.frame == model::TermFrame::base ? "base" : "sensor"},
                       {"basis", basis},
                       {"value", u.coeff[static_cast<std::size_t>(t)]}});
    }
    j["physics"]["user_terms"] = terms;
  }
  if (!m.network) {
    j["network"] = nullptr;
  } else {
    const DeployedNetwork& n = *m.network;
    ordered_json net;
    ordered_json feats = ordered_json::array();
    for (model::Feature f : n.features) feats.push_back(model::feature_name(f));
    net["features"] = feats;
    ordered_json outs = ordered_json::array();
    for (int a : n.output_axes) outs.push_back(kAxisNames[a]);
    net["outputs"] = outs;
    net["normalisation"] = {{"input_mean", n.normalisation.input_mean},
                            {"input_scale", n.normalisation.input_scale},
                            {"output_mean", n.normalisation.output_mean},
                            {"output_scale", n.normalisation.output_scale}};
    net["quantisation"] = {{"weight_bits", n.quantised.weight_bits},
                           {"activation_bits", 16},
                           {"accumulator_bits", n.quantised.weight_bits == 8 ? 32 : 64},
                           {"input_clip", n.quantised.input_clip}};
    ordered_json layers = ordered_json::array();
    const double* p = n.params.data();
    for (int l = 0; l < n.shape.num_layers(); ++l) {
      const int in = n.shape.width[l], out = n.shape.width[l + 1];
      const QuantisedLayer& q = n.quantised.layers[static_cast<std::size_t>(l)];
      ordered_json layer;
      layer["inputs"] = in;
      layer["outputs"] = out;
      layer["activation"] = model::activation_name(n.shape.activation[l]);
      layer["weights"] = std::vector<double>(p, p + in * out);
      layer["bias"] = std::vector<double>(p + in * out, p + in * out + out);
      layer["q_weights"] = q.weights;
      layer["q_weight_scale"] = q.weight_scale;
      layer["q_bias"] = q.bias;
      layer["q_input_scale"] = q.input_scale;
      layer["q_output_scale"] = q.output_scale;
      layers.push_back(layer);
      p += in * out + out;
    }
    net["layers"] = layers;
    j["network"] = net;
  }
  j["provenance"] = ordered_json::parse(m.provenance_json.empty() ? "{}" : m.provenance_json);
  return j;
}

RigDescription rig_from_json(const json& j) {
  RigDescription r;
  r.name = text(at(j, "name", "rig"), "rig.name");
  r.robot = text(at(j, "robot", "rig"), "rig.robot");
  const json& fs = at(j, "flange_sensor", "rig");
  r.p_flange_sensor_m = vec3(at(fs, "p_m", "rig.flange_sensor"), "rig.flange_sensor.p_m");
  r.q_flange_sensor = quat(at(fs, "q_wxyz", "rig.flange_sensor"), "rig.flange_sensor.q_wxyz");
  const json& si = at(j, "sensor_imu", "rig");
  r.p_sensor_imu_m = vec3(at(si, "p_m", "rig.sensor_imu"), "rig.sensor_imu.p_m");
  r.q_sensor_imu = quat(at(si, "q_wxyz", "rig.sensor_imu"), "rig.sensor_imu.q_wxyz");
  r.sample_period_s = number(at(j, "sample_period_s", "rig"), "rig.sample_period_s");
  return r;
}

model::ModelParams physics_from_json(const json& j) {
  model::ModelParams p;
  const json& effects = at(j, "effects", "physics");
  if (!effects.is_array()) fail(LoadError::invalid_value, "physics.effects is not an array");
  const json& params = at(j, "parameters", "physics");
  if (!params.is_object()) fail(LoadError::invalid_value, "physics.parameters is not an object");
  for (std::size_t i = 0; i < effects.size(); ++i) {
    const std::string name = text(effects[i], "physics.effects[" + std::to_string(i) + "]");
    const auto e = model::effect_from_name(name);
    if (!e)
      fail(LoadError::unknown_effect,
           "physics.effects[" + std::to_string(i) + "]: unknown effect '" + name + "'");
    p.effects.add(*e);
  }
  for (const auto& [name, block] : params.items()) {
    const auto e = model::effect_from_name(name);
    if (!e) fail(LoadError::unknown_effect, "physics.parameters: unknown effect '" + name + "'");
    if (!p.effects.has(*e))
      fail(LoadError::invalid_value,
           "physics.parameters." + name + ": effect not in physics.effects");
    const model::EffectInfo& info = model::info(*e);
    if (!block.is_object())
      fail(LoadError::invalid_value, "physics.parameters." + name + " is not an object");
    for (const auto& [pname, value] : block.items()) {
      int k = 0;
      while (k < info.num_params && pname != info.params[k].name) ++k;
      if (k == info.num_params)
        fail(LoadError::unknown_effect, "physics.parameters." + name + ": effect '" + name +
                                            "' has no parameter '" + pname + "'");
      p.block(*e)[k] = number(value, "physics.parameters." + name + "." + pname);
    }
    if (block.size() != static_cast<std::size_t>(info.num_params))
      fail(LoadError::inconsistent_sizes,
           "physics.parameters." + name + " has " + std::to_string(block.size()) +
               " parameters, effect '" + name + "' has " + std::to_string(info.num_params));
  }
  for (model::Effect e : model::kAllEffects) {
    if (p.effects.has(e) && model::info(e).num_params > 0 && !params.contains(model::info(e).name))
      fail(LoadError::invalid_value,
           std::string("missing key 'physics.parameters.") + model::info(e).name + "'");
  }
  if (j.contains("user_terms")) {
    const json& terms = j["user_terms"];
    if (!terms.is_array()) fail(LoadError::invalid_value, "physics.user_terms is not an array");
    model::UserEffects& u = p.user;
    for (std::size_t t = 0; t < terms.size(); ++t) {
      const std::string where = "physics.user_terms[" + std::to_string(t) + "]";
      if (u.num_terms >= model::kMaxUserTerms)
        fail(LoadError::inconsistent_sizes,
             where + ": more than " + std::to_string(model::kMaxUserTerms) + " user terms");
      model::UserTerm term;
      const std::string effect = text(at(terms[t], "effect", where), where + ".effect");
      if (effect.empty() || effect.size() >= static_cast<std::size_t>(model::kUserNameSize))
        fail(LoadError::invalid_value,
             where + ".effect: 1 to " + std::to_string(model::kUserNameSize - 1) + " characters");
      int k = 0;
      while (k < u.num_effects && effect != u.names[static_cast<std::size_t>(k)].data()) ++k;
      if (k == u.num_effects) {
        if (u.num_effects >= model::kMaxUserEffects)
          fail(LoadError::inconsistent_sizes, where + ": too many user effects");
        std::copy(effect.begin(), effect.end(), u.names[static_cast<std::size_t>(k)].begin());
        ++u.num_effects;
      }
      term.effect = static_cast<std::uint8_t>(k);
      const int a =
          model::wrench_axis_from_name(text(at(terms[t], "axis", where), where + ".axis"));
      if (a < 0) fail(LoadError::invalid_value, where + ".axis: not one of Fx Fy Fz Mx My Mz");
      term.axis = static_cast<std::uint8_t>(a);
      const std::string frame = text(at(terms[t], "frame", where), where + ".frame");
      if (frame != "sensor" && frame != "base")
        fail(LoadError::invalid_value, where + ".frame: not sensor or base");
      term.frame = frame == "base" ? model::TermFrame::base : model::TermFrame::sensor;
      const std::string basis = text(at(terms[t], "basis", where), where + ".basis");
      const char* error = nullptr;
      std::size_t pos = 0;
      if (!model::parse_basis(basis, term.basis, error, pos))
        fail(LoadError::invalid_value, where + ".basis '" + basis + "' at character " +
                                           std::to_string(pos + 1) + ": " + error);
      u.terms[static_cast<std::size_t>(u.num_terms)] = term;
      u.coeff[static_cast<std::size_t>(u.num_terms)] =
          number(at(terms[t], "value", where), where + ".value");
      ++u.num_terms;
    }
  }
  return p;
}

DeployedNetwork network_from_json(const json& j) {
  DeployedNetwork n;
  const json& feats = at(j, "features", "network");
  if (!feats.is_array()) fail(LoadError::invalid_value, "network.features is not an array");
  for (std::size_t i = 0; i < feats.size(); ++i) {
    const std::string name = text(feats[i], "network.features[" + std::to_string(i) + "]");
    model::Feature f{};
    if (!model::feature_from_name(name, f))
      fail(LoadError::unknown_feature,
           "network.features[" + std::to_string(i) + "]: unknown feature '" + name + "'");
    n.features.push_back(f);
  }
  const json& outs = at(j, "outputs", "network");
  if (!outs.is_array()) fail(LoadError::invalid_value, "network.outputs is not an array");
  for (std::size_t k = 0; k < outs.size(); ++k) {
    const std::string where = "network.outputs[" + std::to_string(k) + "]";
    const std::string name = text(outs[k], where);
    int axis = 0;
    while (axis < 6 && name != kAxisNames[axis]) ++axis;
    if (axis == 6)
      fail(LoadError::invalid_value, where + ": '" + name + "' is not a wrench axis (Fx..Mz)");
    n.output_axes.push_back(axis);
  }
  const json& norm = at(j, "normalisation", "network");
  n.normalisation.input_mean =
      numbers(at(norm, "input_mean", "network.normalisation"), "network.normalisation.input_mean");
  n.normalisation.input_scale = numbers(at(norm, "input_scale", "network.normalisation"),
                                        "network.normalisation.input_scale");
  n.normalisation.output_mean = numbers(at(norm, "output_mean", "network.normalisation"),
                                        "network.normalisation.output_mean");
  n.normalisation.output_scale = numbers(at(norm, "output_scale", "network.normalisation"),
                                         "network.normalisation.output_scale");
  const json& q = at(j, "quantisation", "network");
  const json& bits = at(q, "weight_bits", "network.quantisation");
  if (!bits.is_number_integer())
    fail(LoadError::invalid_value, "network.quantisation.weight_bits is not an integer");
  n.quantised.weight_bits = bits.get<int>();
  n.quantised.input_clip =
      number(at(q, "input_clip", "network.quantisation"), "network.quantisation.input_clip");
  const json& act_bits = at(q, "activation_bits", "network.quantisation");
  if (!act_bits.is_number_integer() || act_bits.get<int>() != 16)
    fail(LoadError::invalid_value, "network.quantisation.activation_bits must be 16");
  const json& layers = at(j, "layers", "network");
  if (!layers.is_array() || layers.empty())
    fail(LoadError::invalid_value, "network.layers is not a non-empty array");
  for (std::size_t l = 0; l < layers.size(); ++l) {
    const std::string where = "network.layers[" + std::to_string(l) + "]";
    const json& L = layers[l];
    const json& in = at(L, "inputs", where);
    const json& out = at(L, "outputs", where);
    if (!in.is_number_integer() || !out.is_number_integer())
      fail(LoadError::invalid_value, where + ": inputs and outputs must be integers");
    if (l == 0)
      n.shape.width.push_back(in.get<int>());
    else if (in.get<int>() != n.shape.width.back())
      fail(LoadError::inconsistent_sizes, where + " has " + std::to_string(in.get<int>()) +
                                              " inputs, the layer before has " +
                                              std::to_string(n.shape.width.back()) + " outputs");
    n.shape.width.push_back(out.get<int>());
    const std::string act = text(at(L, "activation", where), where + ".activation");
    model::Activation a{};
    if (!model::activation_from_name(act.c_str(), a))
      fail(LoadError::unknown_activation, where + ".activation: unknown activation '" + act + "'");
    n.shape.activation.push_back(a);
    for (double v : numbers(at(L, "weights", where), where + ".weights")) n.params.push_back(v);
    // Sizes are checked by validate_model; keep the counts here to place the bias correctly.
    const std::vector<double> bias = numbers(at(L, "bias", where), where + ".bias");
    n.params.insert(n.params.end(), bias.begin(), bias.end());
    const std::size_t expect_w = static_cast<std::size_t>(std::max(0, in.get<int>())) *
                                 static_cast<std::size_t>(std::max(0, out.get<int>()));
    if (at(L, "weights", where).size() != expect_w ||
        bias.size() != static_cast<std::size_t>(out.get<int>()))
      fail(LoadError::inconsistent_sizes,
           where + ": " + std::to_string(at(L, "weights", where).size()) + " weights and " +
               std::to_string(bias.size()) + " biases for " + std::to_string(in.get<int>()) +
               " inputs × " + std::to_string(out.get<int>()) + " outputs");
    QuantisedLayer ql;
    for (std::int64_t w : integers(at(L, "q_weights", where), where + ".q_weights")) {
      if (w < -32767 || w > 32767)
        fail(LoadError::invalid_value,
             where + ".q_weights: " + std::to_string(w) + " outside int16");
      ql.weights.push_back(static_cast<std::int16_t>(w));
    }
    ql.weight_scale = numbers(at(L, "q_weight_scale", where), where + ".q_weight_scale");
    ql.bias = integers(at(L, "q_bias", where), where + ".q_bias");
    ql.input_scale = number(at(L, "q_input_scale", where), where + ".q_input_scale");
    ql.output_scale = number(at(L, "q_output_scale", where), where + ".q_output_scale");
    n.quantised.layers.push_back(std::move(ql));
  }
  return n;
}

std::optional<std::uint64_t> parse_uint(std::string_view s, int base) {
  std::uint64_t v = 0;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v, base);
  if (ec != std::errc() || ptr != s.data() + s.size() || s.empty()) return std::nullopt;
  return v;
}

DeployedModel parse(std::string_view bytes, const RigDescription& running) {
  if (bytes.empty()) fail(LoadError::truncated, "truncated: the file is empty");
  const std::size_t nl = bytes.substr(0, kMaxHeader).find('\n');
  if (nl == std::string_view::npos) {
    const std::size_t k = std::min(bytes.size(), kMagic.size());
    if (bytes.size() < kMaxHeader && bytes.substr(0, k) == kMagic.substr(0, k))
      fail(LoadError::truncated, "truncated: the header line is cut short (" +
                                     std::to_string(bytes.size()) + " bytes, no newline)");
    fail(LoadError::not_deploy_file,
         "not a zerog deployed-model file (no 'zerog-deploy' header line)");
  }
  std::istringstream header{std::string(bytes.substr(0, nl))};
  std::string magic, version, length_kv, crc_kv, extra;
  header >> magic >> version >> length_kv >> crc_kv >> extra;
  if (magic != kMagic)
    fail(LoadError::not_deploy_file,
         "not a zerog deployed-model file (first word '" + magic + "', expected 'zerog-deploy')");
  const auto v = parse_uint(version, 10);
  if (!v) fail(LoadError::invalid_value, "header: version '" + version + "' is not a number");
  if (*v != static_cast<std::uint64_t>(kDeployFormatVersion))
    fail(LoadError::wrong_version, "wrong version: file format version " + version +
                                       ", this firmware loads version " +
                                       std::to_string(kDeployFormatVersion) + " only");
  if (length_kv.rfind("length=", 0) != 0 || crc_kv.rfind("crc32=", 0) != 0 || !extra.empty())
    fail(LoadError::invalid_value, "header: expected 'zerog-deploy 1 length=N crc32=XXXXXXXX'");
  const auto length = parse_uint(std::string_view(length_kv).substr(7), 10);
  const auto crc = parse_uint(std::string_view(crc_kv).substr(6), 16);
  if (!length || !crc || crc_kv.size() != 6 + 8)
    fail(LoadError::invalid_value,
         "header: malformed length or crc32 ('" + length_kv + "', '" + crc_kv + "')");
  const std::string_view body = bytes.substr(nl + 1);
  if (body.size() < *length)
    fail(LoadError::truncated, "truncated: the header declares " + std::to_string(*length) +
                                   " bytes of content, the file has " +
                                   std::to_string(body.size()));
  if (body.size() > *length)
    fail(LoadError::corrupt,
         "corrupt: " + std::to_string(body.size() - *length) + " bytes after the declared content");
  const std::uint32_t actual = crc32(body);
  if (actual != *crc) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "corrupt: CRC-32 of the content is %08x, the header says %08x",
                  actual, static_cast<unsigned>(*crc));
    fail(LoadError::corrupt, buf);
  }
  json j;
  try {
    j = json::parse(body);
  } catch (const json::exception& e) {
    fail(LoadError::invalid_value, std::string("content is not valid JSON: ") + e.what());
  }
  DeployedModel m;
  m.rig = rig_from_json(at(j, "rig", "content"));
  m.physics = physics_from_json(at(j, "physics", "content"));
  const json& net = at(j, "network", "content");
  if (!net.is_null()) m.network = network_from_json(net);
  if (j.contains("provenance")) m.provenance_json = j["provenance"].dump();
  LoadError err = LoadError::none;
  if (const zerog::Status st = validate_model(m, &err); !st.ok()) fail(err, st.text());
  if (std::string why = rig_mismatch(m.rig, running); !why.empty())
    fail(LoadError::wrong_rig, "wrong rig: " + why);
  return m;
}

bool positive_finite(double v) { return std::isfinite(v) && v > 0.0; }

}  // namespace

model::RigGeometry RigDescription::geometry() const {
  model::RigGeometry g;
  g.R_sensor_imu = q_sensor_imu.normalized().toRotationMatrix();
  g.p_sensor_imu_m = p_sensor_imu_m;
  return g;
}

std::string rig_mismatch(const RigDescription& fitted, const RigDescription& running) {
  if (fitted.name != running.name)
    return "the model was fitted for rig '" + fitted.name + "', this is rig '" + running.name + "'";
  if (fitted.robot != running.robot)
    return "the model was fitted on robot '" + fitted.robot + "', this is '" + running.robot + "'";
  const auto pos = [](const char* what, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    const double d = (a - b).norm();
    return d > kRigPositionTolerance_m
               ? std::string(what) + " differs by " + fmt(d * 1e3) + " mm from the model's rig"
               : std::string();
  };
  const auto rot = [](const char* what, const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
    const double d = a.normalized().angularDistance(b.normalized());
    return d > kRigAngleTolerance_rad
               ? std::string(what) + " differs by " + fmt(d * 1e3) + " mrad from the model's rig"
               : std::string();
  };
  for (const std::string& s :
       {pos("sensor position on the flange", fitted.p_flange_sensor_m, running.p_flange_sensor_m),
        rot("sensor orientation on the flange", fitted.q_flange_sensor, running.q_flange_sensor),
        pos("IMU position in the sensor frame", fitted.p_sensor_imu_m, running.p_sensor_imu_m),
        rot("IMU orientation in the sensor frame", fitted.q_sensor_imu, running.q_sensor_imu)})
    if (!s.empty()) return s;
  if (std::abs(fitted.sample_period_s - running.sample_period_s) > kRigPeriodTolerance_s)
    return "sample period " + fmt(running.sample_period_s) + " s differs from the model's " +
           fmt(fitted.sample_period_s) + " s";
  return {};
}

const char* load_error_name(LoadError e) {
  switch (e) {
    case LoadError::none:
      return "none";
    case LoadError::io:
      return "io";
    case LoadError::not_deploy_file:
      return "not_deploy_file";
    case LoadError::truncated:
      return "truncated";
    case LoadError::corrupt:
      return "corrupt";
    case LoadError::wrong_version:
      return "wrong_version";
    case LoadError::wrong_rig:
      return "wrong_rig";
    case LoadError::unknown_effect:
      return "unknown_effect";
    case LoadError::unknown_feature:
      return "unknown_feature";
    case LoadError::unknown_activation:
      return "unknown_activation";
    case LoadError::inconsistent_sizes:
      return "inconsistent_sizes";
    case LoadError::invalid_value:
      break;
  }
  return "invalid_value";
}

std::uint32_t crc32(std::string_view bytes, std::uint32_t crc) {
  static const std::array<std::uint32_t, 256> table = [] {
    std::array<std::uint32_t, 256> t{};
    for (std::uint32_t i = 0; i < 256; ++i) {
      std::uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  std::uint32_t c = crc ^ 0xFFFFFFFFu;
  for (unsigned char b : bytes) c = table[(c ^ b) & 0xFFu] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

namespace {

// A refusal: the loader's category into *kind, the field and why into the Status.
struct Refuse {
  LoadError* kind;
  zerog::Status operator()(LoadError e, std::string setting, std::string why) const {
    if (kind != nullptr) *kind = e;
    return zerog::Status::invalid(std::move(setting), std::move(why));
  }
  zerog::Status sizes(std::string setting, std::string why) const {
    return (*this)(LoadError::inconsistent_sizes, std::move(setting), std::move(why));
  }
};

zerog::Status validate_rig(const RigDescription& r, const Refuse& refuse) {
  if (r.name.empty()) return refuse(LoadError::invalid_value, "rig.name", "is empty");
  if (std::abs(r.q_flange_sensor.norm() - 1.0) > 1e-6)
    return refuse(LoadError::invalid_value, "rig.flange_sensor.q_wxyz",
                  "is not a quaternion of unit norm");
  if (std::abs(r.q_sensor_imu.norm() - 1.0) > 1e-6)
    return refuse(LoadError::invalid_value, "rig.sensor_imu.q_wxyz",
                  "is not a quaternion of unit norm");
  if (!r.p_flange_sensor_m.allFinite())
    return refuse(LoadError::invalid_value, "rig.flange_sensor.p_m", "is not finite");
  if (!r.p_sensor_imu_m.allFinite())
    return refuse(LoadError::invalid_value, "rig.sensor_imu.p_m", "is not finite");
  if (!positive_finite(r.sample_period_s))
    return refuse(LoadError::invalid_value, "rig.sample_period_s", "must be positive");
  return {};
}

zerog::Status validate_physics(const model::ModelParams& physics, const Refuse& refuse) {
  if ((physics.effects.bits() >> model::kEffectCount) != 0)
    return refuse(LoadError::unknown_effect, "physics.effects", "an effect outside the library");
  for (model::Effect e : model::kAllEffects) {
    if (!physics.effects.has(e)) continue;
    const model::EffectInfo& info = model::info(e);
    for (const auto& req : info.requires_effects)
      if (req && !physics.effects.has(*req))
        return refuse(LoadError::invalid_value, "physics.effects",
                      std::string("effect '") + info.name + "' builds on '" +
                          model::info(*req).name + "', which the model lacks");
    for (int k = 0; k < info.num_params; ++k)
      if (!std::isfinite(physics.block(e)[k]))
        return refuse(LoadError::invalid_value,
                      std::string("physics.parameters.") + info.name + "." + info.params[k].name,
                      "is not finite");
  }
  for (int t = 0; t < physics.user.num_terms; ++t)
    if (!std::isfinite(physics.user.coeff[static_cast<std::size_t>(t)]))
      return refuse(LoadError::invalid_value, "physics.user_terms[" + std::to_string(t) + "].value",
                    "is not finite");
  return {};
}

// Layers, widths, activations, features and output axes.
zerog::Status validate_shape(const DeployedNetwork& n, const Refuse& refuse) {
  const model::NetworkShape& s = n.shape;
  const int L = s.num_layers();
  if (L < 1 || L > model::kMaxNetworkLayers)
    return refuse.sizes("network", std::to_string(L) + " layers, the firmware takes 1.." +
                                       std::to_string(model::kMaxNetworkLayers));
  if (static_cast<int>(s.width.size()) != L + 1)
    return refuse.sizes("network", "width list does not match the layers");
  for (int l = 0; l <= L; ++l)
    if (s.width[l] < 1 || s.width[l] > model::kMaxNetworkWidth)
      return refuse.sizes("network", "width " + std::to_string(s.width[l]) + " outside 1.." +
                                         std::to_string(model::kMaxNetworkWidth));
  for (model::Activation a : s.activation)
    if (static_cast<int>(a) > static_cast<int>(model::Activation::tanh))
      return refuse(LoadError::unknown_activation, "network", "unknown activation");
  for (model::Feature f : n.features)
    if (static_cast<int>(f) >= model::kFeatureCount)
      return refuse(LoadError::unknown_feature, "network", "unknown feature");
  const auto in = static_cast<std::size_t>(s.width.front());
  if (n.features.size() != in)
    return refuse.sizes("network", std::to_string(n.features.size()) + " features for " +
                                       std::to_string(in) + " inputs");
  const auto n_out = static_cast<std::size_t>(s.width.back());
  if (n.output_axes.size() != n_out)
    return refuse.sizes("network", std::to_string(n.output_axes.size()) + " output axes for " +
                                       std::to_string(n_out) + " outputs");
  for (std::size_t k = 0; k < n_out; ++k) {
    if (n.output_axes[k] < 0 || n.output_axes[k] > 5)
      return refuse(LoadError::invalid_value, "network.outputs", "axis index outside 0..5");
    for (std::size_t o = 0; o < k; ++o)
      if (n.output_axes[o] == n.output_axes[k])
        return refuse(LoadError::invalid_value, "network.outputs",
                      std::string("axis ") + kAxisNames[n.output_axes[k]] + " is listed twice");
  }
  return {};
}

// Normalisation and the float parameters (validate_shape first: sizes from the shape).
zerog::Status validate_float_network(const DeployedNetwork& n, const Refuse& refuse) {
  const model::NetworkShape& s = n.shape;
  const auto in = static_cast<std::size_t>(s.width.front());
  const auto n_out = static_cast<std::size_t>(s.width.back());
  const model::NetworkNormalisation& nm = n.normalisation;
  if (nm.input_mean.size() != in || nm.input_scale.size() != in || nm.output_mean.size() != n_out ||
      nm.output_scale.size() != n_out)
    return refuse.sizes("network.normalisation", "need " + std::to_string(in) + " input and " +
                                                     std::to_string(n_out) +
                                                     " output means and scales");
  for (double v : nm.input_scale)
    if (!positive_finite(v))
      return refuse(LoadError::invalid_value, "network.normalisation.input_scale",
                    "has a value that is not positive");
  for (double v : nm.output_scale)
    if (!positive_finite(v))
      return refuse(LoadError::invalid_value, "network.normalisation.output_scale",
                    "has a value that is not positive");
  for (const auto* vec : {&nm.input_mean, &nm.output_mean, &n.params})
    for (double v : *vec)
      if (!std::isfinite(v))
        return refuse(LoadError::invalid_value, "network", "a mean or weight is not finite");
  if (static_cast<int>(n.params.size()) != s.num_params())
    return refuse.sizes("network", std::to_string(n.params.size()) +
                                       " float parameters, the shape needs " +
                                       std::to_string(s.num_params()));
  return {};
}

// The quantised layers (validate_shape first).
zerog::Status validate_quantised(const DeployedNetwork& n, const Refuse& refuse) {
  const model::NetworkShape& s = n.shape;
  const int L = s.num_layers();
  const QuantisedNetwork& q = n.quantised;
  if (q.weight_bits != 8 && q.weight_bits != 16)
    return refuse(LoadError::invalid_value, "network.quantisation.weight_bits",
                  "must be 8 or 16, is " + std::to_string(q.weight_bits));
  if (!positive_finite(q.input_clip))
    return refuse(LoadError::invalid_value, "network.quantisation.input_clip", "must be positive");
  if (static_cast<int>(q.layers.size()) != L)
    return refuse.sizes("network", std::to_string(q.layers.size()) + " quantised layers for " +
                                       std::to_string(L) + " layers");
  const std::int64_t qmax = q.weight_bits == 8 ? 127 : 32767;
  for (int l = 0; l < L; ++l) {
    const QuantisedLayer& ql = q.layers[static_cast<std::size_t>(l)];
    const std::string where = "network.layers[" + std::to_string(l) + "]";
    const auto rows = static_cast<std::size_t>(s.width[l + 1]);
    if (ql.weights.size() != rows * static_cast<std::size_t>(s.width[l]) ||
        ql.weight_scale.size() != rows || ql.bias.size() != rows)
      return refuse.sizes(where, std::to_string(ql.weights.size()) + " quantised weights, " +
                                     std::to_string(ql.weight_scale.size()) + " scales and " +
                                     std::to_string(ql.bias.size()) + " biases for " +
                                     std::to_string(s.width[l]) + " inputs × " +
                                     std::to_string(rows) + " outputs");
    for (std::int16_t w : ql.weights)
      if (std::abs(static_cast<std::int64_t>(w)) > qmax)
        return refuse(LoadError::invalid_value, where + ".q_weights",
                      std::to_string(w) + " exceeds " + std::to_string(q.weight_bits) + " bits");
    for (double v : ql.weight_scale)
      if (!positive_finite(v))
        return refuse(LoadError::invalid_value, where + ".q_weight_scale",
                      "has a value that is not positive");
    for (std::int64_t b : ql.bias)
      if (b > bias_limit(q.weight_bits) || b < -bias_limit(q.weight_bits))
        return refuse(LoadError::invalid_value, where + ".q_bias", "exceeds the accumulator range");
    if (!positive_finite(ql.input_scale) || !positive_finite(ql.output_scale))
      return refuse(LoadError::invalid_value, where,
                    "q_input_scale and q_output_scale must be positive");
    const double expected_in =
        l == 0 ? q.input_clip / kActMax : q.layers[static_cast<std::size_t>(l - 1)].output_scale;
    if (std::abs(ql.input_scale - expected_in) > 1e-12 * expected_in)
      return refuse.sizes(
          where + ".q_input_scale",
          fmt(ql.input_scale) + " does not match the scale of its input " + fmt(expected_in));
  }
  return {};
}

}  // namespace

zerog::Status validate_model(const DeployedModel& m, LoadError* kind) {
  if (kind != nullptr) *kind = LoadError::none;
  const Refuse refuse{kind};
  if (zerog::Status st = validate_rig(m.rig, refuse); !st.ok()) return st;
  if (zerog::Status st = validate_physics(m.physics, refuse); !st.ok()) return st;
  if (!m.network) return {};
  for (auto* check : {&validate_shape, &validate_float_network, &validate_quantised})
    if (zerog::Status st = check(*m.network, refuse); !st.ok()) return st;
  return {};
}

std::string serialise_deployed_model(const DeployedModel& model) {
  LoadError err = LoadError::none;
  if (const zerog::Status st = validate_model(model, &err); !st.ok())
    throw std::invalid_argument(std::string("deployed model: ") + load_error_name(err) + ": " +
                                st.text());
  const std::string body = to_json(model).dump(1) + "\n";
  char header[96];
  std::snprintf(header, sizeof header, "%s %d length=%zu crc32=%08x\n", kMagic.data(),
                kDeployFormatVersion, body.size(), crc32(body));
  return header + body;
}

LoadResult load_deployed_model(std::string_view bytes, const RigDescription& running_rig,
                               std::string_view source) {
  LoadResult r;
  try {
    r.model = parse(bytes, running_rig);
  } catch (const Fail& f) {
    r.error = f.error;
    r.message = std::string(source) + ": " + f.message;
    r.model.reset();
  } catch (const json::exception& e) {
    r.error = LoadError::invalid_value;
    r.message = std::string(source) + ": " + e.what();
    r.model.reset();
  }
  return r;
}

LoadResult load_deployed_model_file(const std::filesystem::path& path,
                                    const RigDescription& running_rig) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    LoadResult r;
    r.error = LoadError::io;
    r.message = path.string() + ": cannot open for reading";
    return r;
  }
  const std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  if (in.bad()) {
    LoadResult r;
    r.error = LoadError::io;
    r.message = path.string() + ": read error";
    return r;
  }
  return load_deployed_model(bytes, running_rig, path.string());
}

}  // namespace zerog::infer
