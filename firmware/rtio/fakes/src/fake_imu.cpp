#include "zerog/rtio/fake_imu.hpp"

namespace zerog::rtio {

bool FakeImu::push(ImuReadStatus status, const ImuSample& sample) {
  return script_.push(Step{status, sample});
}

ImuStartStatus FakeImu::start() {
  started_ = start_status_ == ImuStartStatus::ok;
  return start_status_;
}

ImuReadStatus FakeImu::read_sample(ImuSample& out) {
  if (!started_) return ImuReadStatus::not_started;
  if (script_.empty()) {
    ++counters_.timeouts;
    return ImuReadStatus::timeout;
  }
  const Step& step = script_.pop();
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
