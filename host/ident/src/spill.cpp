#include "zerog/ident/spill.hpp"

#include <fcntl.h>
#include <linux/magic.h>
#include <sys/mman.h>
#include <sys/statfs.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <iterator>
#include <map>
#include <mutex>
#include <new>
#include <stdexcept>
#include <string>
#include <system_error>

namespace zerog::ident::spill {
namespace {

#ifndef RAMFS_MAGIC
#define RAMFS_MAGIC 0x858458f6
#endif

std::size_t env_size(const char* name, std::size_t fallback) {
  const char* v = std::getenv(name);
  if (v == nullptr || *v == '\0') return fallback;
  char* end = nullptr;
  errno = 0;
  const unsigned long long x = std::strtoull(v, &end, 10);
  if (errno != 0 || end == v || *end != '\0')
    throw std::runtime_error(std::string(name) + "='" + v + "' is not a number of bytes/rows");
  return static_cast<std::size_t>(x);
}

// The spill mappings: start address → bytes.
struct Registry {
  std::mutex mutex;
  std::map<std::uintptr_t, std::size_t> maps;
};
// Never destroyed: a dataset held in a static (destroyed at exit, perhaps after a registry made
// later would be) must still find its mapping.
Registry& registry() {
  static Registry* const r = new Registry;
  return *r;
}

bool memory_filesystem(const std::filesystem::path& dir) {
  struct statfs s {};
  if (::statfs(dir.c_str(), &s) != 0) return false;
  const auto type = static_cast<unsigned long>(s.f_type);
  return type == static_cast<unsigned long>(TMPFS_MAGIC) ||
         type == static_cast<unsigned long>(RAMFS_MAGIC);
}

[[noreturn]] void fail(const std::filesystem::path& dir, std::size_t bytes, const char* what,
                       int error) {
  throw std::runtime_error("cannot spill " + std::to_string(bytes) +
                           " bytes of the log's columns to " + dir.string() + " (" + what + ": " +
                           std::strerror(error) +
                           "); set ZEROG_SPILL_DIR to a directory on a disk with that much room");
}

// An unlinked file of `bytes` in `dir`, its blocks reserved.
int spill_file(const std::filesystem::path& dir, std::size_t bytes) {
  int fd = ::open(dir.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
  if (fd < 0) {  // no O_TMPFILE on this file system: a named file, unlinked at once
    std::string name = (dir / "zerog-spill-XXXXXX").string();
    fd = ::mkostemp(name.data(), O_CLOEXEC);
    if (fd < 0) fail(dir, bytes, "creating the file", errno);
    ::unlink(name.c_str());
  }
  const int error = ::posix_fallocate(fd, 0, static_cast<off_t>(bytes));
  if (error != 0) {
    ::close(fd);
    fail(dir, bytes, "reserving its blocks", error);
  }
  return fd;
}

}  // namespace

Settings& settings() {
  static Settings s = [] {
    Settings d;
    d.min_bytes = env_size("ZEROG_SPILL_MIN_BYTES", d.min_bytes);
    d.window_rows = std::max<std::size_t>(1, env_size("ZEROG_SPILL_WINDOW_ROWS", d.window_rows));
    return d;
  }();
  return s;
}

Stats& stats() {
  static Stats s;
  return s;
}

std::filesystem::path directory() {
  if (const char* d = std::getenv("ZEROG_SPILL_DIR"); d != nullptr && *d != '\0') return d;
  if (const char* t = std::getenv("TMPDIR"); t != nullptr && *t != '\0' && !memory_filesystem(t))
    return t;
  return "/var/tmp";
}

void* allocate(std::size_t bytes, std::size_t alignment) {
  if (bytes == 0 || bytes < settings().min_bytes) {
    if (alignment > __STDCPP_DEFAULT_NEW_ALIGNMENT__)
      return ::operator new(bytes, std::align_val_t(alignment));
    return ::operator new(bytes);
  }
  const std::filesystem::path dir = directory();
  const int fd = spill_file(dir, bytes);
  void* p = ::mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  const int error = errno;
  ::close(fd);  // the mapping keeps the file
  if (p == MAP_FAILED) fail(dir, bytes, "mapping the file", error);
  {
    Registry& r = registry();
    const std::lock_guard lock(r.mutex);
    r.maps.emplace(reinterpret_cast<std::uintptr_t>(p), bytes);
  }
  stats().spilled_bytes += bytes;
  return p;
}

void deallocate(void* p, std::size_t bytes, std::size_t alignment) noexcept {
  if (p == nullptr) return;
  {
    Registry& r = registry();
    const std::lock_guard lock(r.mutex);
    const auto it = r.maps.find(reinterpret_cast<std::uintptr_t>(p));
    if (it != r.maps.end()) {
      ::munmap(p, it->second);
      r.maps.erase(it);
      return;
    }
  }
  if (alignment > __STDCPP_DEFAULT_NEW_ALIGNMENT__)
    ::operator delete(p, bytes, std::align_val_t(alignment));
  else
    ::operator delete(p, bytes);
}

bool spilled(const void* p) noexcept {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  const auto a = reinterpret_cast<std::uintptr_t>(p);
  auto it = r.maps.upper_bound(a);
  if (it == r.maps.begin()) return false;
  --it;
  return a < it->first + it->second;
}

void release(const void* begin, const void* end) noexcept {
  auto a = reinterpret_cast<std::uintptr_t>(begin);
  auto e = reinterpret_cast<std::uintptr_t>(end);
  if (e <= a) return;
  std::uintptr_t map_begin = 0, map_end = 0;
  {
    Registry& r = registry();
    const std::lock_guard lock(r.mutex);
    auto it = r.maps.upper_bound(a);
    if (it == r.maps.begin()) return;
    --it;
    map_begin = it->first, map_end = it->first + it->second;
  }
  if (a >= map_end) return;
  // Every page the range touches (release changes no value, so a page shared with a neighbouring
  // row that is still in use only faults back in), within the mapping.
  static const auto page = static_cast<std::uintptr_t>(::sysconf(_SC_PAGESIZE));
  a = std::max(map_begin, a / page * page);
  e = std::min(map_end, (e + page - 1) / page * page);
  if (e <= a) return;
  if (::madvise(reinterpret_cast<void*>(a), e - a, MADV_DONTNEED) == 0)
    stats().released_bytes += e - a;
}

}  // namespace zerog::ident::spill
