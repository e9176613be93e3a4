// zerog-soak (issue 6): a simulated hour of zero-g sessions with pushes and injected faults,
// faster than real time. One zerog::rt::Runtime with its own threads (the cycle thread running
// cycle_once(), the recorder writing run.csv, cycles.csv and the black boxes) and the real RSI
// endpoint on loopback UDP. This program is the robot controller (<Rob> datagrams through the
// codec, each reply read back and parsed before the next datagram: lock-step, as fast as the
// threads answer) and the sensor threads (F/T and IMU samples pushed into the runtime's rings).
// It follows the runtime only through what any thread may read (the supervisor snapshot, the
// proposal status, the replies), and reads the counters after stop().
//
// Scripted sessions: idle → enable_zero_g → pushes (random magnitudes and directions, some
// off-centre for a torque) → stop, or a fault → reset_fault → idle. Faults are injected at random
// times (silent, critical, saturated F/T; silent IMU; lost robot cycles; malformed datagrams; IPOC
// gaps; a growing Delay; contact over the limit), and short disturbances that must not fault
// (duplicate and reordered IPOCs, one or two lost cycles, short sensor dropouts). Supervisor
// parameter changes go through Runtime::propose() as the Modbus server's do.
//
// Checks (every failure is listed; exit 1 if any): each injected fault raised its fault and no
// fault was raised without one; every command did what states.md says; memory after the warm-up
// minute vs the end; every record in cycles.csv in order, run.csv rows = records − stale, and the
// recorder's counters, the summary JSON and this program's own counts agree. `--report FILE`
// writes the figures as JSON; stdout gets them too.
#include <arpa/inet.h>
#include <malloc.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <new>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "rt_fixtures.hpp"
#include "zerog/proto/rsi.hpp"
#include "zerog/rt/runtime.hpp"
#include "zerog/rtio/rsi_endpoint.hpp"

// --- heap in use, all threads ----------------------------------------------------------------
// mallinfo2() sees glibc's main arena only; the recorder thread allocates from its own arena.
// So the global allocation functions are replaced here to count the bytes of C++ allocations
// alive in any thread (malloc_usable_size of each block).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
namespace {
std::atomic<std::int64_t> g_live_bytes{0};

void* tracked_alloc(std::size_t size) {
  void* p = std::malloc(size == 0 ? 1 : size);
  if (p != nullptr)
    g_live_bytes.fetch_add(static_cast<std::int64_t>(::malloc_usable_size(p)),
                           std::memory_order_relaxed);
  return p;
}
void* tracked_aligned(std::size_t size, std::align_val_t alignment) {
  const auto a = static_cast<std::size_t>(alignment);
  const std::size_t rounded = ((size == 0 ? 1 : size) + a - 1) / a * a;
  void* p = std::aligned_alloc(a, rounded);
  if (p != nullptr)
    g_live_bytes.fetch_add(static_cast<std::int64_t>(::malloc_usable_size(p)),
                           std::memory_order_relaxed);
  return p;
}
void tracked_free(void* p) noexcept {
  if (p == nullptr) return;
  g_live_bytes.fetch_sub(static_cast<std::int64_t>(::malloc_usable_size(p)),
                         std::memory_order_relaxed);
  std::free(p);
}
}  // namespace

void* operator new(std::size_t size) {
  if (void* p = tracked_alloc(size)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) {
  if (void* p = tracked_alloc(size)) return p;
  throw std::bad_alloc();
}
void* operator new(std::size_t size, const std::nothrow_t&) noexcept { return tracked_alloc(size); }
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept {
  return tracked_alloc(size);
}
void* operator new(std::size_t size, std::align_val_t a) {
  if (void* p = tracked_aligned(size, a)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size, std::align_val_t a) {
  if (void* p = tracked_aligned(size, a)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { tracked_free(p); }
void operator delete[](void* p) noexcept { tracked_free(p); }
void operator delete(void* p, std::size_t) noexcept { tracked_free(p); }
void operator delete[](void* p, std::size_t) noexcept { tracked_free(p); }
void operator delete(void* p, std::align_val_t) noexcept { tracked_free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { tracked_free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { tracked_free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { tracked_free(p); }
#pragma GCC diagnostic pop

namespace zerog::soak {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using Wrench = Eigen::Matrix<double, 6, 1>;

struct Memory {
  std::int64_t rss_bytes = 0;         ///< /proc/self/statm resident pages × page size
  std::int64_t main_arena_bytes = 0;  ///< mallinfo2().uordblks (glibc's main arena only)
  std::int64_t heap_live_bytes = 0;   ///< C++ allocations alive, every thread
};

Memory measure_memory() {
  Memory m;
  std::ifstream statm("/proc/self/statm");
  std::int64_t size_pages = 0, resident_pages = 0;
  statm >> size_pages >> resident_pages;
  m.rss_bytes = resident_pages * ::sysconf(_SC_PAGESIZE);
  m.main_arena_bytes = static_cast<std::int64_t>(::mallinfo2().uordblks);
  m.heap_live_bytes = g_live_bytes.load(std::memory_order_relaxed);
  return m;
}

// Under AddressSanitizer freed memory waits in the sanitizer's quarantine (256 MiB by default)
// before it is reused, so the resident size grows with the amount freed, not with what is kept:
// there the live-heap count is the check and RSS is only reported.
#if defined(__SANITIZE_ADDRESS__)
constexpr bool kRssIsChecked = false;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kRssIsChecked = false;
#else
constexpr bool kRssIsChecked = true;
#endif
#else
constexpr bool kRssIsChecked = true;
#endif

double to_mib(std::int64_t bytes) { return static_cast<double>(bytes) / (1024.0 * 1024.0); }

json memory_json(const Memory& m) {
  return {{"rss_bytes", m.rss_bytes},
          {"main_arena_bytes", m.main_arena_bytes},
          {"heap_live_bytes", m.heap_live_bytes}};
}

/// The controller's end of the RSI link: a UDP socket on loopback connected to the endpoint.
class RobotSide {
 public:
  ~RobotSide() {
    if (fd_ >= 0) ::close(fd_);
  }
  std::string open(std::uint16_t endpoint_port) {
    fd_ = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (fd_ < 0) return std::string("robot socket: ") + std::strerror(errno);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(endpoint_port);
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::connect(fd_, reinterpret_cast<const sockaddr*>(&a), sizeof a) != 0)
      return std::string("robot socket connect: ") + std::strerror(errno);
    return {};
  }
  bool send(std::string_view datagram) {
    return ::send(fd_, datagram.data(), datagram.size(), 0) ==
           static_cast<ssize_t>(datagram.size());
  }
  /// The next reply, waiting at most `timeout_ms`.
  bool receive(std::string& out, int timeout_ms) {
    pollfd pfd{fd_, POLLIN, 0};
    if (::poll(&pfd, 1, timeout_ms) <= 0) return false;
    char buffer[2048];
    const ssize_t n = ::recv(fd_, buffer, sizeof buffer, MSG_DONTWAIT);
    if (n < 0) return false;
    out.assign(buffer, static_cast<std::size_t>(n));
    return true;
  }

 private:
  int fd_ = -1;
};

// What is injected. Each kind is either a fault (long enough to reach its watchdog's threshold:
// the fault must be raised) or a disturbance (shorter, or harmless by nature: nothing may be
// raised).
enum class Inject : int {
  ft_silent,
  ft_critical,
  ft_saturated,
  imu_silent,
  robot_timeouts,
  robot_malformed,
  ipoc_gap,
  delay_grew,
  contact_over_limit,
  duplicate_ipoc,
  reordered_ipoc,
  count
};
constexpr const char* kInjectNames[] = {"ft_silent",      "ft_critical",    "ft_saturated",
                                        "imu_silent",     "robot_timeouts", "robot_malformed",
                                        "ipoc_gap",       "delay_grew",     "contact_over_limit",
                                        "duplicate_ipoc", "reordered_ipoc"};
static_assert(std::size(kInjectNames) == static_cast<std::size_t>(Inject::count));
const char* inject_name(Inject k) { return kInjectNames[static_cast<int>(k)]; }

// Malformed datagrams: a real message spoilt four ways, each with the parse status it must get.
struct Spoil {
  const char* name;
  proto::rsi::ParseStatus status;
};
constexpr Spoil kSpoils[] = {{"truncated", proto::rsi::ParseStatus::truncated},
                             {"wrong_root", proto::rsi::ParseStatus::wrong_root},
                             {"bad_number", proto::rsi::ParseStatus::bad_number},
                             {"missing_element", proto::rsi::ParseStatus::missing_element}};

enum class Phase : std::uint8_t { idle, zero_g, fault };

struct Episode {
  Inject kind = Inject::count;
  loop::Fault expect = loop::Fault::none;  ///< none: a disturbance
  int periods_left = 0;
  std::uint64_t start_period = 0;
  bool raised = false;
  Wrench contact = Wrench::Zero();  ///< contact_over_limit
  bool reorder_second = false;      ///< reordered_ipoc: the period in which both arrive
};

struct Push {
  std::uint64_t start = 0, end = 0;  ///< periods [start, end)
  Wrench peak = Wrench::Zero();      ///< sensor frame, torque about the sensor origin
  bool clean = true;                 ///< all of it in zero_g with nothing injected
  bool moved = false;                ///< an RKorr ≠ 0 (or the workspace limit) seen
};

struct Options {
  double simulated_s = 3600.0;
  int cycle_ms = 12;
  std::uint64_t seed = 1;
  double warmup_s = 60.0;
  std::string dir;  ///< record folder ("": a temporary one, removed unless --keep)
  bool keep = false;
  std::string report;       ///< JSON file ("" none)
  std::string summary_out;  ///< the runtime's summary JSON, as zerog-rt --summary-out writes it
  int receive_timeout_ms = 150;
  double heap_bound_mib = 1.0;
  double rss_bound_mib = 4.0;
};

class Soak {
 public:
  explicit Soak(Options o) : opt_(std::move(o)), rng_(opt_.seed) {}

  int run();

 private:
  double uniform(double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng_); }
  int uniform_int(int a, int b) { return std::uniform_int_distribution<int>(a, b)(rng_); }
  bool chance(double p) { return uniform(0.0, 1.0) < p; }
  Eigen::Vector3d direction() {
    std::normal_distribution<double> n(0.0, 1.0);
    Eigen::Vector3d d(n(rng_), n(rng_), n(rng_));
    return d.norm() > 1e-9 ? d.normalized() : Eigen::Vector3d::UnitX();
  }
  double t(std::uint64_t period) const { return static_cast<double>(period) * period_s_; }
  std::uint64_t periods(double seconds) const {
    return static_cast<std::uint64_t>(std::llround(seconds / period_s_));
  }

  void fail(const std::string& what) {
    ++failure_count_;
    if (failures_.size() < 40) failures_.push_back(what);
  }
  void check(bool ok, const std::string& what) {
    if (!ok) fail(what);
  }
  template <typename A, typename B>
  void check_eq(const A& a, const B& b, const std::string& what) {
    if (!(a == b)) {
      std::ostringstream s;
      s << what << ": " << a << " != " << b;
      fail(s.str());
    }
  }

  std::string set_up();
  void plan(std::uint64_t p);
  void start_episode(std::uint64_t p, Inject kind, bool as_fault);
  void run_period(std::uint64_t p);
  void feed_samples(const Wrench& contact, int ft_mode, bool imu_silent);
  void send_message(std::uint64_t ipoc);
  void send_malformed(std::uint64_t ipoc);
  void cycle(std::uint64_t p, bool expect_reply, std::uint64_t expect_ipoc, bool stale);
  void after_transitions(std::uint64_t p);
  void pace();
  void finish_checks(const json& summary);
  void check_files();
  json report(const json& summary) const;

  Options opt_;
  std::mt19937_64 rng_;
  double period_s_ = 0.012;
  std::uint64_t ipoc_step_ = 12;
  std::uint64_t total_periods_ = 0;

  fs::path temp_root_;  ///< made by this program (removed at the end unless --keep)
  fs::path dir_;
  formats::Rig rig_;
  loop::CycleConfig config_;
  std::unique_ptr<rtio::RsiEndpoint> endpoint_;
  std::unique_ptr<rt::Runtime> runtime_;
  std::unique_ptr<loop::test::StaticRobot> robot_;
  RobotSide robot_side_;
  std::array<char, 1024> tx_{};
  std::string rx_;
  proto::rsi::RobotMessage message_;

  // Sensor sample pacing and noise.
  double ft_per_period_ = 6.0, imu_per_period_ = 24.0;
  double ft_carry_ = 0.0, imu_carry_ = 0.0;
  std::normal_distribution<double> noise_{0.0, 1.0};

  // The script.
  Phase phase_ = Phase::idle;
  std::uint64_t phase_start_ = 0;
  std::uint64_t enable_at_ = 0, stop_at_ = 0, reset_at_ = 0;
  std::uint64_t fault_at_ = UINT64_MAX, disturbance_at_ = 0;
  std::uint64_t refused_at_ = UINT64_MAX, propose_at_ = 0;
  bool propose_in_zero_g_pending_ = true;
  std::optional<Episode> episode_;
  std::uint64_t quiet_until_ = 0;    ///< no episode or command before this period
  std::optional<Episode> awaiting_;  ///< an ended fault episode whose fault may still come
  std::uint64_t awaiting_until_ = 0;
  std::optional<Push> push_;
  std::uint64_t next_push_at_ = 0;
  std::optional<loop::Command> command_;  ///< requested for the next robot message
  bool command_refusal_expected_ = false;
  std::optional<loop::Tunables> proposed_;
  bool proposal_expect_accept_ = false;
  std::uint64_t no_faults_after_ = 0;

  // What this program did (the oracle).
  std::uint64_t cycle_calls_ = 0, messages_sent_ = 0, datagrams_sent_ = 0;
  std::uint64_t stale_sent_ = 0, timeouts_caused_ = 0, malformed_sent_ = 0;
  std::array<std::uint64_t, std::size(kSpoils)> malformed_by_spoil_{};
  std::uint64_t gap_events_ = 0, datagrams_lost_ = 0;
  bool have_new_ipoc_ = false;
  std::uint64_t last_new_ipoc_ = 0;
  std::uint64_t replies_ = 0;
  std::uint64_t ft_fed_ = 0, imu_fed_ = 0, fed_since_cycle_ = 0, discarded_expected_ = 0;
  struct Seen {  ///< a transition as this program saw it
    std::uint64_t cycle = 0;
    loop::State from = loop::State::idle, to = loop::State::idle;
    std::string cause;  ///< command or fault name
  };
  std::vector<Seen> seen_;
  modbus::SupervisorSnapshot snap_;  ///< after the last cycle this program caused
  loop::State state_seen_ = loop::State::idle;
  std::uint64_t lost_expected_ = 0, unplanned_timeouts_ = 0, stop_timeouts_ = 0;
  Eigen::Vector3d displacement_m_ = Eigen::Vector3d::Zero();  ///< Σ RKorr this session, base
  std::optional<loop::Tunables> last_accepted_;
  bool box_dumped_ = false;
  std::chrono::steady_clock::time_point box_seen_;
  std::uint64_t unplanned_at_ = 0;  ///< period of the last unplanned timeout
  std::uint64_t faults_from_unplanned_ = 0;
  std::uint64_t box_dumped_at_ = 0;
  std::uint64_t refused_expected_ = 0;
  std::uint64_t sessions_ = 0, pushes_ = 0, pushes_clean_ = 0, pushes_moved_ = 0;
  std::uint64_t proposals_accepted_ = 0, proposals_refused_ = 0;
  std::map<std::string, std::uint64_t> faults_injected_, faults_raised_, disturbances_;
  std::vector<std::pair<std::uint64_t, std::string>> fault_log_;  ///< (fault cycle, name)
  /// The faults whose cycles got a black box, and those raised while the box still held the
  /// fault before (not yet dumped and released: the cycle counts them, black_boxes_lost). Only
  /// an unplanned robot_late can come that soon: the plan waits for the box to be free.
  std::vector<std::pair<std::uint64_t, std::string>> boxed_log_, lost_log_;
  std::uint64_t boxes_lost_seen_ = 0;
  std::uint64_t lost_from_unplanned_ = 0;  ///< of lost_log_, the unplanned robot_late faults
  std::uint64_t max_raise_latency_ = 0;
  std::uint64_t pace_waits_ = 0;
  double pace_wait_s_ = 0.0;
  double wall_s_ = 0.0;
  std::optional<Memory> mem_warm_;
  Memory mem_start_, mem_end_, mem_after_stop_;
  std::uint64_t cycles_rows_ = 0, log_rows_ = 0;
  std::vector<std::string> failures_;
  std::uint64_t failure_count_ = 0;
};

std::string Soak::set_up() {
  if (opt_.cycle_ms < 1 || opt_.cycle_ms > 100) return "--cycle-ms: 1 … 100 (RSI: 4 or 12)";
  if (!(opt_.simulated_s >= 120.0)) return "--simulated-s: at least 120 s (warm-up and tail)";
  if (!(opt_.warmup_s >= 0.0 && opt_.warmup_s < opt_.simulated_s - 30.0))
    return "--warmup-s: from 0 to 30 s before the end";
  period_s_ = opt_.cycle_ms * 1e-3;
  ipoc_step_ = static_cast<std::uint64_t>(opt_.cycle_ms);
  total_periods_ = periods(opt_.simulated_s);
  no_faults_after_ = total_periods_ - periods(15.0);
  ft_per_period_ = 500.0 * period_s_;
  imu_per_period_ = 2000.0 * period_s_;

  if (opt_.dir.empty()) {
    std::string pattern = (fs::temp_directory_path() / "zerog-soak-XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr)
      return "cannot create a temporary folder in " + fs::temp_directory_path().string();
    temp_root_ = pattern;
    dir_ = temp_root_ / "rec";
  } else {
    dir_ = opt_.dir;
  }
  rig_ = rt::test::test_rig();
  rig_.sample_period_s = period_s_;
  config_ = loop::test::test_cycle_config();
  config_.period_s = period_s_;
  config_.limits.linear_damping_per_s = 0.5;  // the part settles between pushes
  config_.limits.angular_damping_per_s = 0.5;
  const infer::DeployedModel model = rt::test::payload_model(rig_);
  robot_ = std::make_unique<loop::test::StaticRobot>(model);
  message_ = robot_->message;

  rtio::RsiEndpointConfig ec;
  ec.bind_port = 0;
  // A lost cycle costs this much wall time. Longer than this program ever takes between two
  // datagrams (else the cycle thread times out unasked: counted as unplanned_timeouts).
  ec.receive_timeout = std::chrono::milliseconds(opt_.receive_timeout_ms);
  endpoint_ = std::make_unique<rtio::RsiEndpoint>(ec);
  if (endpoint_->start() != rtio::RobotStartStatus::ok) return "RSI endpoint: cannot bind";
  if (std::string e = robot_side_.open(endpoint_->local_port()); !e.empty()) return e;

  rt::RuntimeOptions ro;
  ro.recorder.dir = dir_;
  ro.recorder.rig = rig_;
  runtime_ = std::make_unique<rt::Runtime>(ro, rt::RuntimeDevices{endpoint_.get()});
  if (const Status st = runtime_->configure(config_, model); !st.ok())
    return "configure: " + st.text();
  std::vector<Status> warnings;
  if (const Status st = runtime_->start(warnings); !st.ok()) return "start: " + st.text();
  return {};
}

// --- the script -------------------------------------------------------------------------------

void Soak::start_episode(std::uint64_t p, Inject kind, bool as_fault) {
  Episode e;
  e.kind = kind;
  e.start_period = p;
  const loop::WatchdogConfig& w = config_.watchdog;
  switch (kind) {
    case Inject::ft_silent:
    case Inject::ft_critical:
    case Inject::ft_saturated:
      e.periods_left =
          as_fault ? w.ft_fault_cycles + uniform_int(0, 5) : uniform_int(1, w.ft_fault_cycles - 2);
      e.expect = kind == Inject::ft_silent     ? loop::Fault::ft_stale
                 : kind == Inject::ft_critical ? loop::Fault::ft_critical
                                               : loop::Fault::ft_saturated;
      break;
    case Inject::imu_silent:
      e.periods_left = as_fault ? w.imu_fault_cycles + uniform_int(0, 5)
                                : uniform_int(1, w.imu_fault_cycles - 2);
      e.expect = loop::Fault::imu_stale;
      break;
    case Inject::robot_timeouts:
    case Inject::robot_malformed:
    case Inject::ipoc_gap:
      e.periods_left = as_fault ? w.robot_fault_cycles + uniform_int(0, 5)
                                : uniform_int(1, w.robot_fault_cycles - 1);
      e.expect = loop::Fault::robot_late;
      break;
    case Inject::delay_grew:
      e.periods_left = as_fault ? w.robot_late_cycles + uniform_int(0, 2)
                                : uniform_int(1, w.robot_late_cycles - 1);
      e.expect = loop::Fault::robot_late;
      break;
    case Inject::contact_over_limit: {
      e.periods_left = 6;
      e.expect = loop::Fault::contact_over_limit;
      const Eigen::Vector3d F =
          direction() * uniform(1.15, 2.5) * config_.limits.max_contact_force_N;
      e.contact << F, config_.p_sensor_com_m.cross(F);
      if (push_) push_->clean = false;
      push_.reset();
      break;
    }
    case Inject::duplicate_ipoc:
      e.periods_left = 1;
      break;
    case Inject::reordered_ipoc:
      e.periods_left = 2;
      break;
    case Inject::count:
      break;
  }
  if (!as_fault) e.expect = loop::Fault::none;
  if (as_fault) {
    ++faults_injected_[std::string(inject_name(kind)) + "->" + loop::fault_name(e.expect)];
  } else {
    ++disturbances_[inject_name(kind)];
  }
  episode_ = e;
}

void Soak::plan(std::uint64_t p) {
  if (episode_ || p < quiet_until_ || awaiting_) return;
  const std::uint64_t faults = boxed_log_.size();
  // The black box of the last fault must have been dumped and released first (one box).
  // The cycle releases the box in its first cycle out of fault after the dump: wait for the
  // dump's file, then for a few cycles out of fault.
  if (faults > 0 && !box_dumped_) {
    const fs::path box = dir_ / ("blackbox-" + std::to_string(boxed_log_.back().first) + ".csv");
    if (fs::exists(box)) {
      box_dumped_ = true;
      box_dumped_at_ = p;
      box_seen_ = std::chrono::steady_clock::now();
    }
  }
  // The recorder hands the box back right after writing it (µs, unless the machine is loaded:
  // 50 ms of wall time), and the cycle thread releases it in its next cycle out of fault.
  // Not observable from outside; a fault before would find the box still frozen (no dump).
  const bool box_free =
      faults == 0 ||
      (box_dumped_ && phase_ != Phase::fault && p >= box_dumped_at_ + 3 && p >= phase_start_ + 3 &&
       std::chrono::steady_clock::now() - box_seen_ > std::chrono::milliseconds(50));
  const bool late = p >= no_faults_after_;

  switch (phase_) {
    case Phase::idle: {
      if (p >= fault_at_ && box_free && !late) {
        static constexpr Inject kSensor[] = {Inject::ft_silent, Inject::ft_critical,
                                             Inject::ft_saturated, Inject::imu_silent};
        fault_at_ = UINT64_MAX;
        start_episode(p, kSensor[uniform_int(0, 3)], true);
        return;
      }
      if (p >= propose_at_ && !proposed_) {
        loop::Tunables tun = last_accepted_ ? *last_accepted_ : runtime_->tunables();
        tun.body.mass_kg = std::round(uniform(80.0, 120.0));
        tun.limits.linear_damping_per_s = std::round(uniform(0.4, 0.8) * 100.0) / 100.0;
        check(runtime_->propose(tun), "propose() refused while nothing pending");
        proposed_ = tun;
        proposal_expect_accept_ = true;
        propose_at_ = p + periods(opt_.simulated_s / 6.0);
        return;
      }
      if (p >= refused_at_) {
        refused_at_ = UINT64_MAX;
        command_ = loop::Command::stop;  // not allowed in idle: refused, nothing changes
        command_refusal_expected_ = true;
        return;
      }
      if (p >= enable_at_ && !late) {
        command_ = loop::Command::enable_zero_g;
        command_refusal_expected_ = false;
        return;
      }
      break;
    }
    case Phase::zero_g: {
      if (p >= fault_at_ && box_free && !late) {
        fault_at_ = UINT64_MAX;
        start_episode(p, static_cast<Inject>(uniform_int(0, 8)), true);
        return;
      }
      if (propose_in_zero_g_pending_ && sessions_ >= 2 && !proposed_) {
        propose_in_zero_g_pending_ = false;
        loop::Tunables tun = last_accepted_ ? *last_accepted_ : runtime_->tunables();
        tun.body.mass_kg = 60.0;
        check(runtime_->propose(tun), "propose() refused while nothing pending");
        proposed_ = tun;
        proposal_expect_accept_ = false;
        return;
      }
      if (p >= stop_at_ || late) {
        if (push_) push_->clean = false;
        command_ = loop::Command::stop;
        command_refusal_expected_ = false;
        return;
      }
      break;
    }
    case Phase::fault:
      if (p >= reset_at_) {
        command_ = loop::Command::reset_fault;
        command_refusal_expected_ = false;
        return;
      }
      return;  // nothing else while faulted
  }
  if (late) return;  // the run ends quietly: every sample fed is used by the last cycles
  if (p >= disturbance_at_) {
    static constexpr Inject kHarmless[] = {
        Inject::ft_silent,      Inject::ft_critical,     Inject::ft_saturated, Inject::imu_silent,
        Inject::robot_timeouts, Inject::robot_malformed, Inject::ipoc_gap,     Inject::delay_grew,
        Inject::duplicate_ipoc, Inject::reordered_ipoc};
    disturbance_at_ = p + periods(std::exponential_distribution<double>(1.0 / 8.0)(rng_)) + 1;
    start_episode(p, kHarmless[uniform_int(0, 9)], false);
  }
}

// --- one robot period -------------------------------------------------------------------------

void Soak::feed_samples(const Wrench& contact, int ft_mode, bool imu_silent) {
  // ft_mode: 0 valid, 1 none, 2 critical, 3 saturated.
  ft_carry_ += ft_per_period_;
  const int n_ft = static_cast<int>(ft_carry_);
  ft_carry_ -= n_ft;
  imu_carry_ += imu_per_period_;
  const int n_imu = static_cast<int>(imu_carry_);
  imu_carry_ -= n_imu;
  if (ft_mode != 1) {
    for (int i = 0; i < n_ft; ++i) {
      rtio::FtSample s = robot_->ft(contact);
      for (int k = 0; k < 6; ++k) s.wrench_si[k] += (k < 3 ? 0.3 : 0.02) * noise_(rng_);
      if (ft_mode == 2) {
        s.valid = false;
        s.status = rtio::FtSampleStatus::critical;
      } else if (ft_mode == 3) {
        s.valid = false;
        s.status = rtio::FtSampleStatus::saturated;
        s.saturated_mask = 0x01;
      }
      check(runtime_->ft_ring().try_push(s), "F/T ring full");
      ++ft_fed_;
      ++fed_since_cycle_;
    }
  }
  if (!imu_silent) {
    for (int i = 0; i < n_imu; ++i) {
      rtio::ImuSample s = robot_->imu_sample;
      for (int k = 0; k < 3; ++k) {
        s.accel_m_s2[k] += 0.01 * noise_(rng_);
        s.rate_rad_s[k] += 1e-4 * noise_(rng_);
      }
      check(runtime_->imu_ring().try_push(s), "IMU ring full");
      ++imu_fed_;
      ++fed_since_cycle_;
    }
  }
}

void Soak::send_message(std::uint64_t ipoc) {
  message_.ipoc = ipoc;
  const proto::rsi::FormatResult f = proto::rsi::format_robot_message(message_, tx_);
  check(f.status == proto::rsi::FormatStatus::ok, "format_robot_message failed");
  check(robot_side_.send(std::string_view(tx_.data(), f.size)), "robot send failed");
  ++datagrams_sent_;
}

void Soak::send_malformed(std::uint64_t ipoc) {
  message_.ipoc = ipoc;
  const proto::rsi::FormatResult f = proto::rsi::format_robot_message(message_, tx_);
  std::string d(tx_.data(), f.size);
  const int kind = uniform_int(0, static_cast<int>(std::size(kSpoils)) - 1);
  auto replace = [&d](const std::string& from, const std::string& to) {
    const std::size_t at = d.find(from);
    if (at != std::string::npos) d.replace(at, from.size(), to);
  };
  switch (kind) {
    case 0:
      d.resize(d.size() / 2);
      break;
    case 1:
      replace("<Rob", "<Bob");
      replace("</Rob>", "</Bob>");
      break;
    case 2:
      replace("<IPOC>", "<IPOC>x");
      break;
    default: {
      const std::size_t a = d.find("<AIPos");
      const std::size_t b = d.find("/>", a);
      if (a != std::string::npos && b != std::string::npos) d.erase(a, b + 2 - a);
      break;
    }
  }
  proto::rsi::RobotMessage ignored;
  const proto::rsi::ParseResult r = proto::rsi::parse_robot_message(d, ignored);
  check(r.status == kSpoils[kind].status, std::string("spoilt datagram '") + kSpoils[kind].name +
                                              "' parses as status " +
                                              std::to_string(static_cast<int>(r.status)));
  ++malformed_by_spoil_[static_cast<std::size_t>(kind)];
  ++malformed_sent_;
  check(robot_side_.send(d), "robot send failed");
  ++datagrams_sent_;
}

template <typename Done>
bool wait_until(Done done, double timeout_s) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  for (int i = 0; !done(); ++i) {
    if (std::chrono::steady_clock::now() > until) return false;
    if (i < 100) {
      std::this_thread::yield();
    } else {
      std::this_thread::sleep_for(std::chrono::microseconds(20));
    }
  }
  return true;
}

void Soak::cycle(std::uint64_t p, bool expect_reply, std::uint64_t expect_ipoc, bool stale) {
  // zerog-rt's cycle thread handles what was sent (or times out); wait for its snapshot.
  const std::uint64_t refused_before = snap_.commands_refused;
  ++cycle_calls_;
  bool got = false;
  if (expect_reply) {
    got = robot_side_.receive(rx_, 2000);
    check(got, "no reply to IPOC " + std::to_string(expect_ipoc));
    check(wait_until([&] { return runtime_->snapshot().cycle >= messages_sent_; }, 5.0),
          "the cycle thread did not publish cycle " + std::to_string(messages_sent_));
  } else {
    ++lost_expected_;
    discarded_expected_ += fed_since_cycle_;
    check(wait_until([&] { return runtime_->snapshot().robot_lost >= lost_expected_; }, 5.0),
          "the cycle thread did not report lost cycle " + std::to_string(lost_expected_));
    check(!robot_side_.receive(rx_, 0), "a reply to a lost cycle");
  }
  fed_since_cycle_ = 0;
  snap_ = runtime_->snapshot();
  if (snap_.robot_lost > lost_expected_) {
    // The cycle thread timed out while this program was busy (descheduled longer than the
    // receive timeout): not injected, counted and reported.
    unplanned_timeouts_ += snap_.robot_lost - lost_expected_;
    unplanned_at_ = p;
    lost_expected_ = snap_.robot_lost;
  }
  if (got) {
    ++replies_;
    proto::rsi::Reply reply;
    const proto::rsi::ParseResult pr = proto::rsi::parse_reply(rx_, reply);
    check(pr.ok() && reply.has_rkorr && !reply.has_akorr,
          "reply does not parse as an RKorr reply: " + rx_);
    check_eq(reply.ipoc, expect_ipoc, "reply IPOC");
    const proto::rsi::Correction& c = reply.rkorr;
    const bool zero =
        c.x_mm == 0 && c.y_mm == 0 && c.z_mm == 0 && c.a_deg == 0 && c.b_deg == 0 && c.c_deg == 0;
    if (stale) check(zero, "a stale IPOC got a non-zero correction");
    if (snap_.state != loop::State::zero_g)
      check(zero, "cycle " + std::to_string(snap_.cycle) + ": a non-zero correction in state " +
                      loop::state_name(snap_.state));
    if (push_ && !zero) push_->moved = true;
    if (phase_ == Phase::zero_g) displacement_m_ += 1e-3 * Eigen::Vector3d(c.x_mm, c.y_mm, c.z_mm);
  }
  // A command is applied by the next step() that is not stale.
  const bool command_due = command_ && got && !stale;
  if (command_due && command_refusal_expected_) {
    check(snap_.state == state_seen_, "a refused command changed the state");
    check(
        (snap_.flags & loop::kCommandRefused) != 0 && snap_.commands_refused == refused_before + 1,
        "the refused command was not flagged and counted");
    ++refused_expected_;
    command_.reset();
  }
  after_transitions(p);  // an accepted command's transition consumes command_
  if (command_due && command_) {
    fail("cycle " + std::to_string(snap_.cycle) + ": command " + loop::command_name(*command_) +
         " was not applied");
    command_.reset();
  }
  if (proposed_ && got && !stale) {
    const loop::ProposalStatus st = runtime_->proposal_status();
    if (proposal_expect_accept_) {
      check(st == loop::ProposalStatus::accepted, "an idle proposal was not accepted");
      last_accepted_ = proposed_;
      ++proposals_accepted_;
    } else {
      check(st == loop::ProposalStatus::refused_state, "a proposal during zero_g was not refused");
      ++proposals_refused_;
    }
    proposed_.reset();
  }
  pace();
}

void Soak::after_transitions(std::uint64_t p) {
  // The snapshot after every cycle: each change of state is one transition (the script never
  // has a command and an injection in the same cycle).
  if (snap_.state == state_seen_) return;
  Seen tr;
  tr.cycle = snap_.cycle;
  tr.from = state_seen_;
  tr.to = snap_.state;
  state_seen_ = snap_.state;
  const std::string where = "cycle " + std::to_string(tr.cycle) + ": ";
  if (tr.to == loop::State::fault) {
    tr.cause = loop::fault_name(snap_.fault);
    ++faults_raised_[tr.cause];
    fault_log_.emplace_back(tr.cycle, tr.cause);
    const std::uint64_t lost = runtime_->cycle().counters().black_boxes_lost;
    const bool box_lost = lost > boxes_lost_seen_;
    boxes_lost_seen_ = lost;
    if (box_lost) {
      lost_log_.emplace_back(tr.cycle, tr.cause);
    } else {
      boxed_log_.emplace_back(tr.cycle, tr.cause);
      box_dumped_ = false;
    }
    Episode* e = episode_ ? &*episode_ : (awaiting_ ? &*awaiting_ : nullptr);
    if ((e == nullptr || e->expect == loop::Fault::none || e->raised) &&
        snap_.fault == loop::Fault::robot_late && unplanned_timeouts_ > 0 &&
        p <= unplanned_at_ + 3) {
      // Robot cycles really were lost (this program was descheduled longer than the receive
      // timeout, three times in a row): the right fault, not an injected one. Reported.
      ++faults_from_unplanned_;
      if (box_lost) ++lost_from_unplanned_;
    } else if (e == nullptr || e->expect == loop::Fault::none || e->raised) {
      fail(where + "fault " + tr.cause + " raised without an injected fault" +
           (e ? std::string(" (during ") + inject_name(e->kind) + ")" : std::string()));
    } else {
      check(snap_.fault == e->expect, where + "injected " + inject_name(e->kind) + " raised " +
                                          tr.cause + ", not " + loop::fault_name(e->expect));
      e->raised = true;
      max_raise_latency_ = std::max(max_raise_latency_, p - e->start_period);
      if (awaiting_ && e == &*awaiting_) awaiting_.reset();
    }
    if (push_) push_->clean = false;
    phase_ = Phase::fault;
    reset_at_ = p + periods(uniform(0.5, 3.0));
    command_.reset();
  } else {
    const loop::Command expected_command =
        tr.to == loop::State::zero_g    ? loop::Command::enable_zero_g
        : tr.from == loop::State::fault ? loop::Command::reset_fault
                                        : loop::Command::stop;
    tr.cause = loop::command_name(expected_command);
    check(command_ && *command_ == expected_command && !command_refusal_expected_,
          where + loop::state_name(tr.from) + " -> " + loop::state_name(tr.to) +
              " without the command " + tr.cause);
    command_.reset();
    if (tr.to == loop::State::zero_g) {
      ++sessions_;
      phase_ = Phase::zero_g;
      displacement_m_.setZero();
      stop_at_ = p + periods(uniform(10.0, 60.0));
      fault_at_ = chance(0.75) ? p + periods(uniform(1.5, t(stop_at_ - p) - 0.5)) : UINT64_MAX;
      next_push_at_ = p + periods(uniform(0.3, 3.0));
    } else {
      phase_ = Phase::idle;
      enable_at_ = p + periods(uniform(2.0, 8.0));
      fault_at_ = chance(0.15) ? p + periods(uniform(0.3, 1.8)) : UINT64_MAX;
      if (chance(0.2)) refused_at_ = p + periods(0.2);
    }
  }
  phase_start_ = p;
  seen_.push_back(tr);
}

void Soak::pace() {
  // The recorder must keep up (a full record ring drops records): wait while it is over half
  // full. The cycle thread never waits; this program can, as it is also the robot.
  rt::Runtime::RecordRing& ring = runtime_->record_ring();
  if (ring.size_approx() <= rt::Runtime::RecordRing::capacity() / 2) return;
  const auto t0 = std::chrono::steady_clock::now();
  ++pace_waits_;
  while (ring.size_approx() > rt::Runtime::RecordRing::capacity() / 8)
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  pace_wait_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void Soak::run_period(std::uint64_t p) {
  if (!mem_warm_ && t(p) >= opt_.warmup_s) mem_warm_ = measure_memory();
  plan(p);

  // Pushes (zero_g only, one at a time).
  if (phase_ == Phase::zero_g && !push_ && p >= next_push_at_ && !episode_ && !command_) {
    Push push;
    push.start = p;
    push.end = p + std::max<std::uint64_t>(periods(uniform(0.1, 1.2)), 6);
    // Chosen in the base frame: back towards where the session started once the part has
    // drifted (the workspace limit would stop a push outwards: nothing to see in the replies).
    Eigen::Vector3d F_base = direction();
    if (displacement_m_.norm() > 0.15)
      F_base = (direction() * 0.5 - displacement_m_.normalized()).normalized();
    F_base *= uniform(10.0, 150.0);
    const Eigen::Vector3d F = robot_->R.transpose() * F_base;  // sensor frame
    Eigen::Vector3d arm = config_.p_sensor_com_m;
    if (chance(0.3)) {  // off-centre: a torque about the centre of mass too
      Eigen::Vector3d off = direction().cross(F.normalized());
      if (off.norm() > 1e-6) arm += off.normalized() * uniform(0.05, 0.3);
    }
    push.peak << F, arm.cross(F);
    push_ = push;
    ++pushes_;
  }
  Wrench contact = Wrench::Zero();
  if (push_ && p < push_->end) {
    const double x =
        static_cast<double>(p - push_->start) / static_cast<double>(push_->end - push_->start);
    contact = push_->peak * std::sin(M_PI * x);
  }
  if (push_ && p >= push_->end + 10) {  // judged 10 cycles after its end
    if (push_->clean) {
      ++pushes_clean_;
      if (push_->moved) ++pushes_moved_;
      check(push_->moved, "push at robot period " + std::to_string(push_->start) +
                              " did not move the part (no RKorr, no workspace limit)");
    }
    push_.reset();
    next_push_at_ = p + periods(uniform(0.5, 6.0));
  }

  int ft_mode = 0;
  bool imu_silent = false;
  enum { normal, timeout, malformed, skip, duplicate, reorder } ev = normal;
  if (episode_) {
    Episode& e = *episode_;
    if (push_) push_->clean = false;
    switch (e.kind) {
      case Inject::ft_silent:
        ft_mode = 1;
        break;
      case Inject::ft_critical:
        ft_mode = 2;
        break;
      case Inject::ft_saturated:
        ft_mode = 3;
        break;
      case Inject::imu_silent:
        imu_silent = true;
        break;
      case Inject::robot_timeouts:
        ev = timeout;
        break;
      case Inject::robot_malformed:
        ev = malformed;
        break;
      case Inject::ipoc_gap:
        ev = skip;
        break;
      case Inject::delay_grew:
        message_.delay += static_cast<std::uint64_t>(uniform_int(1, 3));
        break;
      case Inject::contact_over_limit:
        contact = e.contact;
        break;
      case Inject::duplicate_ipoc:
        ev = duplicate;
        break;
      case Inject::reordered_ipoc:
        ev = e.reorder_second ? reorder : timeout;
        e.reorder_second = true;
        break;
      case Inject::count:
        break;
    }
  }
  feed_samples(contact, ft_mode, imu_silent);

  const std::uint64_t ipoc = 1'000'000 + p * ipoc_step_;
  auto new_message = [&] {
    if (have_new_ipoc_) {
      const std::uint64_t lost = (ipoc - last_new_ipoc_) / ipoc_step_ - 1;
      if (lost > 0) {
        ++gap_events_;
        datagrams_lost_ += lost;
      }
    }
    have_new_ipoc_ = true;
    last_new_ipoc_ = ipoc;
    send_message(ipoc);
    ++messages_sent_;
    cycle(p, true, ipoc, false);
  };
  switch (ev) {
    case normal:
      if (command_) check(runtime_->request(*command_), "request() refused: one pending");
      new_message();
      break;
    case timeout:
      ++timeouts_caused_;
      cycle(p, false, 0, false);
      break;
    case malformed:
      send_malformed(ipoc);
      cycle(p, false, 0, false);
      break;
    case skip:
      break;
    case duplicate:
      new_message();
      send_message(ipoc);
      ++messages_sent_;
      ++stale_sent_;
      cycle(p, true, ipoc, true);
      break;
    case reorder:
      new_message();
      // The previous period's datagram, held up in the network, arrives after this one.
      send_message(ipoc - ipoc_step_);
      ++messages_sent_;
      ++stale_sent_;
      cycle(p, true, ipoc - ipoc_step_, true);
      break;
  }

  if (episode_ && --episode_->periods_left == 0) {
    if (episode_->expect != loop::Fault::none && !episode_->raised) {
      awaiting_ = *episode_;  // an IPOC gap raises at the next message, a contact D rows late
      awaiting_until_ = p + 8;
    }
    episode_.reset();
    quiet_until_ = p + 8;
  }
  if (awaiting_ && p >= awaiting_until_) {
    fail("cycle " + std::to_string(runtime_->cycle().last().cycle) + ": injected " +
         inject_name(awaiting_->kind) + " did not raise " + loop::fault_name(awaiting_->expect));
    awaiting_.reset();
  }
}

// --- after the run ----------------------------------------------------------------------------

void Soak::check_files() {
  // cycles.csv: a header, then every record in order (cycle 1, 2, …): nothing dropped.
  {
    std::ifstream in(dir_ / "cycles.csv");
    check(in.good(), "cannot read cycles.csv");
    std::string line;
    std::getline(in, line);
    check(line.rfind("cycle,ipoc,", 0) == 0, "cycles.csv header: " + line.substr(0, 40));
    std::uint64_t expect = 1;
    bool in_order = true;
    while (std::getline(in, line)) {
      if (line.empty()) continue;
      ++cycles_rows_;
      const std::uint64_t c = std::strtoull(line.c_str(), nullptr, 10);
      if (c != expect && in_order) {
        fail("cycles.csv row " + std::to_string(cycles_rows_) + " has cycle " + std::to_string(c) +
             ", expected " + std::to_string(expect));
        in_order = false;
      }
      ++expect;
    }
  }
  // run.csv: the log format; t_s strictly increasing.
  {
    std::ifstream in(dir_ / "run.csv");
    check(in.good(), "cannot read run.csv");
    std::string line;
    std::getline(in, line);
    check(line == "# zerog-log 1", "run.csv line 1: " + line);
    std::size_t t_column = std::string::npos;
    double last_t = -1.0;
    bool increasing = true;
    while (std::getline(in, line)) {
      if (line.empty() || line[0] == '#') continue;
      if (t_column == std::string::npos) {  // the header
        std::size_t column = 0, start = 0;
        while (true) {
          const std::size_t comma = line.find(',', start);
          if (line.substr(start, comma - start) == "t_s") t_column = column;
          if (comma == std::string::npos) break;
          start = comma + 1;
          ++column;
        }
        check(t_column != std::string::npos, "run.csv has no t_s column");
        if (t_column == std::string::npos) return;
        continue;
      }
      ++log_rows_;
      std::size_t start = 0;
      for (std::size_t c = 0; c < t_column; ++c) start = line.find(',', start) + 1;
      const double t_s = std::strtod(line.c_str() + start, nullptr);
      if (!(t_s > last_t) && increasing) {
        fail("run.csv row " + std::to_string(log_rows_) + ": t_s " + std::to_string(t_s) +
             " not after " + std::to_string(last_t));
        increasing = false;
      }
      last_t = t_s;
    }
  }
  check(fs::exists(dir_ / "run.rig.toml"), "run.rig.toml missing");
  for (const auto& entry : fs::directory_iterator(dir_))
    check(entry.path().extension() != ".partial", "left behind: " + entry.path().string());

  // One black box per fault, named for its fault cycle, naming its fault, 256 records.
  // A fault raised while the box still held the one before has none, and is counted: only an
  // unplanned robot_late may be one of those (lost_log_).
  const std::vector<fs::path>& boxes = runtime_->black_box_paths();
  check_eq(boxes.size(), boxed_log_.size(), "black boxes dumped vs faults raised with a free box");
  check_eq(lost_log_.size(), lost_from_unplanned_,
           "faults without a box (box still held) vs those from unplanned robot timeouts");
  check_eq(runtime_->cycle().counters().black_boxes_lost, lost_log_.size(),
           "black_boxes_lost vs faults seen without a box");
  for (std::size_t i = 0; i < boxed_log_.size(); ++i) {
    const auto& [cycle, name] = boxed_log_[i];
    const fs::path box = dir_ / ("blackbox-" + std::to_string(cycle) + ".csv");
    if (!fs::exists(box)) {
      fail("no black box for fault " + name + " at cycle " + std::to_string(cycle) +
           (i > 0 ? " (the fault before: cycle " + std::to_string(boxed_log_[i - 1].first) + ")"
                  : std::string()));
    }
  }
  for (std::size_t i = 0; i < boxes.size() && i < boxed_log_.size(); ++i) {
    const auto& [cycle, name] = boxed_log_[i];
    check_eq(boxes[i].filename().string(), "blackbox-" + std::to_string(cycle) + ".csv",
             "black box file name");
    std::ifstream in(boxes[i]);
    std::string first, line;
    std::getline(in, first);
    std::size_t lines = 1;
    while (std::getline(in, line)) ++lines;
    check(first.find("fault " + name + " at cycle " + std::to_string(cycle)) != std::string::npos,
          boxes[i].string() + ": first line does not name fault " + name + ": " + first);
    check_eq(lines, 2 + loop::Cycle::kBlackBoxCycles, boxes[i].string() + " lines");
  }
}

void Soak::finish_checks(const json& s) {
  const loop::CycleCounters& c = runtime_->cycle().counters();
  const rt::CycleThreadCounters& th = runtime_->cycle_thread_counters();
  const rtio::RobotLinkCounters& link = endpoint_->counters();
  const rt::RecorderCounters& rec = runtime_->recorder()->counters();

  // Cycles and the robot link.
  check_eq(c.messages + c.robot_timeouts + c.robot_malformed,
           cycle_calls_ + unplanned_timeouts_ + stop_timeouts_,
           "messages + timeouts + malformed vs cycles caused (+ unplanned, + at stop)");
  check_eq(c.messages, messages_sent_, "messages handled vs sent");
  check_eq(link.messages, messages_sent_, "endpoint messages vs sent");
  check_eq(link.datagrams, datagrams_sent_, "endpoint datagrams vs sent");
  check_eq(th.replies_ok, messages_sent_, "replies_ok vs messages");
  check_eq(link.replies, messages_sent_, "endpoint replies vs messages");
  check_eq(replies_, messages_sent_, "replies received by the robot vs messages");
  check_eq(th.replies_failed, 0u, "replies_failed");
  const std::uint64_t timeouts = timeouts_caused_ + unplanned_timeouts_ + stop_timeouts_;
  check_eq(c.robot_timeouts, timeouts, "robot_timeouts vs injected (+ unplanned)");
  check_eq(th.receive_timeouts, timeouts, "receive_timeouts vs injected (+ unplanned)");
  check_eq(link.timeouts, timeouts, "endpoint timeouts vs injected (+ unplanned)");
  check_eq(c.robot_malformed, malformed_sent_, "robot_malformed vs injected");
  check_eq(link.malformed, malformed_sent_, "endpoint malformed vs injected");
  for (std::size_t k = 0; k < std::size(kSpoils); ++k) {
    check_eq(link.malformed_by_status[static_cast<std::size_t>(kSpoils[k].status)],
             malformed_by_spoil_[k], std::string("malformed_by_status ") + kSpoils[k].name);
  }
  check_eq(c.ipoc_stale, stale_sent_, "ipoc_stale vs duplicates + reordered sent");
  check_eq(c.ipoc_gaps, gap_events_, "ipoc_gaps");
  check_eq(c.datagrams_lost, datagrams_lost_, "datagrams_lost");
  check_eq(c.commands_refused, refused_expected_, "commands_refused");
  check_eq(runtime_->compute_histogram().count(), messages_sent_, "compute_ns count");

  // Samples: everything fed was averaged, refused as invalid or discarded with a lost cycle.
  check_eq(c.ft_samples + c.ft_invalid + c.imu_samples + c.imu_invalid + c.sample_overflow +
               th.samples_discarded,
           ft_fed_ + imu_fed_, "samples used + invalid + overflow + discarded vs fed");
  if (unplanned_timeouts_ == 0)  // else some samples went with a cycle this program did not plan
    check_eq(th.samples_discarded, discarded_expected_, "samples discarded in lost cycles");
  check_eq(c.sample_overflow, 0u, "sample_overflow");

  // State machine.
  const std::uint64_t faults = fault_log_.size();
  const loop::StateMachine& sm = runtime_->cycle().state_machine();
  check_eq(sm.total_transitions(), seen_.size(), "transitions vs those seen in the snapshots");
  for (std::size_t i = 0; i < sm.log_size() && sm.log_size() <= seen_.size(); ++i) {
    const loop::Transition& tr = sm.log_at(i);
    const Seen& mine = seen_[seen_.size() - sm.log_size() + i];
    const std::string cause =
        tr.by_fault ? loop::fault_name(tr.fault) : loop::command_name(tr.command);
    check(tr.cycle == mine.cycle && tr.from == mine.from && tr.to == mine.to && cause == mine.cause,
          "transition log entry " + std::to_string(i) + " (cycle " + std::to_string(tr.cycle) +
              ", " + cause + ") differs from what the snapshots showed (cycle " +
              std::to_string(mine.cycle) + ", " + mine.cause + ")");
  }
  if (last_accepted_) {
    check(runtime_->cycle().tunables().body.mass_kg == last_accepted_->body.mass_kg &&
              runtime_->cycle().tunables().limits.linear_damping_per_s ==
                  last_accepted_->limits.linear_damping_per_s,
          "the last accepted proposal is not the virtual body in use");
  }
  std::uint64_t injected = 0;
  for (const auto& [k, n] : faults_injected_) injected += n;
  check_eq(faults, injected + faults_from_unplanned_,
           "faults raised vs injected (+ robot_late from unplanned timeouts)");

  // Records and rows.
  const rt::Runtime::RecordRing& ring = runtime_->record_ring();
  check_eq(ring.pushed(), messages_sent_, "records pushed vs messages");
  check_eq(ring.popped(), ring.pushed(), "records popped vs pushed");
  check_eq(ring.dropped(), 0u, "records dropped");
  check_eq(rec.records, messages_sent_, "records taken vs messages");
  check_eq(cycles_rows_, rec.records, "cycles.csv rows vs records taken");
  check_eq(rec.skipped_stale, stale_sent_, "skipped_stale vs stale sent");
  check_eq(rec.skipped_no_samples, 0u, "skipped_no_samples");
  check_eq(rec.rejected, 0u, "rejected rows");
  check_eq(log_rows_, rec.log_rows, "run.csv rows vs log_rows");
  check_eq(rec.log_rows, rec.records - rec.skipped_stale - rec.skipped_no_samples - rec.rejected,
           "rows = records − stale − before samples − rejected");
  check_eq(rec.black_boxes, boxed_log_.size(), "recorder black_boxes vs faults with a box");
  check_eq(th.black_box_releases + (runtime_->cycle().black_box().frozen() ? 1u : 0u),
           boxed_log_.size(), "black boxes released (+ one still frozen) vs faults with a box");

  // The summary says the same.
  const json& sc = s.at("cycles");
  check_eq(sc.at("messages").get<std::uint64_t>(), c.messages, "summary cycles.messages");
  check_eq(sc.at("robot_timeouts").get<std::uint64_t>(), timeouts, "summary robot_timeouts");
  check_eq(sc.at("robot_malformed").get<std::uint64_t>(), malformed_sent_,
           "summary robot_malformed");
  check_eq(sc.at("ipoc_stale").get<std::uint64_t>(), stale_sent_, "summary ipoc_stale");
  check_eq(sc.at("datagrams_lost").get<std::uint64_t>(), datagrams_lost_, "summary datagrams_lost");
  check_eq(sc.at("commands_refused").get<std::uint64_t>(), refused_expected_,
           "summary commands_refused");
  check_eq(s.at("cycle_thread").at("replies_ok").get<std::uint64_t>(), messages_sent_,
           "summary replies_ok");
  check_eq(s.at("devices").at("robot").at("replies").get<std::uint64_t>(), messages_sent_,
           "summary robot replies");
  check_eq(s.at("transitions_total").get<std::uint64_t>(), seen_.size(),
           "summary transitions_total");
  check_eq(s.at("black_box_dumps").size(), boxed_log_.size(), "summary black_box_dumps");
  check_eq(s.at("rings").at("records").at("dropped").get<std::uint64_t>(), 0u,
           "summary rings.records.dropped");
  check_eq(s.at("rings").at("ft").at("dropped").get<std::uint64_t>(), 0u,
           "summary rings.ft.dropped");
  check_eq(s.at("rings").at("imu").at("dropped").get<std::uint64_t>(), 0u,
           "summary rings.imu.dropped");
  const json& r = s.at("recording");
  check(r.is_object(), "summary has no recording");
  if (r.is_object()) {
    check_eq(r.at("records").get<std::uint64_t>(), cycles_rows_, "summary recording.records");
    check_eq(r.at("log_rows").get<std::uint64_t>(), log_rows_, "summary recording.log_rows");
    check_eq(r.at("skipped_stale").get<std::uint64_t>(), stale_sent_,
             "summary recording.skipped_stale");
    check_eq(r.at("records_dropped").get<std::uint64_t>(), 0u, "summary records_dropped");
    check_eq(r.at("error").get<std::string>(), std::string(), "summary recording.error");
  }
  const json& by_status = s.at("devices").at("robot").at("malformed_by_status");
  std::uint64_t by_status_sum = 0;
  for (const auto& [k, v] : by_status.items()) by_status_sum += v.get<std::uint64_t>();
  check_eq(by_status_sum, malformed_sent_, "summary malformed_by_status sum");

  // Every fault kind (each of its injection routes) at least once in a full run.
  if (opt_.simulated_s >= 3000.0) {
    for (int k = 0; k <= static_cast<int>(Inject::contact_over_limit); ++k) {
      bool seen = false;
      for (const auto& [name, n] : faults_injected_)
        seen = seen || name.rfind(std::string(inject_name(static_cast<Inject>(k))) + "->", 0) == 0;
      check(seen, std::string("no ") + inject_name(static_cast<Inject>(k)) + " fault in the hour");
    }
  }
  check(faults > 0 && sessions_ > 0 && pushes_clean_ > 0, "the script did nothing");
  check(proposals_accepted_ > 0 && proposals_refused_ == 1,
        "supervisor proposals: " + std::to_string(proposals_accepted_) + " accepted, " +
            std::to_string(proposals_refused_) + " refused (want ≥ 1 and 1)");

  // Memory: the cycle allocates nothing; the recorder's buffers are reserved at start and its
  // per-second compute-time window keeps its largest size (≤ records per wall second × 8 B).
  const Memory& w = *mem_warm_;
  check(to_mib(mem_end_.heap_live_bytes - w.heap_live_bytes) < opt_.heap_bound_mib,
        "heap (C++, all threads) grew by " +
            std::to_string(to_mib(mem_end_.heap_live_bytes - w.heap_live_bytes)) + " MiB");
  check(to_mib(mem_end_.main_arena_bytes - w.main_arena_bytes) < opt_.heap_bound_mib,
        "main arena grew by " +
            std::to_string(to_mib(mem_end_.main_arena_bytes - w.main_arena_bytes)) + " MiB");
  check(!kRssIsChecked || to_mib(mem_end_.rss_bytes - w.rss_bytes) < opt_.rss_bound_mib,
        "RSS grew by " + std::to_string(to_mib(mem_end_.rss_bytes - w.rss_bytes)) + " MiB");
}

json Soak::report(const json& summary) const {
  const loop::CycleCounters& c = runtime_->cycle().counters();
  const rt::RecorderCounters& rec = runtime_->recorder()->counters();
  const double simulated = static_cast<double>(total_periods_) * period_s_;
  json j = {
      {"format", "zerog-soak"},
      {"version", 1},
      {"passed", failure_count_ == 0},
      {"seed", opt_.seed},
      {"cycle_s", period_s_},
      {"simulated_s", simulated},
      {"wall_s", wall_s_},
      {"speed_up", wall_s_ > 0 ? simulated / wall_s_ : 0.0},
      {"robot_periods", total_periods_},
      {"cycles_run", cycle_calls_},
      {"messages", c.messages},
      {"sessions", sessions_},
      {"pushes", pushes_},
      {"pushes_clean", pushes_clean_},
      {"pushes_moved", pushes_moved_},
      {"faults_injected", faults_injected_},
      {"faults_raised", faults_raised_},
      {"fault_raise_latency_max_cycles", max_raise_latency_},
      {"disturbances", disturbances_},
      {"robot_timeouts", c.robot_timeouts},
      {"unplanned_timeouts", unplanned_timeouts_},
      {"timeouts_at_stop", stop_timeouts_},
      {"faults_from_unplanned_timeouts", faults_from_unplanned_},
      {"receive_timeout_s", opt_.receive_timeout_ms * 1e-3},
      {"robot_malformed", c.robot_malformed},
      {"ipoc_stale", c.ipoc_stale},
      {"ipoc_gaps", c.ipoc_gaps},
      {"datagrams_lost", c.datagrams_lost},
      {"commands_refused", c.commands_refused},
      {"proposals_accepted", proposals_accepted_},
      {"proposals_refused", proposals_refused_},
      {"transitions", runtime_->cycle().state_machine().total_transitions()},
      {"black_boxes", runtime_->black_box_paths().size()},
      {"black_boxes_lost", lost_log_.size()},
      {"records", rec.records},
      {"records_dropped", runtime_->record_ring().dropped()},
      {"cycles_csv_rows", cycles_rows_},
      {"run_csv_rows", log_rows_},
      {"skipped_stale", rec.skipped_stale},
      {"pace_waits", pace_waits_},
      {"pace_wait_s", pace_wait_s_},
      {"compute_ns", summary.at("compute_ns")},
      {"memory",
       {{"start", memory_json(mem_start_)},
        {"after_warmup", mem_warm_ ? memory_json(*mem_warm_) : json(nullptr)},
        {"end", memory_json(mem_end_)},
        {"after_stop", memory_json(mem_after_stop_)},
        {"warmup_s", opt_.warmup_s},
        {"heap_growth_mib",
         mem_warm_ ? to_mib(mem_end_.heap_live_bytes - mem_warm_->heap_live_bytes) : 0.0},
        {"main_arena_growth_mib",
         mem_warm_ ? to_mib(mem_end_.main_arena_bytes - mem_warm_->main_arena_bytes) : 0.0},
        {"rss_growth_mib", mem_warm_ ? to_mib(mem_end_.rss_bytes - mem_warm_->rss_bytes) : 0.0},
        {"heap_bound_mib", opt_.heap_bound_mib},
        {"rss_bound_mib", opt_.rss_bound_mib},
        {"rss_checked", kRssIsChecked}}},
      {"record_dir", opt_.keep || temp_root_.empty() ? dir_.string() : std::string()},
      {"failure_count", failure_count_},
      {"failures", failures_}};
  return j;
}

int Soak::run() {
  mem_start_ = measure_memory();
  if (std::string e = set_up(); !e.empty()) {
    std::cerr << "zerog-soak: " << e << "\n";
    return 2;
  }
  enable_at_ = periods(2.0);
  disturbance_at_ = periods(5.0);
  propose_at_ = periods(std::min(opt_.warmup_s + 10.0, opt_.simulated_s / 3.0));
  const auto wall0 = std::chrono::steady_clock::now();
  for (std::uint64_t p = 0; p < total_periods_; ++p) run_period(p);
  wall_s_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  if (episode_ || awaiting_) fail("the run ended inside an injection");
  mem_end_ = measure_memory();
  const std::uint64_t lost_before_stop = runtime_->snapshot().robot_lost;
  const Status stop_status = runtime_->stop();
  // The cycle thread waits in receive() when stop() comes: that wait ends as a timeout.
  stop_timeouts_ = runtime_->cycle_thread_counters().receive_timeouts +
                   runtime_->cycle_thread_counters().receive_malformed - lost_before_stop;
  check(stop_timeouts_ <= 1, "lost cycles while stopping: " + std::to_string(stop_timeouts_));
  check(stop_status.ok(), "stop(): " + stop_status.text());
  mem_after_stop_ = measure_memory();
  json summary;
  const std::string summary_text = runtime_->summary_json();
  if (!opt_.summary_out.empty()) std::ofstream(opt_.summary_out) << summary_text;
  try {
    summary = json::parse(summary_text);
  } catch (const std::exception& e) {
    fail(std::string("summary JSON does not parse: ") + e.what());
  }
  check_files();
  if (!summary.is_null()) {
    try {
      finish_checks(summary);
    } catch (const std::exception& e) {
      fail(std::string("summary JSON: ") + e.what());
    }
  }
  const json out = report(summary.is_null() ? json{{"compute_ns", nullptr}} : summary);
  if (!opt_.report.empty()) {
    std::ofstream f(opt_.report);
    f << out.dump(1) << "\n";
    if (!f) std::cerr << "zerog-soak: cannot write " << opt_.report << "\n";
  }
  std::cout << out.dump(1) << "\n";
  std::cout << "zerog-soak: " << (failure_count_ == 0 ? "PASSED" : "FAILED") << ": "
            << out["simulated_s"].get<double>() << " s simulated in " << wall_s_ << " s ("
            << out["speed_up"].get<double>() << "x), " << cycle_calls_ << " cycles, " << sessions_
            << " sessions, " << pushes_ << " pushes, " << fault_log_.size() << " faults, "
            << cycles_rows_ << " records = cycles.csv rows, " << log_rows_ << " run.csv rows; heap "
            << (mem_warm_ ? to_mib(mem_warm_->heap_live_bytes) : 0.0) << " -> "
            << to_mib(mem_end_.heap_live_bytes) << " MiB, RSS "
            << (mem_warm_ ? to_mib(mem_warm_->rss_bytes) : 0.0) << " -> "
            << to_mib(mem_end_.rss_bytes) << " MiB; " << failure_count_ << " failures\n";
  if (!opt_.keep && !temp_root_.empty()) {
    std::error_code ec;
    fs::remove_all(temp_root_, ec);
  }
  return failure_count_ == 0 ? 0 : 1;
}

}  // namespace
}  // namespace zerog::soak

int main(int argc, char** argv) {
  zerog::soak::Options o;
  CLI::App app{
      "zerog-soak: a simulated hour of zero-g sessions, pushes and faults through "
      "zerog-rt's Runtime; checks memory, recorded rows and counters"};
  app.add_option("--simulated-s", o.simulated_s, "robot time to simulate, s")
      ->capture_default_str();
  app.add_option("--cycle-ms", o.cycle_ms, "robot cycle (RSI: 4 or 12), ms")->capture_default_str();
  app.add_option("--seed", o.seed, "random seed of the script")->capture_default_str();
  app.add_option("--warmup-s", o.warmup_s, "memory baseline after this robot time, s")
      ->capture_default_str();
  app.add_option("--record", o.dir, "record folder (default: a temporary one, removed)");
  app.add_flag("--keep", o.keep, "keep the temporary record folder");
  app.add_option("--report", o.report, "write the figures as JSON to this file");
  app.add_option("--summary-out", o.summary_out, "write zerog-rt's summary JSON to this file");
  app.add_option("--receive-timeout-ms", o.receive_timeout_ms,
                 "the RSI endpoint's receive timeout (the wall time of one lost cycle), ms")
      ->capture_default_str();
  app.add_option("--heap-bound-mib", o.heap_bound_mib, "allowed heap growth, MiB")
      ->capture_default_str();
  app.add_option("--rss-bound-mib", o.rss_bound_mib, "allowed RSS growth, MiB")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  return zerog::soak::Soak(o).run();
}
