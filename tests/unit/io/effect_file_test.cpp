// User-defined effect files (proto/user_effects.md): reading, every error with its position,
// writing back, effect lists with @files, and the model file keeping user terms.
#include "zerog/io/effect_file.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "test_util.hpp"
#include "zerog/io/model_file.hpp"

namespace zerog::io {

using formats::InputError;
namespace {

namespace fs = std::filesystem;
using test::expect_input_error;
using test::write_text;

using EffectFileTest = test::TempDirTest;

constexpr const char* kGood = R"toml(# a hose swivel and a hose
format = "zerog-effect"
version = 1
name = "swivel"
description = "viscous swivel and hose drag"

[[term]]
axis = "Mz"
basis = "wz_S"
unit = "N*m/(rad/s)"
value = -2.0

[[term]]
vector = "force"
frame = "base"
basis = "tanh(qd1/0.02)"
value = [1.0, 2.0, 3.0]
)toml";

TEST_F(EffectFileTest, ReadsTermsAxesFramesAndValues) {
  write_text(path("e.toml"), kGood);
  model::UserEffects u;
  read_effect_file(path("e.toml"), u);
  ASSERT_EQ(u.num_effects, 1);
  EXPECT_EQ(user_effect_name(u, 0), "swivel");
  ASSERT_EQ(u.num_terms, 4);
  EXPECT_EQ(term_axis_name(u.terms[0]), "Mz");
  EXPECT_EQ(basis_text(u.terms[0].basis), "wz_S");
  EXPECT_DOUBLE_EQ(u.coeff[0], -2.0);
  for (int k = 0; k < 3; ++k) {
    const model::UserTerm& t = u.terms[static_cast<std::size_t>(1 + k)];
    EXPECT_EQ(t.axis, k);
    EXPECT_EQ(t.frame, model::TermFrame::base);
    EXPECT_EQ(term_axis_name(t), std::string(1, 'F') + "xyz"[k] + "_B");
    EXPECT_DOUBLE_EQ(u.coeff[static_cast<std::size_t>(1 + k)], 1.0 + k);
  }
  EXPECT_EQ(coefficient_unit(u.terms[1]), "N");
  EXPECT_EQ(term_label(u, 0), "swivel.Mz*wz_S [N*m/(rad/s)]");
}

TEST_F(EffectFileTest, WritesWhatItReads) {
  write_text(path("e.toml"), kGood);
  model::UserEffects u;
  read_effect_file(path("e.toml"), u);
  u.coeff[0] = -1.987654321012345;
  const std::vector<double> std = {0.01, NAN, 0.2, 0.3};
  const std::string text = effect_file_text(u, 0, &std, "again", {"written by a test"});
  write_effect_file(path("back.toml"), text);
  model::UserEffects back;
  read_effect_file(path("back.toml"), back);
  ASSERT_EQ(back.num_terms, 4);
  for (int j = 0; j < 4; ++j) {
    EXPECT_EQ(back.terms[static_cast<std::size_t>(j)], u.terms[static_cast<std::size_t>(j)]);
    EXPECT_EQ(back.coeff[static_cast<std::size_t>(j)], u.coeff[static_cast<std::size_t>(j)]);
  }
  EXPECT_NE(text.find("# written by a test"), std::string::npos);
  EXPECT_NE(text.find("std = 0.01"), std::string::npos);
  // The file is an input: never written over.
  EXPECT_THROW(write_effect_file(path("back.toml"), text, {path("back.toml")}), std::runtime_error);
}

TEST_F(EffectFileTest, ErrorsNameFileLineAndColumn) {
  struct Case {
    const char* body;  // after the header lines (3 lines)
    int line, column;
    const char* part;
  };
  const std::string header = "format = \"zerog-effect\"\nversion = 1\nname = \"x\"\n";
  const Case cases[] = {
      {"[[term]]\naxis = \"Mz\"\nbasis = \"wz_S\"\ncolour = 1\n", 7, 1, "unknown key"},
      {"[[term]]\naxis = \"Mz\"\nbasis = \"sin(qd6)\"\n", 6, 10, "joint angles"},
      {"[[term]]\naxis = \"Mz\"\nbasis = \"wz_S*wq_S\"\n", 6, 15, "unknown signal"},
      {"[[term]]\naxis = \"Tz\"\nbasis = \"wz_S\"\n", 5, 8, "Fx, Fy"},
      {"[[term]]\naxis = \"Mz\"\nbasis = \"wz_S\"\nunit = \"N*m\"\n", 7, 8, "N*m/(rad/s)"},
      {"[[term]]\nbasis = \"wz_S\"\n", 4, 1, "either 'axis'"},
      {"[[term]]\naxis = \"Mz\"\nbasis = \"wz_S\"\n[[term]]\naxis = \"Mz\"\nbasis = \"wz_S\"\n", 9,
       9, "already in the model"},
      {"[[term]]\nvector = \"force\"\nbasis = \"wz_S\"\nvalue = [1, 2]\n", 7, 9, "3"},
  };
  int k = 0;
  for (const Case& c : cases) {
    const fs::path file = path("bad" + std::to_string(k++) + ".toml");
    write_text(file, header + c.body);
    model::UserEffects u;
    expect_input_error([&] { read_effect_file(file, u); }, file, c.line, c.column, c.part);
    EXPECT_EQ(u.num_terms, 0) << "a bad file adds nothing";
  }
  // Header errors.
  write_text(path("v.toml"), "format = \"zerog-effect\"\nversion = 2\nname = \"x\"\n[[term]]\n");
  model::UserEffects u;
  expect_input_error([&] { read_effect_file(path("v.toml"), u); }, path("v.toml"), 2, 11,
                     "not supported");
  write_text(path("n.toml"),
             "format = \"zerog-effect\"\nversion = 1\nname = \"cable\"\n"
             "[[term]]\naxis = \"Fx\"\nbasis = \"wz_S\"\n");
  expect_input_error([&] { read_effect_file(path("n.toml"), u); }, path("n.toml"), 3, 8,
                     "library effect");
}

TEST_F(EffectFileTest, EffectListsTakeFilesAndTheModelFileKeepsTheTerms) {
  write_text(path("e.toml"), kGood);
  const ModelSpec spec =
      parse_model_spec("bias,gravity, @" + path("e.toml").string() + ",linear_inertia");
  EXPECT_EQ(effect_list_string(spec.effects), "bias,gravity,linear_inertia");
  ASSERT_EQ(spec.user.num_terms, 4);
  EXPECT_EQ(model_spec_string(spec.effects, spec.user, spec.files),
            "bias,gravity,linear_inertia,@" + path("e.toml").string());
  EXPECT_EQ(model_spec_string(spec.effects, spec.user), "bias,gravity,linear_inertia,@swivel");
  // The same file twice: the name is taken.
  EXPECT_THROW(
      parse_model_spec("bias,@" + path("e.toml").string() + ",@" + path("e.toml").string()),
      InputError);
  EXPECT_THROW(parse_model_spec("bias,@"), std::runtime_error);

  ModelFile m;
  m.params.effects = spec.effects;
  m.params.user = spec.user;
  m.user_std = {0.1, 0.2, 0.3, 0.4};
  const ModelFile back = model_from_json(to_json(m), "m.json");
  ASSERT_EQ(back.params.user.num_terms, 4);
  ASSERT_EQ(back.params.user.num_effects, 1);
  EXPECT_EQ(user_effect_name(back.params.user, 0), "swivel");
  for (int j = 0; j < 4; ++j) {
    EXPECT_EQ(back.params.user.terms[static_cast<std::size_t>(j)],
              spec.user.terms[static_cast<std::size_t>(j)]);
    EXPECT_EQ(back.params.user.coeff[static_cast<std::size_t>(j)],
              spec.user.coeff[static_cast<std::size_t>(j)]);
  }
  EXPECT_EQ(back.user_std, m.user_std);
  // A bad basis in a model file names the key.
  nlohmann::json j = to_json(m);
  j["user_effects"][0]["terms"][1]["basis"] = "tanh(q1/1)";
  try {
    model_from_json(j, "m.json");
    ADD_FAILURE() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("user_effects[0].terms[1].basis"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace zerog::io
