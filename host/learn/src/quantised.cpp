// Stub: the firmware's quantised network inference is being built by a colleague. Replace this
// file with the real evaluation (physics + quantised residual network, per sample) when it lands.
#include "zerog/learn/quantised.hpp"

#include <stdexcept>

namespace zerog::learn {

std::vector<ident::Wrench> quantised_prediction(const NetworkFile& /*residual*/,
                                                const ident::Dataset& /*data*/,
                                                const io::Log& /*log*/) {
  throw std::runtime_error(
      "quantised inference not available: zerog::learn::quantised_prediction is still the stub "
      "in host/learn/src/quantised.cpp");
}

}  // namespace zerog::learn
