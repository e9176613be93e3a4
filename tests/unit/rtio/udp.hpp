#pragma once
// A UDP socket playing the robot controller in tests and benchmarks. Test code; header-only.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <charconv>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <span>
#include <string_view>

namespace zerog::rtio::test {

class UdpPeer {
 public:
  /// Binds to `address`:`port` (0: any free port).
  explicit UdpPeer(const char* address = "127.0.0.1", std::uint16_t port = 0) {
    fd_ = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_in local{};
    local.sin_family = AF_INET;
    local.sin_port = htons(port);
    ::inet_pton(AF_INET, address, &local.sin_addr);
    if (fd_ < 0 || ::bind(fd_, reinterpret_cast<sockaddr*>(&local), sizeof local) != 0) {
      if (fd_ >= 0) ::close(fd_);
      fd_ = -1;
      return;
    }
    socklen_t length = sizeof local;
    ::getsockname(fd_, reinterpret_cast<sockaddr*>(&local), &length);
    port_ = ntohs(local.sin_port);
  }
  ~UdpPeer() {
    if (fd_ >= 0) ::close(fd_);
  }
  UdpPeer(const UdpPeer&) = delete;
  UdpPeer& operator=(const UdpPeer&) = delete;

  bool ok() const { return fd_ >= 0; }
  int fd() const { return fd_; }
  std::uint16_t port() const { return port_; }

  bool send_to(std::uint16_t port, std::string_view bytes, const char* address = "127.0.0.1") {
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_port = htons(port);
    ::inet_pton(AF_INET, address, &to.sin_addr);
    return ::sendto(fd_, bytes.data(), bytes.size(), 0, reinterpret_cast<sockaddr*>(&to),
                    sizeof to) == static_cast<ssize_t>(bytes.size());
  }
  /// One datagram into `buffer` within `timeout_ms`; its length, or −1 on timeout/error.
  /// `from_port` (if given) receives the sender's port.
  long receive(std::span<char> buffer, int timeout_ms, std::uint16_t* from_port = nullptr) {
    pollfd pfd{fd_, POLLIN, 0};
    if (::poll(&pfd, 1, timeout_ms) != 1) return -1;
    sockaddr_in from{};
    socklen_t length = sizeof from;
    const ssize_t n = ::recvfrom(fd_, buffer.data(), buffer.size(), 0,
                                 reinterpret_cast<sockaddr*>(&from), &length);
    if (from_port != nullptr) *from_port = ntohs(from.sin_port);
    return n;
  }

 private:
  int fd_ = -1;
  std::uint16_t port_ = 0;
};

/// Writes a controller message (shaped like a KR C4's) with `ipoc` into `buffer`; returns the
/// view of it. No allocation.
inline std::string_view robot_message(std::span<char> buffer, std::uint64_t ipoc) {
  const int n = std::snprintf(
      buffer.data(), buffer.size(),
      "<Rob Type=\"KUKA\"><RIst X=\"445.5\" Y=\"-0.25\" Z=\"900.0\" A=\"180\" B=\"0.5\" "
      "C=\"-179.9\"/><RSol X=\"445.5\" Y=\"-0.25\" Z=\"900.0\" A=\"180\" B=\"0.5\" C=\"-179.9\"/>"
      "<AIPos A1=\"0\" A2=\"-90\" A3=\"90\" A4=\"0\" A5=\"45.5\" A6=\"-12.25\"/>"
      "<Delay D=\"0\"/><Digout o1=\"0\" o2=\"1\"/><IPOC>%llu</IPOC></Rob>",
      static_cast<unsigned long long>(ipoc));
  return {buffer.data(), n > 0 ? static_cast<std::size_t>(n) : 0};
}

/// The IPOC in a <Sen> reply, or −1 when there is none.
inline long long reply_ipoc(std::string_view reply) {
  const std::size_t start = reply.find("<IPOC>");
  if (start == std::string_view::npos) return -1;
  unsigned long long value = 0;
  const char* first = reply.data() + start + 6;
  const auto [end, error] = std::from_chars(first, reply.data() + reply.size(), value);
  if (error != std::errc{} || std::string_view(end, 7) != "</IPOC>") return -1;
  return static_cast<long long>(value);
}

}  // namespace zerog::rtio::test
