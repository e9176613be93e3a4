// SpscRing and LatestValue: single-threaded semantics, then two-thread stress tests (bounded
// iterations) checking that no value is torn and that every count adds up.
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <thread>

#include "zerog/handover/latest_value.hpp"
#include "zerog/handover/spsc_ring.hpp"

namespace zerog::handover {
namespace {

// A record whose fields are all derived from `seq`: a torn copy shows as a mismatch.
struct Record {
  std::uint64_t seq = 0;
  std::array<std::uint64_t, 15> payload{};

  static Record make(std::uint64_t seq) {
    Record r;
    r.seq = seq;
    for (std::size_t i = 0; i < r.payload.size(); ++i) r.payload[i] = seq * 0x9E3779B97F4A7C15u + i;
    return r;
  }
  bool consistent() const { return *this == make(seq); }
  friend bool operator==(const Record&, const Record&) = default;
};

TEST(SpscRing, FifoOrderAndDropsWhenFull) {
  SpscRing<int, 4> ring;
  int out = 0;
  EXPECT_FALSE(ring.try_pop(out));
  for (int i = 1; i <= 4; ++i) EXPECT_TRUE(ring.try_push(i));
  EXPECT_FALSE(ring.try_push(5));  // full: the newest is dropped and counted
  EXPECT_EQ(ring.dropped(), 1u);
  EXPECT_EQ(ring.size_approx(), 4u);
  for (int i = 1; i <= 4; ++i) {
    ASSERT_TRUE(ring.try_pop(out));
    EXPECT_EQ(out, i);
  }
  EXPECT_FALSE(ring.try_pop(out));
  EXPECT_TRUE(ring.try_push(6));  // indices wrap
  ASSERT_TRUE(ring.try_pop(out));
  EXPECT_EQ(out, 6);
  EXPECT_EQ(ring.pushed(), 5u);
  EXPECT_EQ(ring.popped(), 5u);
}

TEST(SpscRing, TwoThreadStressNoTornRecordsAndCountsAddUp) {
  constexpr std::uint64_t kAttempts = 200'000;
  SpscRing<Record, 64> ring;
  std::atomic<bool> producer_done{false};

  std::thread producer([&] {
    for (std::uint64_t seq = 1; seq <= kAttempts; ++seq) ring.try_push(Record::make(seq));
    producer_done.store(true, std::memory_order_release);
  });

  std::uint64_t received = 0, torn = 0, out_of_order = 0, gaps = 0, last = 0;
  Record r;
  auto take = [&] {
    ++received;
    if (!r.consistent()) ++torn;
    if (r.seq <= last) ++out_of_order;
    gaps += r.seq - last - 1;  // records dropped between two received ones
    last = r.seq;
  };
  while (!producer_done.load(std::memory_order_acquire)) {
    if (ring.try_pop(r)) take();
  }
  while (ring.try_pop(r)) take();
  producer.join();
  gaps += kAttempts - last;  // dropped after the last one received

  EXPECT_EQ(torn, 0u);
  EXPECT_EQ(out_of_order, 0u);
  EXPECT_EQ(ring.pushed() + ring.dropped(), kAttempts);
  EXPECT_EQ(ring.popped(), ring.pushed());
  EXPECT_EQ(received, ring.popped());
  EXPECT_EQ(gaps, ring.dropped());  // every missing sequence number is a counted drop
}

TEST(LatestValue, KeepsTheLastGoodValueAndCountsOverwrites) {
  LatestValue<Record> box;
  Record out = Record::make(99);
  EXPECT_EQ(box.read(out), LatestRead::empty);
  EXPECT_EQ(out.seq, 99u);  // untouched

  box.publish(Record::make(1));
  EXPECT_EQ(box.read(out), LatestRead::fresh);
  EXPECT_EQ(out, Record::make(1));
  EXPECT_EQ(box.read(out), LatestRead::stale);  // nothing new: same value again
  EXPECT_EQ(out, Record::make(1));

  box.publish(Record::make(2));
  box.publish(Record::make(3));  // 2 is overwritten unread
  box.publish(Record::make(4));  // and 3
  EXPECT_EQ(box.read(out), LatestRead::fresh);
  EXPECT_EQ(out, Record::make(4));
  EXPECT_EQ(box.published(), 4u);
  EXPECT_EQ(box.taken(), 2u);
  EXPECT_EQ(box.overwritten(), 2u);
}

TEST(LatestValue, TwoThreadStressNoTornValuesAndCountsAddUp) {
  constexpr std::uint64_t kPublishes = 200'000;
  LatestValue<Record> box;
  std::atomic<bool> writer_done{false};

  std::thread writer([&] {
    for (std::uint64_t seq = 1; seq <= kPublishes; ++seq) box.publish(Record::make(seq));
    writer_done.store(true, std::memory_order_release);
  });

  std::uint64_t fresh = 0, stale = 0, torn = 0, went_back = 0, last = 0;
  Record r;
  auto check = [&](LatestRead result) {
    if (result == LatestRead::empty) return;
    if (!r.consistent()) ++torn;
    if (result == LatestRead::fresh) {
      ++fresh;
      if (r.seq <= last) ++went_back;  // a fresh value is always newer
      last = r.seq;
    } else {
      ++stale;
      if (r.seq != last) ++went_back;  // a stale read repeats the last value
    }
  };
  while (!writer_done.load(std::memory_order_acquire)) check(box.read(r));
  check(box.read(r));  // the last value, if not taken yet
  writer.join();

  EXPECT_EQ(torn, 0u);
  EXPECT_EQ(went_back, 0u);
  EXPECT_EQ(last, kPublishes);  // the final value always arrives
  EXPECT_EQ(fresh, box.taken());
  EXPECT_EQ(box.published(), kPublishes);
  EXPECT_EQ(box.taken() + box.overwritten(), box.published());
  EXPECT_GT(fresh, 0u);
  ::testing::Test::RecordProperty("fresh", static_cast<int>(fresh));
  ::testing::Test::RecordProperty("stale", static_cast<int>(stale));
}

}  // namespace
}  // namespace zerog::handover
