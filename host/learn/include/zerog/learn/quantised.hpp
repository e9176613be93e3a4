#pragma once
// The column of the results table that the firmware's quantised network inference fills.
#include <vector>

#include "zerog/ident/dataset.hpp"
#include "zerog/io/log.hpp"
#include "zerog/learn/network_file.hpp"

namespace zerog::learn {

/// Physics + residual network for every sample, the network evaluated by the firmware's
/// quantised inference (not the float reference). `residual` is a kind-residual network file.
/// NOT AVAILABLE YET: throws std::runtime_error("quantised inference not available ...") until
/// the quantised evaluator replaces the stub in host/learn/src/quantised.cpp.
std::vector<ident::Wrench> quantised_prediction(const NetworkFile& residual,
                                                const ident::Dataset& data, const io::Log& log);

}  // namespace zerog::learn
