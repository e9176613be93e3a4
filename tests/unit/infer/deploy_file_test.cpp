// The deployed-model file: export → load round trip with identical predictions, physics-only
// files, and one test per kind of bad file, each with its own error and a message naming it.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "infer_fixtures.hpp"
#include "zerog/infer/deploy_file.hpp"
#include "zerog/infer/inference.hpp"

namespace zerog::infer {
namespace {

using model::Activation;
using model::Feature;
using testing::HasSubstr;

DeployedModel full_model() {
  const auto data = test::random_samples(2000, 5);
  DeployedModel m;
  m.rig = test::demo_rig();
  m.physics = test::demo_physics();
  m.network = test::make_network(test::feature_range(Feature::sin_q1, Feature::wdz), {24, 16},
                                 Activation::tanh, data, 1.5, 8);
  m.provenance_json = R"({"model":"fit.json","network":"net.json"})";
  return m;
}

// The JSON content of a file, and a file made from (possibly edited) content with a valid
// header, so a test can break the content without tripping the checksum.
nlohmann::json content_of(const std::string& file) {
  return nlohmann::json::parse(file.substr(file.find('\n') + 1));
}
std::string file_with(const nlohmann::json& content) {
  const std::string body = content.dump(1) + "\n";
  char header[96];
  std::snprintf(header, sizeof header, "zerog-deploy 1 length=%zu crc32=%08x\n", body.size(),
                crc32(body));
  return header + body;
}

LoadResult load(const std::string& bytes) {
  return load_deployed_model(bytes, test::demo_rig(), "deploy.zgm");
}

void expect_error(const LoadResult& r, LoadError e, const std::string& words) {
  EXPECT_FALSE(r.ok());
  EXPECT_EQ(load_error_name(r.error), std::string(load_error_name(e))) << r.message;
  EXPECT_FALSE(r.model.has_value());
  EXPECT_THAT(r.message, HasSubstr("deploy.zgm: "));
  EXPECT_THAT(r.message, HasSubstr(words));
}

TEST(DeployFile, Crc32MatchesTheStandardCheckValue) {
  EXPECT_EQ(crc32("123456789"), 0xCBF43926u);  // CRC-32/ISO-HDLC check value
  // A piece at a time (files are checked so): the CRC of the pieces before carries on.
  EXPECT_EQ(crc32("56789", crc32("1234")), 0xCBF43926u);
  EXPECT_EQ(crc32("", crc32("123456789")), 0xCBF43926u);
}

TEST(DeployFile, RoundTripGivesBitIdenticalPredictions) {
  const DeployedModel m = full_model();
  const std::string bytes = serialise_deployed_model(m);
  EXPECT_EQ(bytes.rfind("zerog-deploy 1 length=", 0), 0u);
  const LoadResult r = load(bytes);
  ASSERT_TRUE(r.ok()) << r.message;
  Inference original, loaded;
  ASSERT_EQ(original.configure(m).text(), "");
  ASSERT_EQ(loaded.configure(*r.model).text(), "");
  EXPECT_EQ(loaded.model().network->features, m.network->features);
  EXPECT_EQ(loaded.model().physics.values, m.physics.values);
  EXPECT_EQ(loaded.model().network->params, m.network->params);
  EXPECT_EQ(serialise_deployed_model(*r.model), bytes);  // stable: same model, same bytes
  std::mt19937_64 rng(77);
  for (int i = 0; i < 2000; ++i) {
    const model::FeatureSignals s = test::random_signals(rng);
    Wrench a, b, fa, fb;
    ASSERT_TRUE(original.evaluate(s, a).written());
    ASSERT_TRUE(loaded.evaluate(s, b).written());
    ASSERT_EQ(a, b);  // bit for bit
    ASSERT_TRUE(original.evaluate_reference(s, fa).written());
    ASSERT_TRUE(loaded.evaluate_reference(s, fb).written());
    ASSERT_EQ(fa, fb);
  }
}

TEST(DeployFile, PhysicsOnlyFilesLoadAndPredictThePhysics) {
  DeployedModel m = full_model();
  m.network.reset();
  const LoadResult r = load(serialise_deployed_model(m));
  ASSERT_TRUE(r.ok()) << r.message;
  EXPECT_FALSE(r.model->network.has_value());
  Inference inf;
  ASSERT_EQ(inf.configure(*r.model).text(), "");
  std::mt19937_64 rng(3);
  const model::FeatureSignals s = test::random_signals(rng);
  Wrench w, p;
  EXPECT_EQ(inf.evaluate(s, w).code, StatusCode::ok);
  EXPECT_EQ(inf.evaluate_physics(s, p).code, StatusCode::ok);
  EXPECT_EQ(w, p);
}

TEST(DeployFile, WritesAndReadsFiles) {
  const std::filesystem::path dir = std::filesystem::path(ZEROG_BINARY_DIR) / "infer_test_tmp";
  std::filesystem::create_directories(dir);
  const std::filesystem::path path = dir / "deploy.zgm";
  std::ofstream(path, std::ios::binary) << serialise_deployed_model(full_model());
  const LoadResult r = load_deployed_model_file(path, test::demo_rig());
  EXPECT_TRUE(r.ok()) << r.message;
  const LoadResult missing = load_deployed_model_file(dir / "absent.zgm", test::demo_rig());
  EXPECT_EQ(missing.error, LoadError::io);
  EXPECT_THAT(missing.message, HasSubstr("absent.zgm: cannot open"));
}

TEST(DeployFileBad, CorruptContentFailsTheChecksum) {
  std::string bytes = serialise_deployed_model(full_model());
  bytes[bytes.size() / 2] ^= 0x01;  // one flipped bit in the content
  expect_error(load(bytes), LoadError::corrupt, "corrupt: CRC-32 of the content is ");
}

TEST(DeployFileBad, BytesAfterTheContentAreCorruption) {
  expect_error(load(serialise_deployed_model(full_model()) + "x"), LoadError::corrupt,
               "1 bytes after the declared content");
}

TEST(DeployFileBad, TruncatedContentIsNamed) {
  const std::string bytes = serialise_deployed_model(full_model());
  expect_error(load(bytes.substr(0, bytes.size() - 100)), LoadError::truncated,
               "truncated: the header declares");
  expect_error(load(bytes.substr(0, 20)), LoadError::truncated, "header line is cut short");
  expect_error(load(""), LoadError::truncated, "empty");
}

TEST(DeployFileBad, OtherFilesAreNotDeployedModels) {
  expect_error(load("{\"format\": \"zerog-model\"}\n"), LoadError::not_deploy_file,
               "not a zerog deployed-model file");
}

TEST(DeployFileBad, WrongVersionIsRefused) {
  std::string bytes = serialise_deployed_model(full_model());
  bytes.replace(0, 14, "zerog-deploy 2");
  expect_error(load(bytes), LoadError::wrong_version, "file format version 2");
}

TEST(DeployFileBad, WrongRigIsRefusedByNameAndByGeometry) {
  const std::string bytes = serialise_deployed_model(full_model());
  RigDescription other = test::demo_rig();
  other.name = "kr210-lab-b";
  LoadResult r = load_deployed_model(bytes, other, "deploy.zgm");
  expect_error(r, LoadError::wrong_rig,
               "fitted for rig 'kr210-omega191-stim300', this is rig 'kr210-lab-b'");
  other = test::demo_rig();
  other.p_sensor_imu_m.z() += 0.002;
  r = load_deployed_model(bytes, other, "deploy.zgm");
  expect_error(r, LoadError::wrong_rig, "IMU position in the sensor frame differs by 2 mm");
}

TEST(DeployFileBad, UnknownEffectIsNamed) {
  nlohmann::json c = content_of(serialise_deployed_model(full_model()));
  c["physics"]["effects"].push_back("magnetism");
  expect_error(load(file_with(c)), LoadError::unknown_effect, "unknown effect 'magnetism'");
}

TEST(DeployFileBad, UnknownFeatureIsNamed) {
  nlohmann::json c = content_of(serialise_deployed_model(full_model()));
  c["network"]["features"][2] = "humidity";
  expect_error(load(file_with(c)), LoadError::unknown_feature,
               "network.features[2]: unknown feature 'humidity'");
}

TEST(DeployFileBad, UnknownActivationIsNamed) {
  nlohmann::json c = content_of(serialise_deployed_model(full_model()));
  c["network"]["layers"][1]["activation"] = "gelu";
  expect_error(load(file_with(c)), LoadError::unknown_activation,
               "network.layers[1].activation: unknown activation 'gelu'");
}

TEST(DeployFileBad, InconsistentSizesAreNamed) {
  const nlohmann::json good = content_of(serialise_deployed_model(full_model()));
  nlohmann::json c = good;
  c["network"]["layers"][0]["weights"].erase(0);
  expect_error(load(file_with(c)), LoadError::inconsistent_sizes, "network.layers[0]: ");
  c = good;
  c["network"]["layers"][1]["q_weights"].erase(0);
  expect_error(load(file_with(c)), LoadError::inconsistent_sizes, "quantised weights");
  c = good;
  c["network"]["layers"][1]["inputs"] = 23;
  expect_error(load(file_with(c)), LoadError::inconsistent_sizes,
               "network.layers[1] has 23 inputs, the layer before has 24 outputs");
  c = good;
  c["network"]["normalisation"]["input_scale"].erase(0);
  expect_error(load(file_with(c)), LoadError::inconsistent_sizes, "network.normalisation");
  c = good;
  c["network"]["features"].erase(0);
  expect_error(load(file_with(c)), LoadError::inconsistent_sizes, "features for");
}

TEST(DeployFileBad, MissingKeysAndBadNumbersAreNamed) {
  const nlohmann::json good = content_of(serialise_deployed_model(full_model()));
  nlohmann::json c = good;
  c["physics"]["parameters"]["gravity"].erase("mass");
  expect_error(load(file_with(c)), LoadError::inconsistent_sizes, "physics.parameters.gravity");
  c = good;
  c["rig"].erase("sample_period_s");
  expect_error(load(file_with(c)), LoadError::invalid_value, "missing key 'rig.sample_period_s'");
  c = good;
  c["network"]["quantisation"]["weight_bits"] = 4;
  expect_error(load(file_with(c)), LoadError::invalid_value,
               "network.quantisation.weight_bits: must be 8 or 16, is 4");
  c = good;
  c["network"]["layers"][0]["q_weight_scale"][0] = -1.0;
  expect_error(load(file_with(c)), LoadError::invalid_value, "q_weight_scale");
}

TEST(DeployFile, WriterRefusesAnInconsistentModel) {
  DeployedModel m = full_model();
  m.network->params.pop_back();
  EXPECT_THROW(serialise_deployed_model(m), std::invalid_argument);
  // validate_model names the field and the loader's category.
  LoadError kind = LoadError::none;
  const zerog::Status st = validate_model(m, &kind);
  EXPECT_EQ(st.code(), zerog::StatusCode::invalid_setting);
  EXPECT_EQ(st.setting(), "network");
  EXPECT_EQ(kind, LoadError::inconsistent_sizes);
  m = full_model();
  m.network->quantised.layers[0].bias[0] = std::int64_t{1} << 60;
  EXPECT_EQ(validate_model(m, &kind).setting(), "network.layers[0].q_bias");
  EXPECT_EQ(kind, LoadError::invalid_value);
  EXPECT_TRUE(validate_model(full_model(), &kind).ok());
  EXPECT_EQ(kind, LoadError::none);
}

}  // namespace
}  // namespace zerog::infer

namespace zerog::infer {
namespace {

TEST(DeployFile, NetworksWithFewerOutputsAddToTheirAxesOnly) {
  const auto data = test::random_samples(1000, 6);
  DeployedNetwork full =
      test::make_network(test::feature_range(model::Feature::r11, model::Feature::r33), {16},
                         model::Activation::tanh, data, 1.0, 3);
  // Keep outputs Fx..My (the zero-point network of 001_… leaves Mz out).
  model::NetworkShape shape = full.shape;
  shape.width.back() = 5;
  std::vector<double> params(full.params.begin(), full.params.end());
  const int n = shape.width[1];
  params.erase(params.begin() + (shape.layer_params(0) + 5 * n),
               params.begin() + (shape.layer_params(0) + 6 * n));  // row Mz of W
  params.pop_back();                                               // bias of Mz
  model::NetworkNormalisation norm = full.normalisation;
  norm.output_mean.pop_back();
  norm.output_scale.pop_back();
  DeployedModel m;
  m.rig = test::demo_rig();
  m.physics = test::demo_physics();
  m.network = deploy::make_deployed_network(full.features, {0, 1, 2, 3, 4}, shape, norm, params);
  const LoadResult r = load_deployed_model(serialise_deployed_model(m), test::demo_rig());
  ASSERT_TRUE(r.ok()) << r.message;
  EXPECT_EQ(r.model->network->output_axes, (std::vector<int>{0, 1, 2, 3, 4}));
  Inference inf;
  ASSERT_EQ(inf.configure(*r.model).text(), "");
  std::mt19937_64 rng(2);
  const model::FeatureSignals s = test::random_signals(rng);
  Wrench residual, full_w, physics;
  ASSERT_TRUE(inf.residual_quantised(s, residual).written());
  EXPECT_EQ(residual[5], 0.0);
  ASSERT_TRUE(inf.evaluate(s, full_w).written());
  ASSERT_TRUE(inf.evaluate_physics(s, physics).written());
  EXPECT_EQ(full_w[5], physics[5]);
}

}  // namespace
}  // namespace zerog::infer
