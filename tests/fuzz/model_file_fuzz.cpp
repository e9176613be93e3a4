// The fitted-model file (proto/model_format.md, JSON) as compare, diagnose, ladder, report and
// export read it. read_model throws std::runtime_error naming the file and the bad key; any other
// exception type (e.g. one of nlohmann::json's own), a crash or a hang is a finding.
//
// Property: a model that reads writes back (to_json) into a document that reads to the same
// effects and parameter values.
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <typeinfo>

#include "fuzz_util.hpp"
#include "zerog/io/model_file.hpp"

namespace io = zerog::io;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = zerog::fuzz::scratch_dir() / "model.json";
  zerog::fuzz::write_bytes(path, zerog::fuzz::as_text(data, size));
  io::ModelFile model;
  try {
    model = io::read_model(path);
  } catch (const std::runtime_error& e) {
    if (typeid(e) != typeid(std::runtime_error)) {
      std::fprintf(stderr, "undocumented exception %s: %s\n", typeid(e).name(), e.what());
      __builtin_trap();
    }
    return 0;
  }
  const io::ModelFile back = io::model_from_json(io::to_json(model), "round trip");
  ZEROG_FUZZ_CHECK(back.params.effects == model.params.effects);
  ZEROG_FUZZ_CHECK(back.rig_name == model.rig_name);
  ZEROG_FUZZ_CHECK(back.params.values == model.params.values);
  return 0;
}
