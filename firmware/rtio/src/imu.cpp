#include "zerog/rtio/imu.hpp"

namespace zerog::rtio {

const char* imu_start_status_name(ImuStartStatus status) {
  switch (status) {
    case ImuStartStatus::ok:
      return "ok";
    case ImuStartStatus::open_failed:
      return "open_failed";
    case ImuStartStatus::bad_config:
      return "bad_config";
  }
  return "?";
}

const char* imu_read_status_name(ImuReadStatus status) {
  switch (status) {
    case ImuReadStatus::sample:
      return "sample";
    case ImuReadStatus::timeout:
      return "timeout";
    case ImuReadStatus::disconnected:
      return "disconnected";
    case ImuReadStatus::io_error:
      return "io_error";
    case ImuReadStatus::not_started:
      return "not_started";
    case ImuReadStatus::drained:
      return "drained";
  }
  return "?";
}

bool FakeImu::push(ImuReadStatus status, const ImuSample& sample) {
  if (count_ == kScriptCapacity) return false;
  script_[(head_ + count_) % kScriptCapacity] = Step{status, sample};
  ++count_;
  return true;
}

ImuStartStatus FakeImu::start() {
  started_ = start_status_ == ImuStartStatus::ok;
  return start_status_;
}

ImuReadStatus FakeImu::read_sample(ImuSample& out) {
  if (!started_) return ImuReadStatus::not_started;
  if (count_ == 0) {
    ++counters_.timeouts;
    return ImuReadStatus::timeout;
  }
  const Step& step = script_[head_];
  head_ = (head_ + 1) % kScriptCapacity;
  --count_;
  switch (step.status) {
    case ImuReadStatus::sample:
      out = step.sample;
      out.sequence = ++sequence_;
      ++counters_.samples;
      if (!out.rate_valid || !out.accel_valid || !out.incl_valid) ++counters_.invalid_samples;
      if (out.missed_before != 0) {
        ++counters_.counter_gaps;
        counters_.datagrams_missed += out.missed_before;
      }
      break;
    case ImuReadStatus::timeout:
      ++counters_.timeouts;
      break;
    case ImuReadStatus::disconnected:
      ++counters_.disconnects;
      started_ = false;
      break;
    case ImuReadStatus::io_error:
      ++counters_.io_errors;
      break;
    case ImuReadStatus::not_started:
    case ImuReadStatus::drained:
      break;
  }
  return step.status;
}

}  // namespace zerog::rtio
