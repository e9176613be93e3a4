// STIM300 datagrams (proto/stim300.md): CRC known answer, layout and scale known answers, encoder
// round trips for every identifier, and the stream decoder's resynchronisation and counters.
#include "zerog/proto/stim300.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "alloc_count.hpp"

namespace zerog::proto::stim300 {
namespace {

using Bytes = std::vector<std::uint8_t>;

Bytes encode(const RawDatagram& raw, bool crlf = false) {
  std::array<std::uint8_t, kMaxDatagramLength + 2> buf{};
  const EncodeResult r = encode_datagram(raw, crlf, buf);
  EXPECT_EQ(r.status, EncodeStatus::ok);
  return Bytes(buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(r.size));
}

RawDatagram random_raw(std::uint8_t identifier, std::mt19937& rng) {
  std::uniform_int_distribution<std::int32_t> i24(-(1 << 23), (1 << 23) - 1);
  std::uniform_int_distribution<int> i16(-32768, 32767), u8(0, 255), u16(0, 65535);
  RawDatagram raw;
  raw.identifier = identifier;
  const DatagramContent& c = *find_content(identifier);
  auto t24 = [&](Triplet24& t) {
    for (auto& v : t.counts) v = i24(rng);
  };
  auto t16 = [&](Triplet16& t) {
    for (auto& v : t.counts) v = static_cast<std::int16_t>(i16(rng));
  };
  t24(raw.rate);
  if (c.accel) t24(raw.accel);
  if (c.incl) t24(raw.incl);
  if (c.temperature) {
    t16(raw.rate_temperature);
    if (c.accel) t16(raw.accel_temperature);
    if (c.incl) t16(raw.incl_temperature);
  }
  if (c.pps) {
    raw.pps = static_cast<std::uint32_t>(i24(rng)) & 0xFFFFFFu;
    raw.pps_status = static_cast<std::uint8_t>(u8(rng));
  }
  raw.counter = static_cast<std::uint8_t>(u8(rng));
  raw.latency_us = static_cast<std::uint16_t>(u16(rng));
  return raw;
}

void expect_same(const RawDatagram& a, const RawDatagram& b) {
  EXPECT_EQ(a.identifier, b.identifier);
  EXPECT_EQ(a.rate.counts, b.rate.counts);
  EXPECT_EQ(a.rate.status, b.rate.status);
  EXPECT_EQ(a.accel.counts, b.accel.counts);
  EXPECT_EQ(a.accel.status, b.accel.status);
  EXPECT_EQ(a.incl.counts, b.incl.counts);
  EXPECT_EQ(a.incl.status, b.incl.status);
  EXPECT_EQ(a.pps, b.pps);
  EXPECT_EQ(a.pps_status, b.pps_status);
  EXPECT_EQ(a.rate_temperature.counts, b.rate_temperature.counts);
  EXPECT_EQ(a.accel_temperature.counts, b.accel_temperature.counts);
  EXPECT_EQ(a.incl_temperature.counts, b.incl_temperature.counts);
  EXPECT_EQ(a.counter, b.counter);
  EXPECT_EQ(a.latency_us, b.latency_us);
}

RawDatagram rai(std::uint8_t counter) {
  RawDatagram raw;
  raw.identifier = 0x93;
  raw.rate.counts = {16384, -16384, 100};
  raw.accel.counts = {0, 0, 524288};
  raw.incl.counts = {0, 0, 4194304};
  raw.counter = counter;
  raw.latency_us = 500;
  return raw;
}

// A stream of datagrams with consecutive counters.
Bytes stream_of(int count, std::uint8_t first_counter = 0, bool crlf = false) {
  Bytes out;
  for (int i = 0; i < count; ++i) {
    const Bytes d = encode(rai(static_cast<std::uint8_t>(first_counter + i)), crlf);
    out.insert(out.end(), d.begin(), d.end());
  }
  return out;
}

std::vector<Sample> decode_all(StreamDecoder& decoder, const Bytes& bytes,
                               std::size_t chunk = 1'000'000) {
  std::vector<Sample> out;
  for (std::size_t i = 0; i < bytes.size(); i += chunk) {
    const std::size_t n = std::min(chunk, bytes.size() - i);
    decoder.feed(std::span<const std::uint8_t>(bytes.data() + i, n),
                 [&](const Sample& s) { out.push_back(s); });
  }
  return out;
}

TEST(Stim300Crc, KnownAnswerMpeg2) {
  const std::string_view check = "123456789";
  const std::span<const std::uint8_t> bytes(reinterpret_cast<const std::uint8_t*>(check.data()),
                                            check.size());
  EXPECT_EQ(crc32_mpeg2(bytes), 0x0376E6E7u);
  EXPECT_EQ(crc32_mpeg2(bytes.subspan(4), crc32_mpeg2(bytes.first(4))), 0x0376E6E7u);
  EXPECT_EQ(crc32_mpeg2({}), 0xFFFFFFFFu);
}

TEST(Stim300Table, IdentifiersLengthsAndDummyBytesOfRev31) {
  // TS1524 rev.31 Table 5-21 (identifiers) and Table 5-22 (CRC dummy bytes), as listed in
  // ../shared/reference/stim300-datagrams.md: {id, acc, incl, temp, pps, dummy bytes}.
  struct Row {
    int id;
    bool acc, incl, temp, pps;
    std::size_t dummy;
  };
  const std::array<Row, 16> rev31{{{0x90, 0, 0, 0, 0, 2},
                                   {0x91, 1, 0, 0, 0, 0},
                                   {0x92, 0, 1, 0, 0, 0},
                                   {0x93, 1, 1, 0, 0, 2},
                                   {0x94, 0, 0, 1, 0, 3},
                                   {0xA5, 1, 0, 1, 0, 2},
                                   {0xA6, 0, 1, 1, 0, 2},
                                   {0xA7, 1, 1, 1, 0, 1},
                                   {0xF0, 0, 0, 0, 1, 2},
                                   {0xF1, 1, 0, 0, 1, 0},
                                   {0xF2, 0, 1, 0, 1, 0},
                                   {0xF3, 1, 1, 0, 1, 2},
                                   {0xF4, 0, 0, 1, 1, 3},
                                   {0xF5, 1, 0, 1, 1, 2},
                                   {0xF6, 0, 1, 1, 1, 2},
                                   {0xF7, 1, 1, 1, 1, 1}}};
  for (const Row& r : rev31) {
    const DatagramContent* c = find_content(static_cast<std::uint8_t>(r.id));
    ASSERT_NE(c, nullptr) << r.id;
    EXPECT_EQ(c->accel, r.acc) << r.id;
    EXPECT_EQ(c->incl, r.incl) << r.id;
    EXPECT_EQ(c->temperature, r.temp) << r.id;
    EXPECT_EQ(c->pps, r.pps) << r.id;
    EXPECT_EQ(crc_dummy_bytes(*c), r.dummy) << r.id;  // computed from the layout
  }
  int known = 0;
  for (int id = 0; id < 256; ++id) known += find_content(static_cast<std::uint8_t>(id)) != nullptr;
  EXPECT_EQ(known, 16);  // nothing else: no 0x95–0x9C, no AUX datagrams in rev.31
  for (int id = 0x95; id <= 0x9C; ++id)
    EXPECT_EQ(find_content(static_cast<std::uint8_t>(id)), nullptr) << id;
  for (const DatagramContent& c : kDatagramTable) {
    EXPECT_EQ((datagram_length(c) - 4 + crc_dummy_bytes(c)) % 4, 0u) << int{c.identifier};
    EXPECT_LE(datagram_length(c), kMaxDatagramLength);
  }
  EXPECT_EQ(datagram_length(*find_content(0x90)), 18u);  // 1 + 10 + 7
  EXPECT_EQ(datagram_length(*find_content(0x93)), 38u);  // 1 + 3×10 + 7
  EXPECT_EQ(datagram_length(*find_content(0xA7)), 59u);  // 1 + 3×10 + 3×7 + 7
  EXPECT_EQ(datagram_length(*find_content(0xF0)), 22u);  // 1 + 10 + 4 + 7
  EXPECT_EQ(kMaxDatagramLength, 63u);                    // 0xF7: 1 + 3×10 + 3×7 + 4 + 7
  EXPECT_EQ(datagram_length(*find_content(0xF7)), kMaxDatagramLength);
}

// Builds a datagram by hand in Table 5-20's order, with the CRC over the body plus `dummy` zero
// bytes (§5.5.7), independent of the encoder.
std::vector<std::uint8_t> hand_built(std::vector<std::uint8_t> body, std::size_t dummy) {
  std::vector<std::uint8_t> crc_input = body;
  crc_input.resize(body.size() + dummy, 0);
  const std::uint32_t crc = crc32_mpeg2(crc_input);
  for (int shift : {24, 16, 8, 0}) body.push_back(static_cast<std::uint8_t>(crc >> shift));
  return body;
}

TEST(Stim300Datagram, KnownLayoutOf0xF7PpsAfterTemperatures) {
  // rate X = +1 °/s; acc Z = 1 g (±10 g); incl Z = 1 g; temperatures 25.5, 1.0, 0.5 °C in the
  // first field of each cluster; PPS = 0x123456 with status 0; counter 9; latency 400 µs.
  const std::vector<std::uint8_t> body{
      0xF7,                                                  // identifier
      0x00, 0x40, 0x00, 0,    0, 0, 0,    0,    0,    0x00,  // rate + status
      0,    0,    0,    0,    0, 0, 0x08, 0x00, 0x00, 0x00,  // acc + status
      0,    0,    0,    0,    0, 0, 0x40, 0x00, 0x00, 0x00,  // incl + status
      0x19, 0x80, 0,    0,    0, 0, 0x00,                    // rate temperatures + status
      0x01, 0x00, 0,    0,    0, 0, 0x00,                    // acc temperatures + status
      0x00, 0x80, 0,    0,    0, 0, 0x00,                    // incl temperatures + status
      0x12, 0x34, 0x56, 0x00,                                // PPS + status
      0x09, 0x01, 0x90};                                     // counter, latency
  ASSERT_EQ(body.size(), 59u);
  const std::vector<std::uint8_t> d = hand_built(body, 1);  // Table 5-22: 1 dummy byte
  RawDatagram raw;
  ASSERT_EQ(decode_datagram(d, raw), DecodeStatus::ok);
  EXPECT_EQ(raw.rate.counts[0], 16384);
  EXPECT_EQ(raw.accel.counts[2], 524288);
  EXPECT_EQ(raw.incl.counts[2], 4194304);
  EXPECT_EQ(raw.pps, 0x123456u);
  EXPECT_EQ(raw.counter, 9);
  EXPECT_EQ(raw.latency_us, 400);
  const Sample s = to_sample(raw, Scale{});
  EXPECT_DOUBLE_EQ(s.rate_temperature_c[0], 25.5);
  EXPECT_DOUBLE_EQ(s.accel_temperature_c[0], 1.0);
  EXPECT_DOUBLE_EQ(s.incl_temperature_c[0], 0.5);
  EXPECT_TRUE(s.pps_valid && s.rate_temperature_valid && s.incl_temperature_valid);
  std::array<std::uint8_t, kMaxDatagramLength + 2> buf{};
  const EncodeResult e = encode_datagram(raw, false, buf);
  ASSERT_EQ(e.status, EncodeStatus::ok);
  EXPECT_EQ(std::vector<std::uint8_t>(buf.begin(), buf.begin() + e.size), d);
}

TEST(Stim300Datagram, KnownLayoutOf0xA5AndF0) {
  // 0xA5: rate, acc, their temperatures (2 dummy bytes); 0xF0: rate, PPS (2 dummy bytes).
  const std::vector<std::uint8_t> a5 = hand_built(
      {0xA5, 0xFF, 0xC0, 0x00, 0, 0, 0, 0, 0,    0,    0x00, 0, 0, 0, 0, 0,    0,    0xF8, 0x00,
       0x00, 0x00, 0xFF, 0x00, 0, 0, 0, 0, 0x00, 0x02, 0x00, 0, 0, 0, 0, 0x00, 0x2A, 0x00, 0x10},
      2);
  RawDatagram raw;
  ASSERT_EQ(decode_datagram(a5, raw), DecodeStatus::ok);
  const Sample s = to_sample(raw, Scale{});
  EXPECT_DOUBLE_EQ(s.rate_rad_s[0], -std::numbers::pi / 180.0);
  EXPECT_DOUBLE_EQ(s.accel_m_s2[2], -9.80665);
  EXPECT_DOUBLE_EQ(s.rate_temperature_c[0], -1.0);
  EXPECT_DOUBLE_EQ(s.accel_temperature_c[0], 2.0);
  EXPECT_TRUE(s.accel_valid && s.accel_temperature_valid);
  EXPECT_FALSE(s.incl_valid || s.incl_temperature_valid || s.pps_valid);
  EXPECT_EQ(raw.counter, 0x2A);
  EXPECT_EQ(raw.latency_us, 0x10);

  const std::vector<std::uint8_t> f0 = hand_built(
      {0xF0, 0, 0, 1, 0, 0, 2, 0, 0, 3, 0x00, 0xFF, 0xFF, 0xFF, 0x80, 0x05, 0x00, 0x20}, 2);
  ASSERT_EQ(decode_datagram(f0, raw), DecodeStatus::ok);
  EXPECT_EQ(raw.rate.counts, (std::array<std::int32_t, 3>{1, 2, 3}));
  EXPECT_EQ(raw.pps, 0xFFFFFFu);
  EXPECT_EQ(raw.pps_status, 0x80);
  EXPECT_FALSE(to_sample(raw, Scale{}).pps_valid);
  EXPECT_EQ(raw.counter, 5);
}

TEST(Stim300Datagram, KnownLayoutOf0x93) {
  // Hand-built: rate X = +1 °/s (0x004000), Y = −1 °/s (0xFFC000), Z = 0x000064; acc Z = 1 g at
  // ±10 g (0x080000); incl Z = 1 g (0x400000); counter 7; latency 500 µs (0x01F4).
  std::array<std::uint8_t, 38> d{0x93, 0x00, 0x40, 0x00, 0xFF, 0xC0, 0x00, 0x00, 0x00,
                                 0x64, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x08,
                                 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
                                 0x40, 0x00, 0x00, 0x00, 0x07, 0x01, 0xF4};
  std::array<std::uint8_t, 36> crc_input{};  // 34 bytes + 2 dummy zero bytes
  std::copy(d.begin(), d.begin() + 34, crc_input.begin());
  const std::uint32_t crc = crc32_mpeg2(crc_input);
  d[34] = static_cast<std::uint8_t>(crc >> 24);
  d[35] = static_cast<std::uint8_t>(crc >> 16);
  d[36] = static_cast<std::uint8_t>(crc >> 8);
  d[37] = static_cast<std::uint8_t>(crc);

  RawDatagram raw;
  ASSERT_EQ(decode_datagram(d, raw), DecodeStatus::ok);
  EXPECT_EQ(raw.rate.counts, (std::array<std::int32_t, 3>{16384, -16384, 100}));
  EXPECT_EQ(raw.accel.counts[2], 524288);
  EXPECT_EQ(raw.incl.counts[2], 4194304);
  EXPECT_EQ(raw.counter, 7);
  EXPECT_EQ(raw.latency_us, 500);
  const Bytes encoded = encode(rai(7));
  EXPECT_EQ(encoded, Bytes(d.begin(), d.end()));  // the encoder writes the same bytes

  const Sample s = to_sample(raw, Scale{});
  const double deg = std::numbers::pi / 180.0;
  EXPECT_DOUBLE_EQ(s.rate_rad_s[0], deg);
  EXPECT_DOUBLE_EQ(s.rate_rad_s[1], -deg);
  EXPECT_DOUBLE_EQ(s.accel_m_s2[2], 9.80665);
  EXPECT_DOUBLE_EQ(s.incl_m_s2[2], 9.80665);
  EXPECT_DOUBLE_EQ(s.latency_s, 500e-6);
  EXPECT_TRUE(s.rate_valid && s.accel_valid && s.incl_valid);
  EXPECT_FALSE(s.pps_valid || s.rate_temperature_valid);

  d[5] ^= 0x01;
  EXPECT_EQ(decode_datagram(d, raw), DecodeStatus::crc_mismatch);
  EXPECT_EQ(decode_datagram(std::span(d).first(37), raw), DecodeStatus::too_short);
  d[0] = 0x42;
  EXPECT_EQ(decode_datagram(d, raw), DecodeStatus::unknown_identifier);
}

TEST(Stim300Datagram, ScaleFactors) {
  EXPECT_DOUBLE_EQ(Scale{AccelRange::g5}.accel_m_s2_per_lsb() * (1 << 20), 9.80665);
  EXPECT_DOUBLE_EQ(Scale{AccelRange::g10}.accel_m_s2_per_lsb() * (1 << 19), 9.80665);
  EXPECT_DOUBLE_EQ(Scale{AccelRange::g30}.accel_m_s2_per_lsb() * (1 << 18), 9.80665);
  EXPECT_DOUBLE_EQ(Scale{AccelRange::g80}.accel_m_s2_per_lsb() * (1 << 16), 9.80665);
  EXPECT_EQ(rate_counts(std::numbers::pi / 180.0), 16384);
  EXPECT_EQ(accel_counts(-9.80665, Scale{AccelRange::g30}), -262144);
  EXPECT_EQ(incl_counts(9.80665 / 2), 2097152);
  EXPECT_EQ(temperature_counts(25.5), 6528);
  EXPECT_EQ(rate_counts(1e9), (1 << 23) - 1);  // saturates
  EXPECT_EQ(rate_counts(-1e9), -(1 << 23));
  EXPECT_EQ(rate_counts(std::nan("")), 0);

  RawDatagram raw;
  raw.identifier = 0xA7;  // with temperatures
  raw.rate_temperature.counts = {6528, -256, 0};
  raw.accel_temperature.counts = {256, 0, 0};
  raw.incl_temperature.counts = {0, 0, 128};
  const Sample s = to_sample(raw, Scale{});
  EXPECT_DOUBLE_EQ(s.rate_temperature_c[0], 25.5);
  EXPECT_DOUBLE_EQ(s.rate_temperature_c[1], -1.0);
  EXPECT_DOUBLE_EQ(s.accel_temperature_c[0], 1.0);
  EXPECT_DOUBLE_EQ(s.incl_temperature_c[2], 0.5);
  EXPECT_TRUE(s.rate_temperature_valid && s.accel_temperature_valid && s.incl_temperature_valid);
}

TEST(Stim300Datagram, EncoderRoundTripForEveryIdentifier) {
  std::mt19937 rng(7);
  for (const DatagramContent& c : kDatagramTable) {
    for (int k = 0; k < 20; ++k) {
      for (bool crlf : {false, true}) {
        const RawDatagram raw = random_raw(c.identifier, rng);
        const Bytes bytes = encode(raw, crlf);
        ASSERT_EQ(bytes.size(), datagram_length(c) + (crlf ? 2 : 0));
        RawDatagram back;
        ASSERT_EQ(decode_datagram(bytes, back), DecodeStatus::ok) << int{c.identifier};
        expect_same(raw, back);
      }
    }
  }
}

TEST(Stim300Datagram, EncoderErrors) {
  std::array<std::uint8_t, 80> buf{};
  RawDatagram raw = rai(0);
  EXPECT_EQ(encode_datagram(raw, false, std::span(buf).first(37)).status,
            EncodeStatus::buffer_too_small);
  EXPECT_EQ(encode_datagram(raw, true, std::span(buf).first(39)).status,
            EncodeStatus::buffer_too_small);
  raw.accel.counts[1] = 1 << 23;
  EXPECT_EQ(encode_datagram(raw, false, buf).status, EncodeStatus::value_out_of_range);
  raw = rai(0);
  raw.identifier = 0x01;
  EXPECT_EQ(encode_datagram(raw, false, buf).status, EncodeStatus::unknown_identifier);
}

TEST(Stim300Datagram, StatusBytesInvalidateTheirGroupOnly) {
  RawDatagram raw;
  raw.identifier = 0xF7;  // everything
  raw.accel.status = 0x80;
  raw.incl_temperature.status = 0x01;
  const Sample s = to_sample(raw, Scale{});
  EXPECT_TRUE(s.rate_valid);
  EXPECT_FALSE(s.accel_valid);
  EXPECT_TRUE(s.incl_valid);
  EXPECT_TRUE(s.pps_valid);
  EXPECT_TRUE(s.rate_temperature_valid);
  EXPECT_TRUE(s.accel_temperature_valid);
  EXPECT_FALSE(s.incl_temperature_valid);
}

TEST(Stim300Stream, DecodesAnyChunking) {
  const Bytes bytes = stream_of(40, 250);  // counter wraps 255 → 0: no gap
  for (std::size_t chunk : {1u, 3u, 37u, 38u, 39u, 500u, 100000u}) {
    StreamDecoder decoder;
    const std::vector<Sample> samples = decode_all(decoder, bytes, chunk);
    ASSERT_EQ(samples.size(), 40u) << chunk;
    for (int i = 0; i < 40; ++i) {
      EXPECT_EQ(samples[i].raw.counter, static_cast<std::uint8_t>(250 + i));
      EXPECT_EQ(samples[i].missed_before, 0);
    }
    EXPECT_EQ(decoder.counters().datagrams, 40u);
    EXPECT_EQ(decoder.counters().bytes_skipped, 0u);
    EXPECT_EQ(decoder.counters().counter_gaps, 0u);
    EXPECT_TRUE(decoder.in_sync());
  }
}

TEST(Stim300Stream, PartialDatagramWaitsForTheRest) {
  const Bytes d = encode(rai(1));
  StreamDecoder decoder;
  Sample s;
  EXPECT_EQ(decoder.push(std::span(d).first(20)), 20u);
  EXPECT_FALSE(decoder.pop(s));
  EXPECT_EQ(decoder.push(std::span(d).subspan(20)), d.size() - 20);
  ASSERT_TRUE(decoder.pop(s));
  EXPECT_EQ(s.raw.counter, 1);
  EXPECT_FALSE(decoder.pop(s));
}

TEST(Stim300Stream, GarbagePrefixIsSkippedAndCounted) {
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> byte(0, 255);
  Bytes bytes(300);
  for (auto& b : bytes) b = static_cast<std::uint8_t>(byte(rng));
  bytes[10] = 0x93;  // a false start: right identifier, wrong CRC
  const Bytes good = stream_of(5, 0);
  bytes.insert(bytes.end(), good.begin(), good.end());
  StreamDecoder decoder;
  const std::vector<Sample> samples = decode_all(decoder, bytes, 17);
  ASSERT_EQ(samples.size(), 5u);
  EXPECT_EQ(samples[0].raw.counter, 0);
  EXPECT_EQ(decoder.counters().bytes_skipped, 300u);
  EXPECT_EQ(decoder.counters().crc_failures, 0u);  // not in sync yet: just garbage
  EXPECT_EQ(decoder.counters().sync_losses, 0u);
}

TEST(Stim300Stream, BadCrcResynchronisesToTheNextGoodDatagram) {
  Bytes bytes = stream_of(3, 10);  // counters 10, 11, 12
  bytes[38 + 20] ^= 0x10;          // corrupt the middle datagram
  StreamDecoder decoder;
  const std::vector<Sample> samples = decode_all(decoder, bytes, 5);
  ASSERT_EQ(samples.size(), 2u);
  EXPECT_EQ(samples[0].raw.counter, 10);
  EXPECT_EQ(samples[1].raw.counter, 12);
  EXPECT_EQ(samples[1].missed_before, 1);
  EXPECT_EQ(decoder.counters().crc_failures, 1u);
  EXPECT_EQ(decoder.counters().sync_losses, 1u);
  EXPECT_EQ(decoder.counters().bytes_skipped, 38u);
  EXPECT_EQ(decoder.counters().counter_gaps, 1u);
  EXPECT_EQ(decoder.counters().datagrams_missed, 1u);
}

// A line whose every datagram has a wrong CRC (noise on the wire, a wrong CRC setting) counts each
// of them, with and without CR LF, fed whole or in small chunks (the buffer compacts).
TEST(Stim300Stream, ARunOfDatagramsWithWrongCrcsCountsEachOfThem) {
  for (const bool crlf : {false, true}) {
    for (const std::size_t chunk : {std::size_t{7}, std::size_t{5000}}) {
      SCOPED_TRACE(std::string(crlf ? "CR LF" : "no CR LF") + ", chunk " + std::to_string(chunk));
      Bytes bytes = stream_of(60, 0, crlf);
      const std::size_t stride = bytes.size() / 60;
      for (std::size_t k = 10; k < 50; ++k) bytes[k * stride + 20] ^= 0x10;  // 40 bad ones
      StreamDecoder decoder;
      const std::vector<Sample> samples = decode_all(decoder, bytes, chunk);
      ASSERT_EQ(samples.size(), 20u);
      EXPECT_EQ(samples[10].raw.counter, 50);
      EXPECT_EQ(samples[10].missed_before, 40);
      EXPECT_EQ(decoder.counters().crc_failures, 40u);
      EXPECT_EQ(decoder.counters().sync_losses, 1u);
      EXPECT_EQ(decoder.counters().bytes_skipped, 40u * stride);
    }
  }
}

TEST(Stim300Stream, CounterGapsAreCounted) {
  StreamDecoder decoder;
  Bytes bytes;
  for (int counter : {5, 6, 9, 10, 255, 0, 3}) {  // gaps: 6→9 (2 missed), 10→255 (244), 0→3 (2)
    const Bytes d = encode(rai(static_cast<std::uint8_t>(counter)));
    bytes.insert(bytes.end(), d.begin(), d.end());
  }
  const std::vector<Sample> samples = decode_all(decoder, bytes);
  ASSERT_EQ(samples.size(), 7u);
  EXPECT_EQ(samples[2].missed_before, 2);
  EXPECT_EQ(samples[4].missed_before, 244);
  EXPECT_EQ(samples[5].missed_before, 0);
  EXPECT_EQ(decoder.counters().counter_gaps, 3u);
  EXPECT_EQ(decoder.counters().datagrams_missed, 2u + 244u + 2u);
}

TEST(Stim300Stream, CrLfTerminationIsConsumed) {
  const Bytes bytes = stream_of(10, 0, true);
  StreamDecoder decoder;
  EXPECT_EQ(decode_all(decoder, bytes, 1).size(), 10u);
  EXPECT_EQ(decoder.counters().bytes_skipped, 0u);
  EXPECT_EQ(decoder.counters().sync_losses, 0u);
}

TEST(Stim300Stream, StatusBytesFlagSamplesInvalid) {
  RawDatagram bad = rai(1);
  bad.rate.status = 0x04;
  Bytes bytes = encode(rai(0));
  const Bytes d = encode(bad);
  bytes.insert(bytes.end(), d.begin(), d.end());
  StreamDecoder decoder;
  const std::vector<Sample> samples = decode_all(decoder, bytes);
  ASSERT_EQ(samples.size(), 2u);
  EXPECT_TRUE(samples[0].rate_valid);
  EXPECT_FALSE(samples[1].rate_valid);
  EXPECT_TRUE(samples[1].accel_valid);
  EXPECT_EQ(decoder.counters().invalid_samples, 1u);
}

TEST(Stim300Stream, FixedIdentifierTreatsOthersAsGarbage) {
  RawDatagram other = rai(0);
  other.identifier = 0x90;
  Bytes bytes = encode(other);
  const Bytes good = stream_of(2, 1);
  bytes.insert(bytes.end(), good.begin(), good.end());
  StreamConfig config;
  config.identifier = 0x93;
  StreamDecoder decoder(config);
  const std::vector<Sample> samples = decode_all(decoder, bytes);
  ASSERT_EQ(samples.size(), 2u);
  EXPECT_EQ(decoder.counters().bytes_skipped, 18u);
}

TEST(Stim300Stream, FeedingDoesNotAllocate) {
  Bytes bytes = stream_of(50, 0, true);
  bytes[100] ^= 0xFF;
  StreamDecoder decoder;
  std::size_t count = 0;
  const std::size_t before = zerog::test::allocation_count();
  for (std::size_t i = 0; i < bytes.size(); i += 13) {
    decoder.feed(std::span<const std::uint8_t>(bytes).subspan(
                     i, std::min<std::size_t>(13, bytes.size() - i)),
                 [&](const Sample&) { ++count; });
  }
  EXPECT_EQ(zerog::test::allocation_count(), before);
  EXPECT_EQ(count, 49u);
}

}  // namespace
}  // namespace zerog::proto::stim300
