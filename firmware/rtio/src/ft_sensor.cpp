#include "zerog/rtio/ft_sensor.hpp"

namespace zerog::rtio {

const char* ft_sample_status_name(FtSampleStatus status) {
  switch (status) {
    case FtSampleStatus::ok:
      return "ok";
    case FtSampleStatus::warning:
      return "warning";
    case FtSampleStatus::critical:
      return "critical";
    case FtSampleStatus::saturated:
      return "saturated";
  }
  return "?";
}

const char* ft_start_status_name(FtStartStatus status) {
  switch (status) {
    case FtStartStatus::ok:
      return "ok";
    case FtStartStatus::bad_config:
      return "bad_config";
    case FtStartStatus::no_response:
      return "no_response";
    case FtStartStatus::readout_failed:
      return "readout_failed";
    case FtStartStatus::unknown_units:
      return "unknown_units";
    case FtStartStatus::io_error:
      return "io_error";
  }
  return "?";
}

const char* ft_read_status_name(FtReadStatus status) {
  switch (status) {
    case FtReadStatus::sample:
      return "sample";
    case FtReadStatus::timeout:
      return "timeout";
    case FtReadStatus::not_started:
      return "not_started";
    case FtReadStatus::tx_failed:
      return "tx_failed";
    case FtReadStatus::io_error:
      return "io_error";
  }
  return "?";
}

bool FakeFtSensor::push(FtReadStatus status, const FtSample& sample) {
  if (count_ == kScriptCapacity) return false;
  script_[(head_ + count_) % kScriptCapacity] = Step{status, sample};
  ++count_;
  return true;
}

FtStartStatus FakeFtSensor::start() {
  started_ = start_status_ == FtStartStatus::ok;
  return start_status_;
}

FtReadStatus FakeFtSensor::read_sample(FtSample& out) {
  if (!started_) return FtReadStatus::not_started;
  ++counters_.requests;
  if (count_ == 0) {
    ++counters_.timeouts;
    return FtReadStatus::timeout;
  }
  const Step& step = script_[head_];
  head_ = (head_ + 1) % kScriptCapacity;
  --count_;
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
