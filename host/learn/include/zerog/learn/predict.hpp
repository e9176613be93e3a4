#pragma once
// What a trained network file predicts for every sample of a log (host, double arithmetic on
// the stored float parameters): paper-bp the network; paper-zp zero point + tool gravity wrench
// (001_… eq. 15); residual the physics model plus the network.
#include <vector>

#include "zerog/formats/log.hpp"
#include "zerog/ident/dataset.hpp"
#include "zerog/learn/network_file.hpp"

namespace zerog::learn {

/// Raw network outputs (n × outputs, row-major) for every sample.
std::vector<double> network_outputs(const NetworkFile& net, const ident::Dataset& data,
                                    const formats::Log& log);

/// The predicted sensor wrench of every sample. Throws std::runtime_error if the log lacks a
/// signal the network or its physics model needs.
std::vector<ident::Wrench> predictions(const NetworkFile& net, const ident::Dataset& data,
                                       const formats::Log& log);

/// Tool gravity wrench in S at attitude R_base_sensor (001_… eq. 15): ˢG = Rᵀ ᴮG*, ˢM = A r*.
ident::Wrench tool_wrench(const ToolLoad& tool, const Eigen::Matrix3d& R_base_sensor);

}  // namespace zerog::learn
