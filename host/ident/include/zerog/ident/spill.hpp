#pragma once
// Spilling a long log's per-sample columns to disk (issue 16: a recording of any length fits in
// bounded memory).
//
// The Dataset's per-sample columns (dataset.hpp, Column<T>) use SpillAllocator: an allocation
// of fewer than spill::settings().min_bytes (default 512 KiB, e.g. 2^16 rows of a double column)
// is ordinary heap memory, so tests and short logs are unchanged; a larger one is an unlinked
// temporary file of exactly that size, memory-mapped MAP_SHARED. The data then lives in the file
// (and the kernel's page cache); the process holds only the pages it touched since they were last
// released. Every pass over the samples walks them front to back with a ResidentWindow, which
// releases the rows a window behind it (madvise MADV_DONTNEED: for a shared file mapping the
// pages leave the process, their contents stay in the file), so the resident part of the columns
// is a window of rows, whatever the length of the log. Reading a released row again (a pass that
// goes back, interpolation across a chunk edge, another thread) faults it back in from the file:
// release never changes a value, only what is resident.
//
// The passes that walk with a ResidentWindow: building the dataset (DatasetBuilder, and ω̇ from
// the gyro), the block statistics, the fit's own passes (start values, whitening, the final
// residuals) and the normal engine's solver passes on every thread (normal_equations.hpp,
// BlockEvaluator::walk), errors in variables, compare and the floors, diagnose's features,
// held-out residuals and discovery's signals. Not the Ceres engines (block_stats, samples: Ceres
// evaluates the blocks in its own order and keeps their Jacobians, which outweigh the columns),
// nor zerog learn's passes: there the touched rows stay resident until the dataset is freed, as
// they did on the heap.
//
// Where the file goes: $ZEROG_SPILL_DIR if set (used as given); else $TMPDIR unless it is a
// tmpfs or ramfs (that would hold the columns in memory again); else /var/tmp. The file is
// created unlinked (O_TMPFILE, or mkstemp then unlink), so nothing is left behind, even after a
// crash; its blocks are reserved up front (posix_fallocate), so a directory without room fails at
// once with std::runtime_error naming the directory and the bytes needed, never with SIGBUS
// later. Environment: ZEROG_SPILL_MIN_BYTES (the heap/spill threshold, bytes; 0 spills every
// column), ZEROG_SPILL_WINDOW_ROWS (rows kept behind a pass, default 65536); read once, at the
// first use. Host only (Linux: mmap, madvise, statfs).
#include <atomic>
#include <cstddef>
#include <filesystem>
#include <limits>
#include <new>

namespace zerog::ident::spill {

struct Settings {
  std::size_t min_bytes = std::size_t{1} << 19;    ///< allocations this large or larger spill
  std::size_t window_rows = std::size_t{1} << 16;  ///< rows a ResidentWindow keeps behind it
};
/// The process's settings (from the environment at the first call); tests may change them
/// between datasets (an allocation keeps where it went).
Settings& settings();

/// The directory spill files go to (see above), chosen at each call.
std::filesystem::path directory();

/// Counters for tests and reports (monotonic, all threads).
struct Stats {
  std::atomic<std::size_t> spilled_bytes{0};   ///< bytes ever mapped from spill files
  std::atomic<std::size_t> released_bytes{0};  ///< bytes passed to madvise(MADV_DONTNEED)
  /// The most rows any ResidentWindow had unreleased behind its front (reset by tests).
  std::atomic<std::size_t> peak_window_rows{0};
  /// Walks (ResidentWindow) over spilled rows that ended, each a pass of one thread.
  std::atomic<std::size_t> walks{0};
};
Stats& stats();

/// `bytes` of memory aligned to `alignment`: heap below settings().min_bytes, else a spill-file
/// mapping (page aligned). Throws std::runtime_error if the spill file cannot be made (naming the
/// directory and the bytes), std::bad_alloc if the heap fails.
void* allocate(std::size_t bytes, std::size_t alignment);
void deallocate(void* p, std::size_t bytes, std::size_t alignment) noexcept;
/// True if [p, p + bytes) lies in a spill mapping.
bool spilled(const void* p) noexcept;
/// Drops the pages touching [begin, end) from the process if they are in a spill mapping (the
/// data stays in the file: the next read faults it back in); a no-op for heap memory.
void release(const void* begin, const void* end) noexcept;

/// std::allocator's interface over allocate/deallocate (stateless: all instances are equal).
template <typename T>
struct Allocator {
  using value_type = T;
  Allocator() = default;
  template <typename U>
  Allocator(const Allocator<U>&) noexcept {}  // NOLINT(google-explicit-constructor)
  T* allocate(std::size_t n) {
    if (n > std::numeric_limits<std::size_t>::max() / sizeof(T)) throw std::bad_alloc();
    return static_cast<T*>(spill::allocate(n * sizeof(T), alignof(T)));
  }
  void deallocate(T* p, std::size_t n) noexcept { spill::deallocate(p, n * sizeof(T), alignof(T)); }
  template <typename U>
  bool operator==(const Allocator<U>&) const noexcept {
    return true;
  }
};

}  // namespace zerog::ident::spill
