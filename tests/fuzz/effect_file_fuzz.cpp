// User-defined effect files (proto/user_effects.md), read by fit, diagnose and ladder for every
// @FILE of an effect list. read_effect_file throws formats::InputError (or its TomlError) naming
// file, line and column; any other exception, a crash or a hang is a finding.
//
// Properties: a file that reads adds all its terms or none (the effects read before are kept as
// they were); what it read writes back (effect_file_text) into a file that reads to the same terms
// and values; every basis formats to text that parses to the same basis.
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_util.hpp"
#include "zerog/formats/log.hpp"
#include "zerog/io/effect_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace io = zerog::io;
  namespace formats = zerog::formats;
  namespace model = zerog::model;
  const auto& dir = zerog::fuzz::scratch_dir();
  const auto path = dir / "input.toml";
  zerog::fuzz::write_bytes(path, zerog::fuzz::as_text(data, size));
  // One effect already in the model: a bad file must leave it alone.
  model::UserEffects u;
  u.num_effects = 1;
  const std::string first = "first";
  std::copy(first.begin(), first.end(), u.names[0].begin());
  u.num_terms = 1;
  const char* error = nullptr;
  std::size_t pos = 0;
  ZEROG_FUZZ_CHECK(model::parse_basis("wz_S", u.terms[0].basis, error, pos));
  u.terms[0].axis = 5;
  u.coeff[0] = 2.0;
  const model::UserEffects before = u;
  try {
    io::read_effect_file(path, u);
  } catch (const formats::InputError&) {
    ZEROG_FUZZ_CHECK(u.num_terms == before.num_terms && u.num_effects == before.num_effects);
    return 0;
  }
  ZEROG_FUZZ_CHECK(u.num_effects == 2 && u.num_terms > 1);
  for (int j = 0; j < u.num_terms; ++j) {
    const model::Basis& b = u.terms[static_cast<std::size_t>(j)].basis;
    model::Basis again;
    ZEROG_FUZZ_CHECK(model::parse_basis(io::basis_text(b), again, error, pos));
    ZEROG_FUZZ_CHECK(again == b);
  }
  const auto back_path = dir / "again.toml";
  io::write_effect_file(back_path, io::effect_file_text(u, 1), {path});
  model::UserEffects back = before;
  io::read_effect_file(back_path, back);
  ZEROG_FUZZ_CHECK(back.num_terms == u.num_terms);
  for (int j = 1; j < u.num_terms; ++j) {
    ZEROG_FUZZ_CHECK(back.terms[static_cast<std::size_t>(j)] ==
                     u.terms[static_cast<std::size_t>(j)]);
    ZEROG_FUZZ_CHECK(back.coeff[static_cast<std::size_t>(j)] ==
                     u.coeff[static_cast<std::size_t>(j)]);
  }
  return 0;
}
