#pragma once
// The Modbus TCP server of zerog-rt (proto/modbus.md). One thread of its own: poll() over the
// listening socket and at most max_clients client sockets, all non-blocking. It frames requests
// itself (frame_request), so a client that sends half a request or stops reading cannot hold
// the thread (request_timeout_s closes it), decides with decide() and answers with libmodbus
// (modbus_reply / modbus_reply_exception). It reaches the cycle only through SupervisorTarget,
// so the cycle never waits for it. Not real-time: start()/stop() allocate and may fail.
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "zerog/modbus/request.hpp"
#include "zerog/modbus/target.hpp"
#include "zerog/status.hpp"

namespace zerog::modbus {

/// The [modbus] settings of zerog-rt's configuration (proto/rt_config.md).
struct ServerConfig {
  /// Local IPv4 address to listen on. Required: there is no default, so nothing listens on all
  /// interfaces unless "0.0.0.0" is written down.
  std::string bind_address;
  int port = 502;  ///< 0..65535; 0 takes a free port (tests; see ModbusServer::port())
  /// Clients allowed to connect: IPv4 addresses ("10.0.0.7") or networks ("10.0.0.0/24").
  /// Empty: anyone who can reach bind_address.
  std::vector<std::string> allow;
  int max_clients = 4;  ///< 1..64; a connection beyond it is closed at once (counted)
  /// A request must be complete this long after its first byte, else the client is closed.
  double request_timeout_s = 0.5;
  /// A client silent this long is closed (frees its slot); 0: never.
  double idle_timeout_s = 60.0;
  /// Longest wait for the cycle to take a parameter write or a command (the server answers no
  /// one else meanwhile); a write still waiting is withdrawn (exception 04).
  double proposal_timeout_s = 0.25;
};

/// ok() if usable, else invalid_setting naming the ServerConfig field ("bind_address",
/// "allow[1]", "max_clients", …) with why.
Status check_server_config(const ServerConfig& c);

/// The allowlist, parsed. permits() takes an address in host byte order.
class Allowlist {
 public:
  /// ok() or invalid_setting naming the entry ("allow[1]") with why.
  Status parse(const std::vector<std::string>& entries);
  bool permits(std::uint32_t ipv4_host_order) const;
  bool empty() const { return nets_.empty(); }

 private:
  struct Net {
    std::uint32_t address, mask;
  };
  std::vector<Net> nets_;
};

/// Everything the server counts (a copy; ModbusServer::counters()).
struct ServerCounters {
  std::uint64_t requests = 0;  ///< complete requests handled
  std::uint64_t replies = 0;   ///< normal replies sent
  /// Exception replies by code (index = code 1..6; 0 unused).
  std::array<std::uint64_t, 7> exceptions{};
  std::uint64_t writes_accepted = 0;    ///< register writes the cycle accepted
  std::uint64_t writes_refused = 0;     ///< register and coil writes answered with an exception
  std::uint64_t commands_accepted = 0;  ///< coil writes the cycle carried out
  std::uint64_t clients_accepted = 0;
  std::uint64_t clients_refused_allowlist = 0;
  std::uint64_t clients_refused_limit = 0;
  std::uint64_t clients_closed = 0;    ///< by the peer or on a socket error
  std::uint64_t request_timeouts = 0;  ///< closed: a request not complete in request_timeout_s
  std::uint64_t idle_timeouts = 0;     ///< closed: silent for idle_timeout_s
  std::uint64_t framing_errors = 0;    ///< closed: not Modbus TCP
  std::uint64_t send_errors = 0;       ///< closed: the reply could not be sent whole
  std::uint64_t exceptions_total() const;
};

class ModbusServer {
 public:
  /// `target` must outlive the server.
  ModbusServer(ServerConfig config, SupervisorTarget& target);
  ~ModbusServer();  ///< stop()
  ModbusServer(const ModbusServer&) = delete;
  ModbusServer& operator=(const ModbusServer&) = delete;

  /// Checks the configuration, binds and listens, takes the target's tunables and starts the
  /// thread. ok(), or check_server_config's invalid_setting, already_started, or system_error
  /// ("Modbus server: cannot bind 127.0.0.1:502: Permission denied").
  Status start();
  /// Closes every connection and joins the thread. Idempotent.
  void stop();

  /// The port listened on (the chosen one when configured as 0); 0 before start().
  int port() const { return port_; }
  ServerCounters counters() const;
  int clients_connected() const { return clients_now_.load(std::memory_order_relaxed); }
  /// The tunables the server last saw accepted (its copy; the server thread writes it).
  loop::Tunables tunables() const;

  struct Impl;

 private:
  ServerConfig config_;
  SupervisorTarget& target_;
  std::unique_ptr<Impl> impl_;
  std::thread thread_;
  int port_ = 0;
  std::atomic<int> clients_now_{0};
  bool started_ = false;
};

}  // namespace zerog::modbus
