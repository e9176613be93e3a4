#pragma once
// From a trained network to what the firmware runs: the deployed model (zerog::infer), and the
// column of the results table that the firmware's quantised inference fills.
#include <vector>

#include "zerog/deploy/quantise.hpp"
#include "zerog/formats/log.hpp"
#include "zerog/ident/dataset.hpp"
#include "zerog/infer/deploy_model.hpp"
#include "zerog/learn/network_file.hpp"

namespace zerog::learn {

/// The rig as the deployed model file records it.
infer::RigDescription rig_description(const formats::Rig& rig);

/// Quantises a residual network for the firmware. With `calibration` (a log and its dataset),
/// the input ranges come from up to 20,000 of its samples.
infer::DeployedNetwork deploy_network(const NetworkFile& residual, deploy::QuantiseOptions options,
                                      const ident::Dataset* calibration_data = nullptr,
                                      const formats::Log* calibration_log = nullptr);

/// Physics + residual network for every sample, the network evaluated by the firmware's
/// quantised inference (zerog::infer, not the float reference), quantised with the ranges of
/// `data` itself. `residual` must be a residual network with its physics model.
std::vector<ident::Wrench> quantised_prediction(const NetworkFile& residual,
                                                const ident::Dataset& data,
                                                const formats::Log& log);

}  // namespace zerog::learn
