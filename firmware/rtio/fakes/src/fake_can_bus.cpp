#include "zerog/rtio/fake_can_bus.hpp"

namespace zerog::rtio {

bool FakeCanBus::inject(const CanRxFrame& frame) {
  if (rx_count_ == kQueueCapacity) {
    ++counters_.kernel_drops;
    return false;
  }
  rx_[(rx_head_ + rx_count_) % kQueueCapacity] = frame;
  ++rx_count_;
  return true;
}

CanReadStatus FakeCanBus::read(CanRxFrame& out, std::chrono::nanoseconds /*timeout*/) {
  if (rx_count_ == 0) return CanReadStatus::timeout;  // a fake never sleeps
  out = rx_[rx_head_];
  rx_head_ = (rx_head_ + 1) % kQueueCapacity;
  --rx_count_;
  if (out.frame.len > proto::kCanMaxDataLength) {
    ++counters_.bad_length;
    return CanReadStatus::bad_length;
  }
  if (out.frame.error()) {
    count_error_frame(out.frame, counters_);
    return CanReadStatus::error_frame;
  }
  ++counters_.frames_received;
  return CanReadStatus::frame;
}

CanWriteStatus FakeCanBus::write(const proto::CanFrame& frame) {
  if (frame.len > proto::kCanMaxDataLength) return CanWriteStatus::bad_frame;
  switch (forced_write_status_) {
    case CanWriteStatus::would_block:
      ++counters_.tx_would_block;
      return forced_write_status_;
    case CanWriteStatus::io_error:
      ++counters_.tx_errors;
      return forced_write_status_;
    case CanWriteStatus::ok:
    case CanWriteStatus::bad_frame:
    case CanWriteStatus::not_open:
      break;
  }
  if (forced_write_status_ != CanWriteStatus::ok) return forced_write_status_;
  tx_log_[written_ % kLogCapacity] = frame;
  ++written_;
  ++counters_.frames_sent;
  if (responder_ != nullptr) responder_->on_write(frame, *this);
  return CanWriteStatus::ok;
}

}  // namespace zerog::rtio
