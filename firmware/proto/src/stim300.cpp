#include "zerog/proto/stim300.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "big_endian.hpp"

namespace zerog::proto::stim300 {

namespace {

constexpr std::array<std::uint32_t, 256> make_crc_table() {
  std::array<std::uint32_t, 256> table{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t c = i << 24;
    for (int k = 0; k < 8; ++k) c = (c & 0x80000000u) ? (c << 1) ^ 0x04C11DB7u : c << 1;
    table[i] = c;
  }
  return table;
}
constexpr std::array<std::uint32_t, 256> kCrcTable = make_crc_table();

constexpr std::int32_t kMax24 = (1 << 23) - 1;
constexpr std::int32_t kMin24 = -(1 << 23);
constexpr std::uint32_t kMaxU24 = (1u << 24) - 1;

// CRC of a datagram: everything before the CRC field, then the dummy zero bytes.
std::uint32_t datagram_crc(const std::uint8_t* p, const DatagramContent& c) {
  static constexpr std::array<std::uint8_t, 3> kZeros{};
  const std::size_t body = datagram_length(c) - 4;
  std::uint32_t crc = crc32_mpeg2({p, body});
  return crc32_mpeg2({kZeros.data(), crc_dummy_bytes(c)}, crc);
}

void read_triplet(const std::uint8_t*& p, Triplet24& t) {
  for (int i = 0; i < 3; ++i, p += 3) t.counts[i] = detail::load_i24(p);
  t.status = *p++;
}
void read_triplet(const std::uint8_t*& p, Triplet16& t) {
  for (int i = 0; i < 3; ++i, p += 2) t.counts[i] = detail::load_i16(p);
  t.status = *p++;
}
void write_triplet(std::uint8_t*& p, const Triplet24& t) {
  for (int i = 0; i < 3; ++i, p += 3) detail::store_i24(p, t.counts[i]);
  *p++ = t.status;
}
void write_triplet(std::uint8_t*& p, const Triplet16& t) {
  for (int i = 0; i < 3; ++i, p += 2) detail::store_i16(p, t.counts[i]);
  *p++ = t.status;
}
bool fits24(const Triplet24& t) {
  for (std::int32_t v : t.counts) {
    if (v < kMin24 || v > kMax24) return false;
  }
  return true;
}

template <typename T>
std::array<double, 3> scaled(const std::array<T, 3>& counts, double per_lsb) {
  return {counts[0] * per_lsb, counts[1] * per_lsb, counts[2] * per_lsb};
}

std::int32_t saturate24(double counts) {
  if (!(counts > kMin24)) return counts != counts ? 0 : kMin24;  // NaN → 0
  if (counts > kMax24) return kMax24;
  return static_cast<std::int32_t>(std::lround(counts));
}

}  // namespace

const DatagramContent* find_content(std::uint8_t identifier) {
  for (const DatagramContent& c : kDatagramTable) {
    if (c.identifier == identifier) return &c;
  }
  return nullptr;
}

std::uint32_t crc32_mpeg2(std::span<const std::uint8_t> bytes, std::uint32_t crc) {
  for (std::uint8_t b : bytes) crc = (crc << 8) ^ kCrcTable[((crc >> 24) ^ b) & 0xFFu];
  return crc;
}

DecodeStatus decode_datagram(std::span<const std::uint8_t> bytes, RawDatagram& out) {
  if (bytes.empty()) return DecodeStatus::too_short;
  const DatagramContent* c = find_content(bytes[0]);
  if (c == nullptr) return DecodeStatus::unknown_identifier;
  const std::size_t length = datagram_length(*c);
  if (bytes.size() < length) return DecodeStatus::too_short;
  const std::uint8_t* p = bytes.data();
  if (datagram_crc(p, *c) != detail::load_u32(p + length - 4)) return DecodeStatus::crc_mismatch;

  out = RawDatagram{};
  out.identifier = *p++;
  read_triplet(p, out.rate);
  if (c->accel) read_triplet(p, out.accel);
  if (c->incl) read_triplet(p, out.incl);
  if (c->temperature) {
    read_triplet(p, out.rate_temperature);
    if (c->accel) read_triplet(p, out.accel_temperature);
    if (c->incl) read_triplet(p, out.incl_temperature);
  }
  if (c->pps) {  // after the temperatures (Table 5-20)
    out.pps = static_cast<std::uint32_t>(detail::load_i24(p)) & kMaxU24;
    out.pps_status = p[3];
    p += kPpsBytes;
  }
  out.counter = *p++;
  out.latency_us = detail::load_u16(p);
  return DecodeStatus::ok;
}

Sample to_sample(const RawDatagram& raw, const Scale& scale) {
  Sample s;
  s.raw = raw;
  const DatagramContent* c = find_content(raw.identifier);
  if (c == nullptr) return s;  // nothing valid
  const double per_c = Scale::temperature_c_per_lsb();
  s.rate_rad_s = scaled(raw.rate.counts, Scale::rate_rad_s_per_lsb());
  s.rate_valid = raw.rate.status == 0;
  if (c->accel) {
    s.accel_m_s2 = scaled(raw.accel.counts, scale.accel_m_s2_per_lsb());
    s.accel_valid = raw.accel.status == 0;
  }
  if (c->incl) {
    s.incl_m_s2 = scaled(raw.incl.counts, Scale::incl_m_s2_per_lsb());
    s.incl_valid = raw.incl.status == 0;
  }
  s.pps_valid = c->pps && raw.pps_status == 0;
  if (c->temperature) {
    s.rate_temperature_c = scaled(raw.rate_temperature.counts, per_c);
    s.rate_temperature_valid = raw.rate_temperature.status == 0;
    if (c->accel) {
      s.accel_temperature_c = scaled(raw.accel_temperature.counts, per_c);
      s.accel_temperature_valid = raw.accel_temperature.status == 0;
    }
    if (c->incl) {
      s.incl_temperature_c = scaled(raw.incl_temperature.counts, per_c);
      s.incl_temperature_valid = raw.incl_temperature.status == 0;
    }
  }
  s.latency_s = raw.latency_us * 1e-6;
  return s;
}

EncodeResult encode_datagram(const RawDatagram& raw, bool crlf, std::span<std::uint8_t> out) {
  const DatagramContent* c = find_content(raw.identifier);
  if (c == nullptr) return {EncodeStatus::unknown_identifier, 0};
  const std::size_t length = datagram_length(*c);
  if (out.size() < length + (crlf ? 2 : 0)) return {EncodeStatus::buffer_too_small, 0};
  if (!fits24(raw.rate) || (c->accel && !fits24(raw.accel)) || (c->incl && !fits24(raw.incl)) ||
      (c->pps && raw.pps > kMaxU24)) {
    return {EncodeStatus::value_out_of_range, 0};
  }
  std::uint8_t* p = out.data();
  *p++ = raw.identifier;
  write_triplet(p, raw.rate);
  if (c->accel) write_triplet(p, raw.accel);
  if (c->incl) write_triplet(p, raw.incl);
  if (c->temperature) {
    write_triplet(p, raw.rate_temperature);
    if (c->accel) write_triplet(p, raw.accel_temperature);
    if (c->incl) write_triplet(p, raw.incl_temperature);
  }
  if (c->pps) {
    detail::store_i24(p, static_cast<std::int32_t>(raw.pps));  // the low 24 bits
    p[3] = raw.pps_status;
    p += kPpsBytes;
  }
  *p++ = raw.counter;
  detail::store_u16(p, raw.latency_us);
  p += 2;
  detail::store_u32(p, datagram_crc(out.data(), *c));
  p += 4;
  if (crlf) {
    *p++ = '\r';
    *p++ = '\n';
  }
  return {EncodeStatus::ok, static_cast<std::size_t>(p - out.data())};
}

std::int32_t rate_counts(double rate_rad_s) {
  return saturate24(rate_rad_s / Scale::rate_rad_s_per_lsb());
}
std::int32_t accel_counts(double accel_m_s2, const Scale& scale) {
  return saturate24(accel_m_s2 / scale.accel_m_s2_per_lsb());
}
std::int32_t incl_counts(double incl_m_s2) {
  return saturate24(incl_m_s2 / Scale::incl_m_s2_per_lsb());
}
std::int16_t temperature_counts(double temperature_c) {
  const double counts = temperature_c / Scale::temperature_c_per_lsb();
  if (!(counts > -32768.0)) return counts != counts ? 0 : -32768;
  if (counts > 32767.0) return 32767;
  return static_cast<std::int16_t>(std::lround(counts));
}

// --- StreamDecoder ----------------------------------------------------------------------------

std::size_t StreamDecoder::push(std::span<const std::uint8_t> bytes) {
  if (head_ == tail_) {
    base_ += head_;
    head_ = tail_ = 0;
  }
  if (tail_ + bytes.size() > kBufferSize && head_ > 0) {  // compact
    std::memmove(buffer_.data(), buffer_.data() + head_, tail_ - head_);
    base_ += head_;
    tail_ -= head_;
    head_ = 0;
  }
  const std::size_t n = std::min(bytes.size(), kBufferSize - tail_);
  if (n > 0) std::memcpy(buffer_.data() + tail_, bytes.data(), n);
  tail_ += n;
  return n;
}

void StreamDecoder::skip_byte() {
  ++head_;
  ++counters_.bytes_skipped;
  if (in_sync_) {
    in_sync_ = false;
    ++counters_.sync_losses;
  }
}

bool StreamDecoder::pop(Sample& out) {
  while (head_ < tail_) {
    const std::uint8_t b = buffer_[head_];
    if (after_datagram_ == 1 && b == '\r') {
      after_datagram_ = 2;
      ++head_;
      continue;
    }
    if (after_datagram_ == 2 && b == '\n') {
      after_datagram_ = 0;
      ++head_;
      continue;
    }
    after_datagram_ = 0;

    const DatagramContent* c = find_content(b);
    if (c == nullptr || (config_.identifier != 0 && b != config_.identifier)) {
      skip_byte();
      continue;
    }
    const std::size_t length = datagram_length(*c);
    if (tail_ - head_ < length) return false;  // wait for the rest
    RawDatagram raw;
    const DecodeStatus status = decode_datagram({buffer_.data() + head_, length}, raw);
    if (status != DecodeStatus::ok) {  // only crc_mismatch is possible here
      // Due here: in sync, or where the datagram after a counted bad one would start.
      const std::uint64_t at = base_ + head_;
      if (in_sync_ || (have_bad_end_ && (at == bad_end_ || at == bad_end_ + 2))) {
        ++counters_.crc_failures;
        bad_end_ = at + length;
        have_bad_end_ = true;
      }
      skip_byte();
      continue;
    }
    have_bad_end_ = false;
    head_ += length;
    in_sync_ = true;
    after_datagram_ = 1;
    out = to_sample(raw, config_.scale);
    if (have_counter_) {
      out.missed_before = static_cast<std::uint8_t>(raw.counter - last_counter_ - 1);
      if (out.missed_before != 0) {
        ++counters_.counter_gaps;
        counters_.datagrams_missed += out.missed_before;
      }
    }
    have_counter_ = true;
    last_counter_ = raw.counter;
    ++counters_.datagrams;
    const DatagramContent& cc = *c;
    if (!out.rate_valid || (cc.accel && !out.accel_valid) || (cc.incl && !out.incl_valid) ||
        (cc.pps && !out.pps_valid) ||
        (cc.temperature &&
         (!out.rate_temperature_valid || (cc.accel && !out.accel_temperature_valid) ||
          (cc.incl && !out.incl_temperature_valid)))) {
      ++counters_.invalid_samples;
    }
    return true;
  }
  return false;
}

void StreamDecoder::reset() {
  base_ += tail_;
  head_ = tail_ = 0;
  have_bad_end_ = false;
  in_sync_ = false;
  after_datagram_ = 0;
  have_counter_ = false;
}

}  // namespace zerog::proto::stim300
