#pragma once
// Shared by the fuzz targets (tests/fuzz): a private scratch folder in /dev/shm for the parsers
// that read files, the check that fails a target, and a byte reader for structured inputs.
#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <span>
#include <string>
#include <string_view>

namespace zerog::fuzz {

/// Stops the run as a crash (libFuzzer saves the input) when a property does not hold.
#define ZEROG_FUZZ_CHECK(cond)                                                           \
  do {                                                                                   \
    if (!(cond)) {                                                                       \
      std::fprintf(stderr, "%s:%d: property violated: %s\n", __FILE__, __LINE__, #cond); \
      __builtin_trap();                                                                  \
    }                                                                                    \
  } while (0)

/// A folder of this process in $ZEROG_FUZZ_SCRATCH (scripts/fuzz.sh sets it and removes it
/// afterwards), else in /dev/shm (RAM, no disk wear). Removed at a normal exit; libFuzzer ends
/// with _Exit() after -max_total_time, which skips that, hence the variable.
inline const std::filesystem::path& scratch_dir() {
  static const std::filesystem::path dir = [] {
    const char* parent = std::getenv("ZEROG_FUZZ_SCRATCH");
    std::string tmpl = std::string(parent != nullptr && *parent != '\0' ? parent : "/dev/shm") +
                       "/zerog-fuzz-XXXXXX";
    if (::mkdtemp(tmpl.data()) == nullptr) {
      std::perror("zerog fuzz: mkdtemp in /dev/shm");
      std::abort();
    }
    std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(scratch_dir(), ec);
    });
    return std::filesystem::path(tmpl);
  }();
  return dir;
}

/// Writes `bytes` to `path` (replacing it); aborts if it cannot (not a finding of the parser).
inline void write_bytes(const std::filesystem::path& path, std::string_view bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out) {
    std::fprintf(stderr, "zerog fuzz: cannot write %s\n", path.c_str());
    std::abort();
  }
}

inline std::string_view as_text(const std::uint8_t* data, std::size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

/// Equal within `abs_tol` plus `rel_tol` of the larger magnitude (both NaN counts as equal).
inline bool near(double a, double b, double abs_tol, double rel_tol) {
  if (std::isnan(a) || std::isnan(b)) return std::isnan(a) && std::isnan(b);
  return std::fabs(a - b) <= abs_tol + rel_tol * std::fmax(std::fabs(a), std::fabs(b));
}

/// Takes bytes from the front of the input; returns 0 once it is used up.
class ByteReader {
 public:
  ByteReader(const std::uint8_t* data, std::size_t size) : rest_(data, size) {}
  std::uint8_t u8() {
    if (rest_.empty()) return 0;
    const std::uint8_t b = rest_.front();
    rest_ = rest_.subspan(1);
    return b;
  }
  std::uint32_t u32() {
    std::uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v = (v << 8) | u8();
    return v;
  }
  bool empty() const { return rest_.empty(); }
  std::span<const std::uint8_t> rest() const { return rest_; }

 private:
  std::span<const std::uint8_t> rest_;
};

}  // namespace zerog::fuzz
