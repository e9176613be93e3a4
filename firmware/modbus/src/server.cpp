#include "zerog/modbus/server.hpp"

#include <arpa/inet.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <mutex>

namespace zerog::modbus {
namespace {

using Clock = std::chrono::steady_clock;

Clock::duration seconds(double s) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
}

std::string errno_text(int e) { return std::strerror(e); }

bool parse_ipv4(const std::string& text, std::uint32_t& host_order) {
  in_addr a{};
  if (inet_pton(AF_INET, text.c_str(), &a) != 1) return false;
  host_order = ntohl(a.s_addr);
  return true;
}

std::string ipv4_text(std::uint32_t host_order) {
  char buf[INET_ADDRSTRLEN];
  const in_addr a{htonl(host_order)};
  inet_ntop(AF_INET, &a, buf, sizeof buf);
  return buf;
}

struct AtomicCounters {
  std::atomic<std::uint64_t> requests{0}, replies{0};
  std::array<std::atomic<std::uint64_t>, 7> exceptions{};
  std::atomic<std::uint64_t> writes_accepted{0}, writes_refused{0}, commands_accepted{0};
  std::atomic<std::uint64_t> clients_accepted{0}, clients_refused_allowlist{0},
      clients_refused_limit{0}, clients_closed{0}, request_timeouts{0}, idle_timeouts{0},
      framing_errors{0}, send_errors{0};
};

void bump(std::atomic<std::uint64_t>& c) { c.fetch_add(1, std::memory_order_relaxed); }

struct Client {
  int fd = -1;
  std::array<std::uint8_t, 2 * kMaxAduBytes> buffer{};
  std::size_t used = 0;
  Clock::time_point request_started{};  ///< first byte of the request in the buffer
  Clock::time_point last_request{};     ///< last complete request (or the connection)
};

}  // namespace

struct ModbusServer::Impl {
  Allowlist allow;
  int listen_fd = -1;
  int wake_fd = -1;  // eventfd: stop()
  modbus_t* ctx = nullptr;
  modbus_mapping_t* mapping = nullptr;
  std::vector<Client> clients;
  AtomicCounters counters;
  mutable std::mutex tunables_mutex;  // server thread vs tunables() callers; never the cycle
  loop::Tunables tunables;

  ~Impl() {
    for (Client& c : clients) ::close(c.fd);
    if (listen_fd >= 0) ::close(listen_fd);
    if (wake_fd >= 0) ::close(wake_fd);
    if (mapping != nullptr) modbus_mapping_free(mapping);
    if (ctx != nullptr) {
      modbus_set_socket(ctx, -1);
      modbus_free(ctx);
    }
  }
};

std::uint64_t ServerCounters::exceptions_total() const {
  std::uint64_t n = 0;
  for (std::uint64_t e : exceptions) n += e;
  return n;
}

Status check_server_config(const ServerConfig& c) {
  std::uint32_t a = 0;
  if (c.bind_address.empty())
    return Status::invalid("bind_address",
                           "required (the local IPv4 address to listen on, e.g. the cell "
                           "network's; \"0.0.0.0\" listens on every interface)");
  if (!parse_ipv4(c.bind_address, a))
    return Status::invalid("bind_address", "'" + c.bind_address + "' is not an IPv4 address");
  if (c.port < 0 || c.port > 65535)
    return Status::invalid("port", "must be 0..65535, is " + std::to_string(c.port));
  Allowlist allow;
  if (Status st = allow.parse(c.allow); !st.ok()) return st;
  if (c.max_clients < 1 || c.max_clients > 64)
    return Status::invalid("max_clients", "must be 1..64, is " + std::to_string(c.max_clients));
  if (!(c.request_timeout_s > 0.0 && c.request_timeout_s <= 10.0))
    return Status::invalid("request_timeout_s", "must be in (0, 10] s");
  if (!(c.idle_timeout_s >= 0.0 && c.idle_timeout_s <= 86400.0))
    return Status::invalid("idle_timeout_s", "must be 0 (never) or up to 86400 s");
  if (!(c.proposal_timeout_s > 0.0 && c.proposal_timeout_s <= 5.0))
    return Status::invalid("proposal_timeout_s", "must be in (0, 5] s");
  return {};
}

Status Allowlist::parse(const std::vector<std::string>& entries) {
  nets_.clear();
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const std::string& e = entries[i];
    const std::string setting = "allow[" + std::to_string(i) + "]";
    const std::string quoted = "'" + e + "' ";
    const std::size_t slash = e.find('/');
    std::uint32_t address = 0;
    if (!parse_ipv4(e.substr(0, slash), address))
      return Status::invalid(setting,
                             quoted + "is not an IPv4 address or network (a.b.c.d or a.b.c.d/n)");
    int bits = 32;
    if (slash != std::string::npos) {
      const std::string n = e.substr(slash + 1);
      if (n.empty() || n.size() > 2 || !std::all_of(n.begin(), n.end(), ::isdigit) ||
          std::stoi(n) > 32)
        return Status::invalid(setting, quoted + "has a prefix length that is not 0..32");
      bits = std::stoi(n);
    }
    const std::uint32_t mask = bits == 0 ? 0u : ~std::uint32_t{0} << (32 - bits);
    if ((address & ~mask) != 0)
      return Status::invalid(setting, quoted + "has host bits set (did you mean " +
                                          ipv4_text(address & mask) + "/" + std::to_string(bits) +
                                          "?)");
    nets_.push_back({address, mask});
  }
  return {};
}

bool Allowlist::permits(std::uint32_t ipv4_host_order) const {
  if (nets_.empty()) return true;
  return std::any_of(nets_.begin(), nets_.end(),
                     [&](const Net& n) { return (ipv4_host_order & n.mask) == n.address; });
}

ModbusServer::ModbusServer(ServerConfig config, SupervisorTarget& target)
    : config_(std::move(config)), target_(target) {}

ModbusServer::~ModbusServer() { stop(); }

ServerCounters ModbusServer::counters() const {
  ServerCounters out;
  if (!impl_) return out;
  const AtomicCounters& c = impl_->counters;
  const auto get = [](const std::atomic<std::uint64_t>& a) {
    return a.load(std::memory_order_relaxed);
  };
  out.requests = get(c.requests);
  out.replies = get(c.replies);
  for (std::size_t i = 0; i < out.exceptions.size(); ++i) out.exceptions[i] = get(c.exceptions[i]);
  out.writes_accepted = get(c.writes_accepted);
  out.writes_refused = get(c.writes_refused);
  out.commands_accepted = get(c.commands_accepted);
  out.clients_accepted = get(c.clients_accepted);
  out.clients_refused_allowlist = get(c.clients_refused_allowlist);
  out.clients_refused_limit = get(c.clients_refused_limit);
  out.clients_closed = get(c.clients_closed);
  out.request_timeouts = get(c.request_timeouts);
  out.idle_timeouts = get(c.idle_timeouts);
  out.framing_errors = get(c.framing_errors);
  out.send_errors = get(c.send_errors);
  return out;
}

loop::Tunables ModbusServer::tunables() const {
  if (!impl_) return target_.tunables();
  std::lock_guard lock(impl_->tunables_mutex);
  return impl_->tunables;
}

namespace {

/// The server thread's state and loop (kept out of the header).
class Loop {
 public:
  Loop(const ServerConfig& config, SupervisorTarget& target, ModbusServer::Impl& impl,
       std::atomic<int>& clients_now)
      : config_(config), target_(target), impl_(impl), clients_now_(clients_now) {}

  void run() {
    std::vector<pollfd> fds;
    for (;;) {
      fds.clear();
      fds.push_back({impl_.wake_fd, POLLIN, 0});
      fds.push_back({impl_.listen_fd, POLLIN, 0});
      bool pending = false;
      for (const Client& c : impl_.clients) {
        const short events = c.used < c.buffer.size() ? POLLIN : 0;
        fds.push_back({c.fd, events, 0});
        if (frame_request({c.buffer.data(), c.used}).status != FrameStatus::incomplete)
          pending = true;
      }
      const int timeout_ms = pending ? 0 : poll_timeout_ms();
      if (::poll(fds.data(), fds.size(), timeout_ms) < 0 && errno != EINTR) return;
      if ((fds[0].revents & POLLIN) != 0) return;  // stop()
      // Clients first (their fds are at 2.. in the order of impl_.clients), then new ones.
      std::vector<std::size_t> to_close;
      for (std::size_t i = 0; i < impl_.clients.size(); ++i) {
        if (!serve(impl_.clients[i], fds[2 + i].revents)) to_close.push_back(i);
      }
      for (auto it = to_close.rbegin(); it != to_close.rend(); ++it) close_client(*it);
      if ((fds[1].revents & POLLIN) != 0) accept_clients();
    }
  }

 private:
  int poll_timeout_ms() const {
    const Clock::time_point now = Clock::now();
    Clock::duration wait = std::chrono::milliseconds(100);
    for (const Client& c : impl_.clients) {
      if (c.used > 0)
        wait = std::min(wait, c.request_started + seconds(config_.request_timeout_s) - now);
      if (config_.idle_timeout_s > 0.0)
        wait = std::min(wait, c.last_request + seconds(config_.idle_timeout_s) - now);
    }
    const auto ms = std::chrono::ceil<std::chrono::milliseconds>(wait).count();
    return static_cast<int>(std::clamp<long long>(ms, 0, 100));
  }

  void accept_clients() {
    for (;;) {
      sockaddr_in peer{};
      socklen_t len = sizeof peer;
      const int fd = ::accept4(impl_.listen_fd, reinterpret_cast<sockaddr*>(&peer), &len,
                               SOCK_NONBLOCK | SOCK_CLOEXEC);
      if (fd < 0) {
        // EAGAIN: no more. Out of descriptors (EMFILE, ENFILE, ENOBUFS): the connection stays
        // queued and the socket readable; pause so that poll() does not spin on it.
        if (errno == EMFILE || errno == ENFILE || errno == ENOBUFS || errno == ENOMEM)
          std::this_thread::sleep_for(std::chrono::milliseconds(10));
        return;
      }
      if (!impl_.allow.permits(ntohl(peer.sin_addr.s_addr))) {
        bump(impl_.counters.clients_refused_allowlist);  // before the peer can see the close
        ::close(fd);
        continue;
      }
      if (impl_.clients.size() >= static_cast<std::size_t>(config_.max_clients)) {
        bump(impl_.counters.clients_refused_limit);
        ::close(fd);
        continue;
      }
      const int one = 1;
      ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
      Client c;
      c.fd = fd;
      c.last_request = Clock::now();
      impl_.clients.push_back(c);
      bump(impl_.counters.clients_accepted);
      clients_now_.store(static_cast<int>(impl_.clients.size()), std::memory_order_relaxed);
    }
  }

  void close_client(std::size_t i) {
    ::close(impl_.clients[i].fd);
    impl_.clients.erase(impl_.clients.begin() + static_cast<std::ptrdiff_t>(i));
    clients_now_.store(static_cast<int>(impl_.clients.size()), std::memory_order_relaxed);
  }

  /// Reads what arrived, answers at most one complete request (fair to the others). False:
  /// close the client.
  bool serve(Client& c, short revents) {
    const Clock::time_point now = Clock::now();
    Frame f = frame_request({c.buffer.data(), c.used});
    // Read only when no complete request waits (it is answered first, even if the peer has
    // closed its side after sending it).
    if (f.status == FrameStatus::incomplete) {
      if ((revents & POLLIN) != 0) {
        const ssize_t n = ::recv(c.fd, c.buffer.data() + c.used, c.buffer.size() - c.used, 0);
        if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) {
          bump(impl_.counters.clients_closed);
          return false;
        }
        if (n > 0) {
          if (c.used == 0) c.request_started = now;
          c.used += static_cast<std::size_t>(n);
        }
      } else if ((revents & (POLLERR | POLLHUP | POLLNVAL)) != 0) {
        bump(impl_.counters.clients_closed);
        return false;
      }
      f = frame_request({c.buffer.data(), c.used});
    }
    if (f.status == FrameStatus::invalid) {
      bump(impl_.counters.framing_errors);
      return false;
    }
    if (f.status == FrameStatus::incomplete) {
      if (c.used > 0 && now - c.request_started > seconds(config_.request_timeout_s)) {
        bump(impl_.counters.request_timeouts);
        return false;
      }
      if (c.used == 0 && config_.idle_timeout_s > 0.0 &&
          now - c.last_request > seconds(config_.idle_timeout_s)) {
        bump(impl_.counters.idle_timeouts);
        return false;
      }
      return true;
    }
    const bool sent = handle(c.fd, {c.buffer.data(), f.length});
    std::memmove(c.buffer.data(), c.buffer.data() + f.length, c.used - f.length);
    c.used -= f.length;
    c.last_request = Clock::now();
    c.request_started = c.last_request;  // of what follows in the buffer, if anything
    if (!sent) bump(impl_.counters.send_errors);
    return sent;
  }

  StatusInputs status(const SupervisorSnapshot& s) const {
    StatusInputs in;
    in.target = s;
    in.proposal = target_.proposal_status();
    in.clients_connected = static_cast<std::uint16_t>(impl_.clients.size());
    const AtomicCounters& c = impl_.counters;
    in.requests = c.requests.load(std::memory_order_relaxed);
    std::uint64_t exceptions = 0;
    for (const auto& e : c.exceptions) exceptions += e.load(std::memory_order_relaxed);
    in.exceptions = exceptions;
    in.writes_refused = c.writes_refused.load(std::memory_order_relaxed);
    in.clients_refused = c.clients_refused_allowlist.load(std::memory_order_relaxed) +
                         c.clients_refused_limit.load(std::memory_order_relaxed);
    return in;
  }

  void refresh(const SupervisorSnapshot& s) {
    modbus_mapping_t& m = *impl_.mapping;
    const StatusInputs in = status(s);
    fill_bits(Table::coil, in, {m.tab_bits, static_cast<std::size_t>(m.nb_bits)});
    fill_bits(Table::discrete_input, in,
              {m.tab_input_bits, static_cast<std::size_t>(m.nb_input_bits)});
    fill_input(in, {m.tab_input_registers, static_cast<std::size_t>(m.nb_input_registers)});
    std::lock_guard lock(impl_.tunables_mutex);
    fill_holding(impl_.tunables, {m.tab_registers, static_cast<std::size_t>(m.nb_registers)});
  }

  /// Answers one request; false if the answer could not be sent.
  bool handle(int fd, std::span<const std::uint8_t> adu) {
    bump(impl_.counters.requests);
    modbus_set_socket(impl_.ctx, fd);
    const SupervisorSnapshot snap = target_.snapshot();
    loop::Tunables current;
    {
      std::lock_guard lock(impl_.tunables_mutex);
      current = impl_.tunables;
    }
    const Decision d = decide(adu, current, snap.state);
    ExceptionCode code = d.exception;
    switch (d.action) {
      case Action::read:
      case Action::write_noop:
      case Action::exception:
        break;
      case Action::write_tunables:
        code = propose_and_wait(d.tunables);
        if (code == ExceptionCode::none) {
          std::lock_guard lock(impl_.tunables_mutex);
          impl_.tunables = d.tunables;
          bump(impl_.counters.writes_accepted);
        }
        break;
      case Action::command:
        code = command_and_wait(d.command);
        if (code == ExceptionCode::none) bump(impl_.counters.commands_accepted);
        break;
    }
    const int length = static_cast<int>(adu.size());
    if (code != ExceptionCode::none) {
      const auto index = static_cast<std::size_t>(code);
      if (index < impl_.counters.exceptions.size()) bump(impl_.counters.exceptions[index]);
      const bool write =
          d.function == 0x05 || d.function == 0x06 || d.function == 0x0F || d.function == 0x10;
      if (write && code != ExceptionCode::acknowledge) bump(impl_.counters.writes_refused);
      return modbus_reply_exception(impl_.ctx, adu.data(), static_cast<unsigned>(code)) > 0;
    }
    refresh(d.action == Action::read ? snap : target_.snapshot());
    bump(impl_.counters.replies);
    return modbus_reply(impl_.ctx, adu.data(), length, impl_.mapping) > 0;
  }

  ExceptionCode propose_and_wait(const loop::Tunables& t) {
    if (!target_.propose(t)) return ExceptionCode::server_device_busy;
    const Clock::time_point deadline = Clock::now() + seconds(config_.proposal_timeout_s);
    loop::ProposalStatus s = target_.proposal_status();
    while (s == loop::ProposalStatus::pending) {
      if (Clock::now() > deadline && target_.withdraw_proposal())
        return ExceptionCode::server_device_failure;  // the cycle is not running
      std::this_thread::sleep_for(std::chrono::microseconds(200));
      s = target_.proposal_status();
    }
    switch (s) {
      case loop::ProposalStatus::accepted:
        return ExceptionCode::none;
      case loop::ProposalStatus::refused_state:
        return ExceptionCode::server_device_busy;
      case loop::ProposalStatus::refused_invalid:
        return ExceptionCode::illegal_data_value;
      default:
        return ExceptionCode::server_device_failure;
    }
  }

  ExceptionCode command_and_wait(loop::Command c) {
    const std::uint64_t ticket = target_.request(c);
    if (ticket == 0) return ExceptionCode::server_device_busy;
    // The next step() applies it and records its own outcome under the ticket.
    const Clock::time_point deadline = Clock::now() + seconds(config_.proposal_timeout_s);
    for (;;) {
      switch (target_.command_outcome(ticket)) {
        case loop::CommandOutcome::accepted:
          return await_snapshot_after(deadline);
        case loop::CommandOutcome::refused:
          return ExceptionCode::server_device_failure;
        case loop::CommandOutcome::unknown:  // 8 later commands while this server waited
          return ExceptionCode::acknowledge;
        case loop::CommandOutcome::pending:
          break;
      }
      if (Clock::now() > deadline) return ExceptionCode::acknowledge;  // queued, not yet run
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
  }

  /// The cycle records a command's outcome during step() and publishes the snapshot after it:
  /// a PLC that reads the state right after the write's reply must see the command applied, so
  /// the reply waits for a snapshot newer than the one current now (at most one cycle late).
  ExceptionCode await_snapshot_after(Clock::time_point deadline) {
    const std::uint64_t seen = target_.snapshot().cycle;
    while (target_.snapshot().cycle <= seen) {
      if (Clock::now() > deadline) return ExceptionCode::acknowledge;  // applied, not yet shown
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    return ExceptionCode::none;
  }

  const ServerConfig& config_;
  SupervisorTarget& target_;
  ModbusServer::Impl& impl_;
  std::atomic<int>& clients_now_;
};

}  // namespace

Status ModbusServer::start() {
  if (started_) return {StatusCode::already_started, "Modbus server: already started"};
  if (Status st = check_server_config(config_); !st.ok()) return st;
  const auto failed = [](std::string why) {
    return Status(StatusCode::system_error, "Modbus server: " + std::move(why));
  };
  auto impl = std::make_unique<Impl>();
  (void)impl->allow.parse(config_.allow);  // checked above
  impl->tunables = target_.tunables();
  const std::string where = config_.bind_address + ":" + std::to_string(config_.port);

  impl->listen_fd = ::socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (impl->listen_fd < 0) return failed("socket: " + errno_text(errno));
  const int one = 1;
  ::setsockopt(impl->listen_fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(config_.port));
  inet_pton(AF_INET, config_.bind_address.c_str(), &addr.sin_addr);
  if (::bind(impl->listen_fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    const int e = errno;
    std::string why = "cannot bind " + where + ": " + errno_text(e);
    if (e == EACCES && config_.port < 1024)
      why += " (ports below 1024 need root or CAP_NET_BIND_SERVICE)";
    return failed(std::move(why));
  }
  if (::listen(impl->listen_fd, 16) != 0)
    return failed("cannot listen on " + where + ": " + errno_text(errno));
  socklen_t len = sizeof addr;
  ::getsockname(impl->listen_fd, reinterpret_cast<sockaddr*>(&addr), &len);
  impl->wake_fd = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  if (impl->wake_fd < 0) return failed("eventfd: " + errno_text(errno));

  impl->ctx = modbus_new_tcp(config_.bind_address.c_str(), config_.port);
  if (impl->ctx == nullptr) return failed("modbus_new_tcp failed");
  impl->mapping = modbus_mapping_new_start_address(
      0, table_extent(Table::coil), 0, table_extent(Table::discrete_input), 0,
      table_extent(Table::holding_register), 0, table_extent(Table::input_register));
  if (impl->mapping == nullptr) return failed("cannot allocate the register map");

  port_ = ntohs(addr.sin_port);
  impl_ = std::move(impl);
  try {
    thread_ = std::thread([this] {
      Loop loop(config_, target_, *impl_, clients_now_);
      loop.run();
    });
  } catch (const std::exception& e) {
    return failed(std::string("cannot start its thread: ") + e.what());
  }
  started_ = true;
  return {};
}

void ModbusServer::stop() {
  if (!started_) return;
  const std::uint64_t one = 1;
  [[maybe_unused]] const ssize_t n = ::write(impl_->wake_fd, &one, sizeof one);
  if (thread_.joinable()) thread_.join();
  started_ = false;
  for (Client& c : impl_->clients) ::close(c.fd);
  impl_->clients.clear();
  clients_now_.store(0, std::memory_order_relaxed);
  ::close(impl_->listen_fd);
  impl_->listen_fd = -1;
}

}  // namespace zerog::modbus
