#pragma once
// Sensonor STIM300 on a serial port (proto/stim300.md) behind the Imu interface: SerialPort in
// raw mode + the codec's StreamDecoder (resynchronisation, CRC, counter gaps, status bytes).
#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>

#include "zerog/proto/stim300.hpp"
#include "zerog/rtio/imu.hpp"
#include "zerog/rtio/serial_port.hpp"

namespace zerog::rtio {

struct Stim300Config {
  std::string path = "/dev/ttyUSB0";  ///< read at start() only
  SerialConfig serial;                ///< 921600 baud by default
  /// Accelerometer range and the one datagram identifier accepted (0x93: rate, acc, incl; 0
  /// accepts every identifier of the content table).
  proto::stim300::StreamConfig stream{proto::stim300::Scale{}, 0x93};
  /// Longest wait for a complete datagram (the unit sends 125–2000 per second).
  std::chrono::nanoseconds read_timeout = std::chrono::milliseconds(10);
};

class Stim300Imu final : public Imu {
 public:
  /// Bytes taken from the tty per read(): about 1 ms of data at 921600 baud.
  static constexpr std::size_t kReadChunkBytes = 128;

  explicit Stim300Imu(const Stim300Config& config);

  /// Opens and configures the tty; resets the decoder (counters are kept).
  ImuStartStatus start() override;
  /// Returns the next datagram from the decoder, reading the tty only when none is buffered.
  /// Garbage, bad CRCs and counter gaps are counted and skipped. Real-time safe.
  ImuReadStatus read_sample(ImuSample& out) override;
  /// A sample from the bytes already read (none read from the tty). Real-time safe.
  bool pop_buffered(ImuSample& out) override;
  ImuReadStatus read_sample_upto(ImuSample& out, std::uint64_t bytes_limit,
                                 std::chrono::nanoseconds timeout) override;
  ImuCounters counters() const override;

  /// errno of the last failed open or read.
  int last_errno() const { return last_errno_; }

 private:
  Stim300Config config_;
  SerialPort port_;
  proto::stim300::StreamDecoder decoder_;
  std::array<std::uint8_t, kReadChunkBytes> chunk_{};
  std::size_t chunk_used_ = 0;  // bytes of chunk_ already pushed into the decoder
  std::size_t chunk_size_ = 0;
  std::int64_t chunk_time_ns_ = 0;
  bool started_ = false;
  bool disconnected_ = false;
  int last_errno_ = 0;
  std::uint64_t sequence_ = 0;
  ImuCounters own_;  // bytes read, timeouts, disconnects, io errors
};

}  // namespace zerog::rtio
