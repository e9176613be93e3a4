#include "zerog/rtio/fake_ft_sensor.hpp"

namespace zerog::rtio {

bool FakeFtSensor::push(FtReadStatus status, const FtSample& sample) {
  return script_.push(Step{status, sample});
}

FtStartStatus FakeFtSensor::start() {
  started_ = start_status_ == FtStartStatus::ok;
  return start_status_;
}

FtReadStatus FakeFtSensor::read_sample(FtSample& out) {
  if (!started_) return FtReadStatus::not_started;
  ++counters_.requests;
  if (script_.empty()) {
    ++counters_.timeouts;
    return FtReadStatus::timeout;
  }
  const Step& step = script_.pop();
  switch (step.status) {
    case FtReadStatus::sample:
      out = step.sample;
      out.sequence = ++sequence_;
      ++counters_.samples;
      if (out.status == FtSampleStatus::warning) ++counters_.samples_warning;
      if (out.status == FtSampleStatus::critical) ++counters_.samples_critical;
      if (out.status == FtSampleStatus::saturated) ++counters_.samples_saturated;
      break;
    case FtReadStatus::timeout:
      ++counters_.timeouts;
      break;
    case FtReadStatus::tx_failed:
      ++counters_.tx_would_block;
      break;
    case FtReadStatus::io_error:
      ++counters_.io_errors;
      break;
    case FtReadStatus::not_started:
      break;
  }
  return step.status;
}

}  // namespace zerog::rtio
