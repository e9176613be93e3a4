#pragma once
// Network inputs from a log: the firmware's feature catalogue (zerog/model/features.hpp)
// evaluated on an ident::Dataset, time-blocked splits and static dwells. Host only (allocates).
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "zerog/formats/log.hpp"
#include "zerog/ident/dataset.hpp"
#include "zerog/model/features.hpp"

namespace zerog::learn {

/// The signals of sample i of `data` for model::compute_features. The sensor position comes from
/// `log` (the Dataset keeps the attitude only); `log` must be the log `data` was made from.
/// Joint velocities are the Dataset's (backward differences of the joint angles).
model::FeatureSignals feature_signals(const ident::Dataset& data, const formats::Log& log,
                                      std::size_t i);

/// Parses a comma-separated list of feature names ("sign_qd6,qd6,wz"). Throws
/// std::invalid_argument naming the unknown name and listing the valid ones.
std::vector<model::Feature> parse_features(const std::string& list);
std::string feature_list_string(std::span<const model::Feature> features);

/// Throws std::runtime_error if the log lacks a signal a feature needs (joint angles, IMU,
/// temperature), naming the feature and the missing columns.
void check_feature_signals(std::span<const model::Feature> features, const ident::Dataset& data);

/// Feature rows (row-major, samples.size() × features.size()) of the given samples.
std::vector<double> feature_rows(const ident::Dataset& data, const formats::Log& log,
                                 std::span<const model::Feature> features,
                                 std::span<const std::size_t> samples);

/// 1 for samples in time blocks b = floor((t − t0) / block_s) with b mod every == offset.
/// ident::heldout_mask(data, block_s, every) is time_block_mask(data, block_s, every, every − 1).
std::vector<std::uint8_t> time_block_mask(const ident::Dataset& data, double block_s, int every,
                                          int offset);

/// The features that carry a signal named by ident::diagnose ("joint A6 velocity direction
/// (sign)" → sign_qd6, "angular rate about IMU z" → wz, …); empty if none matches.
std::vector<model::Feature> features_for_signal(const std::string& signal);

/// A static dwell: samples [begin, end) that do not move and all lie in the mask.
struct Dwell {
  std::size_t begin = 0, end = 0;
};
/// Maximal runs of non-moving samples inside `mask` (null = all samples), at least `min_samples`
/// long.
std::vector<Dwell> static_dwells(const ident::Dataset& data, const std::vector<std::uint8_t>* mask,
                                 std::size_t min_samples = 20);

}  // namespace zerog::learn
