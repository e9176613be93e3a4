#pragma once
// FakeCanBus (zerog::rtio_fakes): an in-memory CanBus for unit tests, the no-allocation test and
// the emulated F/T board (host/emu). Frames written are logged and handed to an optional
// responder (e.g. a board emulator), which may queue frames for read(). read() never sleeps: an
// empty queue is an immediate timeout. Single-threaded.
#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>

#include "zerog/rtio/can_bus.hpp"

namespace zerog::rtio {

class FakeCanBus;

/// Reacts to frames written to a FakeCanBus (typically by queueing responses with inject()).
class CanResponder {
 public:
  virtual ~CanResponder() = default;
  virtual void on_write(const proto::CanFrame& frame, FakeCanBus& bus) = 0;
};

class FakeCanBus final : public CanBus {
 public:
  static constexpr std::size_t kQueueCapacity = 256;
  static constexpr std::size_t kLogCapacity = 256;

  void set_responder(CanResponder* responder) { responder_ = responder; }
  /// Queues a frame for read(); false when the queue is full (counted as a kernel drop, as the
  /// real socket would).
  bool inject(const CanRxFrame& frame);
  bool inject(const proto::CanFrame& frame) { return inject(CanRxFrame{frame, 0}); }
  /// Frames queued and not read yet.
  std::size_t queued() const { return rx_count_; }
  /// Makes write() return `status` (counting it like the socket does) instead of sending.
  void fail_writes(CanWriteStatus status) { forced_write_status_ = status; }

  /// Number of frames written so far and the i-th of the last kLogCapacity.
  std::uint64_t written_count() const { return written_; }
  const proto::CanFrame& written(std::uint64_t i) const { return tx_log_[i % kLogCapacity]; }

  CanReadStatus read(CanRxFrame& out, std::chrono::nanoseconds timeout) override;
  CanWriteStatus write(const proto::CanFrame& frame) override;
  const CanBusCounters& counters() const override { return counters_; }

 private:
  std::array<CanRxFrame, kQueueCapacity> rx_{};
  std::size_t rx_head_ = 0;
  std::size_t rx_count_ = 0;
  std::array<proto::CanFrame, kLogCapacity> tx_log_{};
  std::uint64_t written_ = 0;
  CanResponder* responder_ = nullptr;
  CanWriteStatus forced_write_status_ = CanWriteStatus::ok;
  CanBusCounters counters_;
};

}  // namespace zerog::rtio
