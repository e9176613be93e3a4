#include "zerog/emu/rig_emulator.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <stdexcept>
#include <thread>
#include <tuple>
#include <utility>

#include "zerog/emu/ati_board.hpp"
#include "zerog/emu/stim300_emulator.hpp"
#include "zerog/proto/rsi.hpp"
#include "zerog/robot/robot_model.hpp"
#include "zerog/sim/elastic.hpp"

namespace zerog::emu {
namespace {

using Clock = std::chrono::steady_clock;
namespace rsi = proto::rsi;

constexpr double kImuRateHz = 2000.0;     // STIM300 normal mode (proto/stim300.md)
constexpr double kPhysicsWakeHz = 500.0;  // the physics thread steps in batches of 2 ms
/// robot_foreign's datagrams carry this much more in their IPOC than the real one.
constexpr std::uint64_t kForeignIpocOffset = 500'000'000;

RobotConfig robot_config(const Scenario& s) {
  RobotConfig c;
  c.physics_rate_hz = s.robot.physics_rate_hz;
  c.servo_bandwidth_hz = s.robot.servo_bandwidth_hz;
  c.interpolation_s = s.cycle_s();
  c.start_joints_rad = s.robot.start_joints_rad;
  c.p_flange_tcp_m = s.sim.p_flange_sensor_m;
  return c;
}

std::string errno_text(int e) { return std::strerror(e); }

std::string address_text(const sockaddr_in& a) {
  char ip[INET_ADDRSTRLEN] = {};
  ::inet_ntop(AF_INET, &a.sin_addr, ip, sizeof ip);
  return std::string(ip) + ":" + std::to_string(ntohs(a.sin_port));
}

void append(std::string& out, double v) {
  char buf[32];
  const int n = std::snprintf(buf, sizeof buf, "%.10g", v == 0.0 ? 0.0 : v);
  out.append(buf, static_cast<std::size_t>(n));
}

nlohmann::json vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

const char* correction_kind_name(CorrectionKind k) {
  switch (k) {
    case CorrectionKind::none:
      return "none";
    case CorrectionKind::rkorr:
      return "rkorr";
    case CorrectionKind::akorr:
      return "akorr";
    case CorrectionKind::both:
      return "both";
  }
  return "?";
}

// A datagram the controller's parser-side would reject, four kinds in turn (proto/emulator.md).
std::string malformed(const std::string& good, std::uint64_t n) {
  switch (n % 4) {
    case 0:
      return good.substr(0, good.size() / 2);  // truncated
    case 1: {
      std::string s = good;  // a number that is not one
      const std::size_t at = s.find("X=\"");
      if (at != std::string::npos) s.insert(at + 3, "x");
      return s;
    }
    case 2: {
      std::string s = good;  // wrong root element
      s.replace(1, 3, "Bot");
      return s;
    }
    default:
      return std::string(64, '\xff');  // not XML at all
  }
}

}  // namespace

sockaddr_in parse_endpoint(const std::string& text, const std::string& what) {
  const std::size_t colon = text.rfind(':');
  sockaddr_in a{};
  a.sin_family = AF_INET;
  unsigned port = 0;
  const bool ok = colon != std::string::npos && colon > 0 &&
                  ::inet_pton(AF_INET, text.substr(0, colon).c_str(), &a.sin_addr) == 1 && [&] {
                    const char* first = text.data() + colon + 1;
                    const char* last = text.data() + text.size();
                    const auto [ptr, ec] = std::from_chars(first, last, port);
                    return first != last && ec == std::errc{} && ptr == last && port <= 65535;
                  }();
  if (!ok)
    throw std::invalid_argument(what + ": '" + text +
                                "' is not an IPv4 address and port like 127.0.0.1:49152");
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  return a;
}

const char* reply_status_name(ReplyStatus status) {
  switch (status) {
    case ReplyStatus::none:
      return "none";
    case ReplyStatus::ok:
      return "ok";
    case ReplyStatus::late:
      return "late";
    case ReplyStatus::wrong_ipoc:
      return "wrong_ipoc";
  }
  return "?";
}

formats::Rig emulator_rig(const Scenario& scenario, const sim::RigSimulator& simulator) {
  formats::Rig rig = simulator.rig();
  rig.name = kEmulatorRigName;
  rig.sample_period_s = scenario.cycle_s();
  rig.ft_rate_hz = 0.0;  // as fast as zerog-rt asks: the board answers each request
  rig.imu_rate_hz = kImuRateHz;
  // The arm that is not rigid (proto/sim_robot.md): the rig names its robot file's kinematics
  // and elasticity (calib/robots/kr210_r2700.robot.toml, the simulator's arm), as a cell's rig
  // would; the emulated arm may be set otherwise by the scenario
  // (elastic.k1…, the real robot is not its file). zerog-rt's motion estimator steps it.
  if (simulator.config().elastic.enabled) {
    robot::RobotModel arm = sim::kr210();
    arm.flange_sensor = {rig.flange_sensor.q.toRotationMatrix(), rig.flange_sensor.p_m};
    rig.robot_model = arm;
  }
  return rig;
}

io::ModelFile emulator_truth(const Scenario& scenario, const sim::RigSimulator& simulator) {
  io::ModelFile m = simulator.truth();
  m.rig_name = kEmulatorRigName;
  m.extra["generator"] = "zerog-emu";
  m.extra["scenario"] = scenario.source.string();
  m.extra.erase("trajectory");  // the emulator's motion comes from zerog-rt, not a path
  return m;
}

std::string truth_csv_header() {
  return "t_s,ipoc,reply,q1_rad,q2_rad,q3_rad,q4_rad,q5_rad,q6_rad,"
         "tcp_x_m,tcp_y_m,tcp_z_m,tcp_qw,tcp_qx,tcp_qy,tcp_qz,"
         "tcp_vx_mps,tcp_vy_mps,tcp_vz_mps,tcp_wx_radps,tcp_wy_radps,tcp_wz_radps,"
         "com_vx_mps,com_vy_mps,com_vz_mps,push_fx_N,push_fy_N,push_fz_N,"
         "push_mx_Nm,push_my_Nm,push_mz_Nm,correction,corr_1,corr_2,corr_3,corr_4,corr_5,corr_6,"
         "delay";
}

RigEmulator::RigEmulator(const Scenario& scenario, const RigEmulatorOptions& options, AtiBoard* ft,
                         Stim300Emulator* imu)
    : scenario_(scenario),
      options_(options),
      handover_(robot_config(scenario)),
      physics_(scenario.sim, scenario.pushes, scenario.robot.physics_rate_hz) {
  setup_.ft = ft;
  setup_.imu = imu;
  setup_.lockstep = !options_.lockstep_path.empty();
  sockets_.bind_addr = parse_endpoint(options_.robot_bind, "--robot-bind");
  sockets_.rt_addr = parse_endpoint(options_.rt_address, "--rt-address");
  if (sockets_.rt_addr.sin_port == 0)
    throw std::invalid_argument("--rt-address: port 0 is not a port");
  if (!(std::isfinite(options_.duration_s) && options_.duration_s >= 0.0))
    throw std::invalid_argument("duration must be >= 0 s");
  setup_.cycle_ms = static_cast<std::uint64_t>(scenario_.robot.cycle_ms);
  setup_.cycles_total =
      static_cast<std::uint64_t>(std::llround(options_.duration_s / scenario_.cycle_s()));
  if (options_.duration_s > 0.0 && setup_.cycles_total == 0) setup_.cycles_total = 1;
  faults_.resize(scenario_.faults.size());
  for (std::size_t i = 0; i < faults_.size(); ++i) {
    const Fault& f = scenario_.faults[i];
    if (!info(f.kind).robot) {
      const bool ft_fault = f.kind == FaultKind::ft_silent || f.kind == FaultKind::ft_slow ||
                            f.kind == FaultKind::ft_critical || f.kind == FaultKind::ft_saturated ||
                            f.kind == FaultKind::ft_thermistor_silent;
      if ((ft_fault && setup_.ft == nullptr) || (!ft_fault && setup_.imu == nullptr))
        faults_[i].note = "not injected: no device";
      continue;
    }
    std::tie(faults_[i].first_cycle, faults_[i].last_cycle) =
        robot_fault_cycles(f, scenario_.cycle_s());
  }
  if (setup_.cycles_total > 0) {
    loop_.records.reserve(setup_.cycles_total);
    truth_.ticks.reserve(setup_.cycles_total + 1);
  }
}

RigEmulator::~RigEmulator() {
  if (sockets_.fd >= 0) ::close(sockets_.fd);
  if (sockets_.foreign_fd >= 0) ::close(sockets_.foreign_fd);
  if (sockets_.lockstep_fd >= 0) ::close(sockets_.lockstep_fd);
  if (!sockets_.lockstep_bound.empty()) ::unlink(sockets_.lockstep_bound.c_str());
}

void RigEmulator::bind() {
  auto open_bound = [](sockaddr_in address, const std::string& what) {
    const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (fd < 0) throw std::runtime_error(what + ": socket: " + errno_text(errno));
    if (::bind(fd, reinterpret_cast<const sockaddr*>(&address), sizeof address) != 0) {
      const int e = errno;
      ::close(fd);
      throw std::runtime_error(what + ": cannot bind " + address_text(address) + ": " +
                               errno_text(e));
    }
    return fd;
  };
  sockets_.fd = open_bound(sockets_.bind_addr, "--robot-bind");
  sockaddr_in local{};
  socklen_t length = sizeof local;
  ::getsockname(sockets_.fd, reinterpret_cast<sockaddr*>(&local), &length);
  sockets_.robot_port = ntohs(local.sin_port);
  sockaddr_in other = sockets_.bind_addr;
  other.sin_port = 0;
  sockets_.foreign_fd = open_bound(other, "robot_foreign socket");
  if (setup_.lockstep) {
    const std::string& path = options_.lockstep_path;
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    if (path.size() >= sizeof a.sun_path)
      throw std::invalid_argument("--lockstep " + path + ": longer than a socket path may be");
    std::memcpy(a.sun_path, path.c_str(), path.size());
    struct stat st {};
    if (::lstat(path.c_str(), &st) == 0) {
      if (!S_ISSOCK(st.st_mode))
        throw std::runtime_error("--lockstep " + path + ": exists and is not a socket; remove it");
      ::unlink(path.c_str());  // a stale socket of an earlier run
    }
    sockets_.lockstep_fd = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (sockets_.lockstep_fd < 0 ||
        ::bind(sockets_.lockstep_fd, reinterpret_cast<const sockaddr*>(&a), sizeof a) != 0)
      throw std::runtime_error("--lockstep " + path + ": cannot bind: " + errno_text(errno));
    sockets_.lockstep_bound = path;
  }
}

std::chrono::steady_clock::time_point RigEmulator::now() const {
  return setup_.lockstep ? lockstep_.now : Clock::now();
}

std::uint16_t RigEmulator::robot_port() const { return sockets_.robot_port; }

Clock::time_point RigEmulator::cycle_start(std::uint64_t n) const {
  return setup_.t0 + std::chrono::milliseconds(setup_.cycle_ms * n);
}

// --- Physics thread ------------------------------------------------------------------------

std::uint64_t RigEmulator::tick_step(std::uint64_t n) const {
  const double t_s = static_cast<double>(n * setup_.cycle_ms) * 1e-3;
  return static_cast<std::uint64_t>(std::ceil(t_s * physics_.physics_rate_hz() - 1e-6));
}

void RigEmulator::apply_correction(const rsi::Reply& reply) {
  bool clamped = false, singular = false;
  if (reply.has_rkorr) {
    const CorrectionOutcome o = handover_.robot.apply_rkorr(reply.rkorr);
    clamped = o.clamped;
    singular = o.near_singular;
  }
  if (reply.has_akorr) clamped = handover_.robot.apply_akorr(reply.akorr_deg).clamped || clamped;
  physics_thread_.clamped_cycles += clamped;
  physics_thread_.near_singular_cycles += singular;
}

bool RigEmulator::apply_due_corrections(std::uint64_t k, std::unique_lock<std::mutex>& lock,
                                        const std::atomic<bool>& stop) {
  while (tick_step(physics_thread_.next_apply_tick) <= k) {
    if (handover_.ticks_handed < physics_thread_.next_apply_tick) {
      // The robot loop has not reached the tick yet (a slow host).
      ++physics_thread_.handover_waits;
      while (handover_.ticks_handed < physics_thread_.next_apply_tick) {
        if (stop.load() || handover_.robot_done.load()) return false;
        handover_.handed_cv.wait_for(lock, std::chrono::milliseconds(1));
      }
    }
    const std::optional<rsi::Reply> reply = handover_.handed.front();
    handover_.handed.pop_front();
    ++physics_thread_.next_apply_tick;
    if (reply) apply_correction(*reply);
  }
  return true;
}

bool RigEmulator::physics_step(std::uint64_t k, const std::atomic<bool>& stop) {
  sim::JointState js;
  TcpMotion tcp;
  {
    std::unique_lock<std::mutex> lock(handover_.mutex);
    if (k > 0) {
      // The corrections of the ticks up to the start of this step take effect now.
      if (!apply_due_corrections(k - 1, lock, stop)) return false;
      handover_.robot.step();
    }
    js = handover_.robot.actual();
    tcp = handover_.robot.actual_tcp();
  }
  const PhysicsSample s = physics_.step(js);
  if (k == tick_step(truth_.ticks.size())) {  // only this thread adds to truth_.ticks
    const std::lock_guard<std::mutex> lock(truth_.mutex);
    truth_.ticks.push_back(
        {js.q_rad, tcp, s.truth.v_com_base_mps, s.push_force_base_N, s.push_torque_com_base_Nm});
  }
  const double rate = physics_.physics_rate_hz();
  if (setup_.ft != nullptr) {
    setup_.ft->set_wrench(s.wrench_sensor_noisy);
    // The scenario's sensor temperature (the sim's profile, the one temperature_bias follows),
    // for the thermistor channel.
    setup_.ft->set_temperature(scenario_.sim.temperature.at(static_cast<double>(k) / rate));
  }
  if (setup_.lockstep && setup_.ft != nullptr) {  // the samples zerog-rt will request, at its rate
    const auto ft_due = static_cast<std::uint64_t>(
        std::floor(static_cast<double>(k) * lockstep_.ft_rate_hz / rate + 1e-9));
    for (; lockstep_.ft_produced < ft_due; ++lockstep_.ft_produced)
      setup_.ft->queue_sample(s.wrench_sensor_noisy);
  }
  const auto imu_due =
      static_cast<std::uint64_t>(std::floor(static_cast<double>(k + 1) * kImuRateHz / rate + 1e-9));
  while (physics_thread_.imu_samples < imu_due) {
    ++physics_thread_.imu_samples;
    if (setup_.imu == nullptr) continue;
    ImuTruthSample truth;
    truth.rate_imu_radps = s.truth.imu.angular_rate_imu_radps;
    truth.specific_force_imu_mps2 = s.truth.imu.specific_force_imu_mps2;
    if (!setup_.imu->write_sample(truth)) ++physics_thread_.imu_dropped;
  }
  physics_thread_.physics_steps_done.store(k, std::memory_order_release);
  return true;
}

namespace {

// What an imu_* fault kind (but imu_unplug) does to the emulated IMU's stream.
ImuFault imu_stream_fault(FaultKind kind) {
  constexpr std::array<std::pair<FaultKind, ImuFault>, 4> kStreamFaults{{
      {FaultKind::imu_garbage, ImuFault::garbage},
      {FaultKind::imu_crc, ImuFault::crc_errors},
      {FaultKind::imu_gaps, ImuFault::counter_gaps},
      {FaultKind::imu_silent, ImuFault::silent},
  }};
  for (const auto& [k, fault] : kStreamFaults)
    if (k == kind) return fault;
  return ImuFault::none;
}

}  // namespace

void RigEmulator::device_faults(double t_s) {
  auto thermistor_silent = [this](bool silent) {
    AtiBoardQuirks quirks = setup_.ft->quirks();
    quirks.no_diagnostic_response = silent;
    setup_.ft->set_quirks(quirks);
  };
  for (std::size_t i = 0; i < faults_.size(); ++i) {
    const Fault& f = scenario_.faults[i];
    FaultState& st = faults_[i];
    if (info(f.kind).robot || st.done || !st.note.empty()) continue;
    const bool ends = f.duration_s > 0.0;
    if (!st.active && t_s >= f.start_s) {
      st.active = true;
      st.applied_start_s = t_s;
      switch (f.kind) {
        case FaultKind::ft_silent:
          setup_.ft->set_fault(FtFault::silent);
          break;
        case FaultKind::ft_slow:
          setup_.ft->set_response_delay(
              std::chrono::microseconds(std::llround(f.response_delay_ms * 1e3)));
          break;
        case FaultKind::ft_critical:
          setup_.ft->set_fault(FtFault::critical);
          break;
        case FaultKind::ft_saturated:
          setup_.ft->set_fault(FtFault::saturated);
          break;
        case FaultKind::ft_thermistor_silent:
          thermistor_silent(true);
          break;
        case FaultKind::imu_unplug:
          setup_.imu->unplug();
          break;
        default:  // the IMU's stream faults (kStreamFaults); the robot's are not timed here
          if (const ImuFault fault = imu_stream_fault(f.kind); fault != ImuFault::none)
            setup_.imu->set_fault(fault);
          break;
      }
    }
    if (st.active && ends && t_s >= f.start_s + f.duration_s) {
      st.active = false;
      st.done = true;
      st.applied_end_s = t_s;
      switch (f.kind) {
        case FaultKind::ft_silent:
        case FaultKind::ft_critical:
        case FaultKind::ft_saturated:
          setup_.ft->set_fault(FtFault::none);
          break;
        case FaultKind::ft_slow:
          setup_.ft->set_response_delay(std::chrono::microseconds(0));
          break;
        case FaultKind::ft_thermistor_silent:
          thermistor_silent(false);
          break;
        case FaultKind::imu_unplug: {
          if (const Status plugged = setup_.imu->open(options_.imu_link); !plugged.ok())
            st.note = "re-plug failed: " + plugged.message();
          break;
        }
        default:
          setup_.imu->set_fault(ImuFault::none);
          break;
      }
    }
  }
}

void RigEmulator::physics_loop(const std::atomic<bool>& stop) {
  const double h = 1.0 / physics_.physics_rate_hz();
  auto step_time = [&](std::uint64_t k) {
    return setup_.t0 + std::chrono::duration_cast<Clock::duration>(
                           std::chrono::duration<double>(static_cast<double>(k) * h));
  };
  // The thread wakes at kPhysicsWakeHz and steps what is due: waking once per step at 2 kHz, it
  // took about half of one of the VM's emulated CPUs (proto/emulator.md).
  const auto wake_steps = static_cast<std::uint64_t>(
      std::max(1.0, std::floor(physics_.physics_rate_hz() / kPhysicsWakeHz + 1e-9)));
  std::uint64_t k = 1;
  while (!stop.load() && !handover_.robot_done.load()) {
    const Clock::time_point now = Clock::now();
    const Clock::time_point wake = step_time(k + wake_steps - 1);
    if (now < wake) {
      std::this_thread::sleep_until(wake);
      continue;
    }
    const double lag = std::chrono::duration<double>(now - wake).count();
    physics_thread_.worst_lag_s = std::max(physics_thread_.worst_lag_s, lag);
    const auto due = static_cast<std::uint64_t>(
        std::floor(std::chrono::duration<double>(now - setup_.t0).count() / h));
    const std::uint64_t batch = due - k + 1;
    if (batch > wake_steps) ++physics_thread_.late_batches;
    physics_thread_.largest_batch = std::max(physics_thread_.largest_batch, batch);
    for (; k <= due; ++k)
      if (!physics_step(k, stop)) return;
    device_faults(static_cast<double>(due) * h);
  }
}

// --- Robot loop ------------------------------------------------------------------------------

void RigEmulator::transmit(const ScheduledSend& s) {
  const int fd = s.foreign ? sockets_.foreign_fd : sockets_.fd;
  const ssize_t n =
      ::sendto(fd, s.bytes.data(), s.bytes.size(), 0,
               reinterpret_cast<const sockaddr*>(&sockets_.rt_addr), sizeof sockets_.rt_addr);
  if (n != static_cast<ssize_t>(s.bytes.size())) ++loop_.counts.send_errors;
  ++loop_.counts.datagrams_sent;
}

void RigEmulator::send_due(Clock::time_point now) {
  for (std::size_t i = 0; i < loop_.sends.size();) {
    if (loop_.sends[i].at > now) {
      ++i;
      continue;
    }
    transmit(loop_.sends[i]);
    loop_.sends.erase(loop_.sends.begin() + static_cast<std::ptrdiff_t>(i));
  }
}

void RigEmulator::handle_datagram(std::uint64_t n, const char* data, std::size_t size) {
  ++loop_.counts.reply_datagrams;
  rsi::Reply reply;
  const bool parsed = rsi::parse_reply(std::string_view(data, size), reply).ok();
  std::int64_t idx = -1;
  if (parsed && reply.ipoc >= options_.first_ipoc &&
      (reply.ipoc - options_.first_ipoc) % setup_.cycle_ms == 0) {
    const std::uint64_t k = (reply.ipoc - options_.first_ipoc) / setup_.cycle_ms;
    if (k < loop_.records.size() && loop_.records[k].sent) idx = static_cast<std::int64_t>(k);
  }
  const bool good =
      parsed && idx == static_cast<std::int64_t>(n) && loop_.records[n].reply != ReplyStatus::ok;
  if (!loop_.any_ok && !good) ++loop_.counts.before_first_ok;
  if (!parsed) {
    ++loop_.counts.malformed;
    return;
  }
  if (good) {
    CycleRecord& r = loop_.records[n];
    r.reply = ReplyStatus::ok;
    ++loop_.counts.ok;
    if (!loop_.any_ok) loop_.counts.first_ok_cycle = static_cast<std::int64_t>(n);
    loop_.any_ok = true;
    // Like the controller's interpolator, the correction takes effect at the next cycle's
    // tick, whenever in this cycle it arrived (hand_over, then the physics thread applies it
    // at the tick's physics step): the arrival jitter of the replies must not shake the robot.
    loop_.pending = reply;
    if (reply.has_rkorr) {
      const rsi::Correction& c = reply.rkorr;
      r.correction = {c.x_mm, c.y_mm, c.z_mm, c.a_deg, c.b_deg, c.c_deg};
      r.correction_kind = reply.has_akorr ? CorrectionKind::both : CorrectionKind::rkorr;
    } else if (reply.has_akorr) {
      r.correction = reply.akorr_deg;
      r.correction_kind = CorrectionKind::akorr;
    }
    return;
  }
  if (idx == static_cast<std::int64_t>(n)) {
    ++loop_.counts.duplicate;  // a second reply to this cycle
  } else if (idx >= 0 && idx < static_cast<std::int64_t>(n)) {
    ++loop_.counts.late;
    CycleRecord& r = loop_.records[static_cast<std::size_t>(idx)];
    if (r.reply != ReplyStatus::ok) r.reply = ReplyStatus::late;
  } else {
    ++loop_.counts.wrong_ipoc;
    if (n < loop_.records.size() && loop_.records[n].reply == ReplyStatus::none)
      loop_.records[n].reply = ReplyStatus::wrong_ipoc;
  }
}

void RigEmulator::hand_over(std::uint64_t n) {
  {
    const std::lock_guard<std::mutex> lock(handover_.mutex);
    handover_.handed.push_back(loop_.pending);
    handover_.ticks_handed = n;
  }
  loop_.pending.reset();
  handover_.handed_cv.notify_all();
}

void RigEmulator::receive_pending(std::uint64_t n) {
  std::array<char, rsi::kMaxMessageBytes + 1> buf;
  while (true) {
    sockaddr_in from{};
    socklen_t length = sizeof from;
    const ssize_t got = ::recvfrom(sockets_.fd, buf.data(), buf.size(), 0,
                                   reinterpret_cast<sockaddr*>(&from), &length);
    if (got < 0) break;
    if (from.sin_addr.s_addr != sockets_.rt_addr.sin_addr.s_addr ||
        from.sin_port != sockets_.rt_addr.sin_port) {
      ++loop_.counts.from_elsewhere;
      continue;
    }
    handle_datagram(n, buf.data(), static_cast<std::size_t>(got));
  }
  while (::recv(sockets_.foreign_fd, buf.data(), buf.size(), 0) >= 0)
    ++loop_.counts.foreign_replies;
}

void RigEmulator::start_cycle(std::uint64_t n) {
  const double t_s = static_cast<double>(n) * scenario_.cycle_s();
  CycleRecord r;
  r.t_s = t_s;
  r.ipoc = options_.first_ipoc + n * setup_.cycle_ms;
  r.delay = loop_.delay_count;
  rsi::RobotMessage msg;
  sim::JointState js;
  {
    const std::lock_guard<std::mutex> lock(handover_.mutex);
    msg = handover_.robot.message(r.ipoc, loop_.delay_count);
    js = handover_.robot.actual();
    r.tcp = handover_.robot.actual_tcp();
  }
  // The datagram carries the latest state. Normally the physics is at the tick or one step
  // short of it; a slow host may hold it back further (counted). The truth row gets the state at
  // the tick's physics step after the run.
  const std::uint64_t done = physics_thread_.physics_steps_done.load(std::memory_order_acquire);
  if (done + 1 < tick_step(n)) {
    ++loop_.stale_datagrams;
    loop_.worst_datagram_lag_s =
        std::max(loop_.worst_datagram_lag_s,
                 static_cast<double>(tick_step(n) - done) / physics_.physics_rate_hz());
  }
  r.q_rad = js.q_rad;
  const PhysicsSample p = physics_.evaluate(js, js, t_s);
  r.v_com_base_mps = p.truth.v_com_base_mps;
  r.push_force_base_N = p.push_force_base_N;
  r.push_torque_com_base_Nm = p.push_torque_com_base_Nm;

  std::array<char, rsi::kMaxMessageBytes> buf;
  const rsi::FormatResult f = rsi::format_robot_message(msg, buf);
  const std::string bytes(buf.data(), f.status == rsi::FormatStatus::ok ? f.size : 0);

  // The robot fault active in this cycle, if any (they do not overlap: scenario validation).
  const Fault* fault = nullptr;
  std::size_t fault_index = 0;
  for (std::size_t i = 0; i < faults_.size(); ++i) {
    const FaultState& st = faults_[i];
    if (st.first_cycle < 0 || static_cast<std::int64_t>(n) < st.first_cycle ||
        static_cast<std::int64_t>(n) > st.last_cycle)
      continue;
    fault = &scenario_.faults[i];
    fault_index = i;
  }
  const Clock::time_point at = cycle_start(n);
  auto send = [&](std::string b, Clock::time_point when, bool foreign) {
    loop_.sends.push_back({when, std::move(b), foreign});
  };
  bool hit = fault != nullptr;
  r.sent = !bytes.empty();
  if (fault == nullptr) {
    send(bytes, at, false);
  } else {
    switch (fault->kind) {
      case FaultKind::robot_drop:
        r.sent = false;
        break;
      case FaultKind::robot_malformed:
        send(malformed(bytes, n), at, false);
        ++loop_.counts.malformed_sent;
        r.sent = false;
        break;
      case FaultKind::robot_late:
        send(bytes, at + std::chrono::microseconds(std::llround(fault->delay_ms * 1e3)), false);
        break;
      case FaultKind::robot_duplicate:
        send(bytes, at, false);
        send(bytes, at, false);
        ++loop_.counts.duplicates_sent;
        break;
      case FaultKind::robot_reorder:
        if ((static_cast<std::int64_t>(n) - faults_[fault_index].first_cycle) % 2 == 0) {
          loop_.held_bytes = bytes;  // sent after the next cycle's datagram
          loop_.reorder_held = static_cast<std::int64_t>(n);
        } else {
          send(bytes, at, false);
          hit = false;
        }
        break;
      case FaultKind::robot_foreign: {
        send(bytes, at, false);
        rsi::RobotMessage other = msg;
        other.ipoc += kForeignIpocOffset;
        const rsi::FormatResult g = rsi::format_robot_message(other, buf);
        send(std::string(buf.data(), g.size), at, true);
        ++loop_.counts.foreign_sent;
        break;
      }
      default:
        send(bytes, at, false);
        break;
    }
  }
  if (hit) {
    FaultState& st = faults_[fault_index];
    ++st.cycles_hit;
    if (st.applied_start_s < 0.0) st.applied_start_s = t_s;
    st.applied_end_s = t_s + scenario_.cycle_s();
  }
  loop_.records.push_back(r);
  loop_.counts.good_sent += r.sent;
  if (!setup_.lockstep) send_due(Clock::now());  // lockstep: lockstep_events_before sends them
  if (loop_.reorder_held >= 0 && loop_.reorder_held < static_cast<std::int64_t>(n)) {
    loop_.sends.push_back({now(), loop_.held_bytes, false});
    loop_.reorder_held = -1;
    if (!setup_.lockstep) send_due(Clock::now());
  }
}

void RigEmulator::run(const std::atomic<bool>& stop) {
  if (sockets_.fd < 0) throw std::logic_error("RigEmulator::run before bind()");
  if (setup_.lockstep) {
    run_lockstep(stop);
    return;
  }
  setup_.t0 = Clock::now();
  physics_step(0, stop);
  device_faults(0.0);
  std::exception_ptr physics_error;
  std::thread physics([&] {
    try {
      physics_loop(stop);
    } catch (...) {
      physics_error = std::current_exception();
    }
  });

  // Serves the socket until `deadline`: replies go to cycle `window` (−1: before the first).
  auto serve_until = [&](Clock::time_point deadline, std::int64_t window) {
    while (true) {
      Clock::time_point now = Clock::now();
      send_due(now);
      if (now >= deadline) return;
      Clock::time_point next = deadline;
      for (const ScheduledSend& s : loop_.sends) next = std::min(next, s.at);
      const auto wait = std::chrono::duration_cast<std::chrono::nanoseconds>(next - now);
      timespec ts{static_cast<time_t>(wait.count() / 1'000'000'000),
                  static_cast<long>(wait.count() % 1'000'000'000)};
      std::array<pollfd, 2> fds{{{sockets_.fd, POLLIN, 0}, {sockets_.foreign_fd, POLLIN, 0}}};
      if (::ppoll(fds.data(), fds.size(), &ts, nullptr) > 0) {
        if (window >= 0) {
          receive_pending(static_cast<std::uint64_t>(window));
        } else {
          std::array<char, 64> sink;
          while (::recv(sockets_.fd, sink.data(), sink.size(), 0) >= 0) ++loop_.counts.wrong_ipoc;
          while (::recv(sockets_.foreign_fd, sink.data(), sink.size(), 0) >= 0)
            ++loop_.counts.foreign_replies;
        }
      }
    }
  };
  auto finish_cycle = [&](std::uint64_t n) {
    if (loop_.records[n].reply != ReplyStatus::ok) ++loop_.delay_count;
    hand_over(n + 1);
  };

  std::uint64_t n = 0;
  for (; !stop.load() && (setup_.cycles_total == 0 || n < setup_.cycles_total) && !physics_error;
       ++n) {
    serve_until(cycle_start(n), static_cast<std::int64_t>(n) - 1);
    if (n > 0) finish_cycle(n - 1);
    start_cycle(n);
  }
  if (n > 0) {
    serve_until(stop.load() ? Clock::now() : cycle_start(n), static_cast<std::int64_t>(n) - 1);
    finish_cycle(n - 1);
  }
  loop_.sends.clear();  // a held or late datagram due after the run: never sent
  // Let the physics reach the last tick, so that every truth row is taken at its tick.
  const Clock::time_point give_up = Clock::now() + std::chrono::seconds(2);
  while (!stop.load() && Clock::now() < give_up) {
    {
      const std::lock_guard<std::mutex> lock(truth_.mutex);
      if (truth_.ticks.size() >= loop_.records.size()) break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  handover_.robot_done = true;
  physics.join();
  // Corrections handed over for ticks the physics did not reach: the command takes them still.
  for (const std::optional<rsi::Reply>& reply : handover_.handed)
    if (reply) apply_correction(*reply);
  handover_.handed.clear();
  merge_tick_truth();
  if (physics_error) std::rethrow_exception(physics_error);
}

void RigEmulator::merge_tick_truth() {
  // Each truth row as the physics took it at its tick (the datagram carried the latest state).
  for (std::size_t i = 0; i < loop_.records.size() && i < truth_.ticks.size(); ++i) {
    const TickTruth& t = truth_.ticks[i];
    CycleRecord& r = loop_.records[i];
    r.q_rad = t.q_rad;
    r.tcp = t.tcp;
    r.v_com_base_mps = t.v_com_base_mps;
    r.push_force_base_N = t.push_force_base_N;
    r.push_torque_com_base_Nm = t.push_torque_com_base_Nm;
  }
}

// --- Lockstep (proto/lockstep.md) ------------------------------------------------------------

namespace {
// Real-time guards: how long zerog-rt may take to start (hello) and to handle one event. They
// only catch a hung zerog-rt; the result never depends on them.
constexpr std::chrono::seconds kHelloGuard{120};
constexpr std::chrono::seconds kEventGuard{60};

// Receives one LockstepReply within `guard`; throws naming `what` otherwise.
rtio::LockstepReply lockstep_receive(int fd, std::chrono::seconds guard, const std::string& what,
                                     std::vector<char>* peer, const std::atomic<bool>* stop) {
  const Clock::time_point give_up = Clock::now() + guard;
  while (true) {
    if (stop != nullptr && stop->load())
      throw std::runtime_error("lockstep: stopped (signal) while waiting for " + what);
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(give_up - Clock::now()).count();
    if (left <= 0)
      throw std::runtime_error("lockstep: " + what + " did not come within " +
                               std::to_string(guard.count()) +
                               " s (is zerog-rt --lockstep "
                               "running and alive?)");
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(std::min<long long>(left, 1000))) <= 0) continue;
    rtio::LockstepReply r;
    sockaddr_un from{};
    socklen_t length = sizeof from;
    const ssize_t n = ::recvfrom(fd, &r, sizeof r, MSG_TRUNC | MSG_DONTWAIT,
                                 reinterpret_cast<sockaddr*>(&from), &length);
    if (n < 0) continue;
    if (n != static_cast<ssize_t>(sizeof r) || r.magic != rtio::kLockstepMagic ||
        r.version != rtio::kLockstepVersion)
      throw std::runtime_error("lockstep: a message of " + std::to_string(n) +
                               " bytes that is not zerog-rt's (magic, size or version differ: "
                               "zerog-emu and zerog-rt from different builds?)");
    if (peer != nullptr)
      peer->assign(reinterpret_cast<const char*>(&from),
                   reinterpret_cast<const char*>(&from) + length);
    return r;
  }
}
}  // namespace

void RigEmulator::lockstep_exchange(rtio::LockstepKind kind, Clock::time_point at,
                                    std::uint64_t window) {
  // Every byte of the IMU's datagrams so far in the pty (a partly written one completed).
  const Clock::time_point give_up = Clock::now() + kEventGuard;
  while (setup_.imu != nullptr && !setup_.imu->flush_pending()) {
    if (Clock::now() > give_up)
      throw std::runtime_error("lockstep: the IMU's pty stayed full for 60 s (nobody reads it)");
    std::this_thread::sleep_for(std::chrono::microseconds(100));
  }
  rtio::LockstepEvent ev;
  ev.kind = kind;
  ev.seq = ++lockstep_.counts.events;
  ev.time_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(at - setup_.t0).count();
  ev.ft_samples = lockstep_.ft_produced;
  ev.ft_answers =
      setup_.ft != nullptr && setup_.ft->answers_within(lockstep_.rt_ft_sample_timeout) ? 1 : 0;
  if (setup_.imu != nullptr) {
    ev.imu_bytes = setup_.imu->bytes_since_plug();
    ev.imu_epoch = setup_.imu->unplugs();
    ev.imu_plugged = setup_.imu->plugged() ? 1 : 0;
  }
  if (kind == rtio::LockstepKind::timeout) ++lockstep_.counts.timeout_events;
  if (kind == rtio::LockstepKind::datagram) ++lockstep_.counts.datagram_events;
  const Clock::time_point sent = Clock::now();
  if (::sendto(sockets_.lockstep_fd, &ev, sizeof ev, 0,
               reinterpret_cast<const sockaddr*>(sockets_.lockstep_peer.data()),
               static_cast<socklen_t>(sockets_.lockstep_peer.size())) !=
      static_cast<ssize_t>(sizeof ev))
    throw std::runtime_error("lockstep: cannot send to zerog-rt: " + errno_text(errno));
  if (kind == rtio::LockstepKind::end) return;
  const rtio::LockstepReply r = lockstep_receive(
      sockets_.lockstep_fd, kEventGuard, "zerog-rt's answer to event " + std::to_string(ev.seq),
      nullptr, lockstep_.stop);
  if (r.kind != rtio::LockstepKind::done || r.seq != ev.seq)
    throw std::runtime_error("lockstep: zerog-rt answered event " + std::to_string(r.seq) +
                             " while " + std::to_string(ev.seq) + " was due");
  lockstep_.counts.slowest_ack_s = std::max(
      lockstep_.counts.slowest_ack_s, std::chrono::duration<double>(Clock::now() - sent).count());
  // The RSI replies were sent before the answer; wait until loopback has delivered them.
  while (loop_.counts.reply_datagrams < r.replies_sent) {
    if (Clock::now() > give_up)
      throw std::runtime_error("lockstep: zerog-rt sent " + std::to_string(r.replies_sent) +
                               " replies, " + std::to_string(loop_.counts.reply_datagrams) +
                               " arrived within 60 s");
    pollfd p{sockets_.fd, POLLIN, 0};
    ::poll(&p, 1, 10);
    receive_pending(window);
  }
  receive_pending(window);
}

void RigEmulator::lockstep_events_before(Clock::time_point limit, std::uint64_t window) {
  while (true) {
    auto next = loop_.sends.end();
    for (auto it = loop_.sends.begin(); it != loop_.sends.end(); ++it)
      if (next == loop_.sends.end() || it->at < next->at) next = it;
    const Clock::time_point deadline = lockstep_.last_rt_event + lockstep_.rt_receive_timeout;
    if (next != loop_.sends.end() && next->at < limit && next->at <= deadline) {
      const ScheduledSend s = *next;
      loop_.sends.erase(next);
      transmit(s);
      if (!s.foreign) {  // zerog-rt skips foreign datagrams inside receive(): no event
        lockstep_exchange(rtio::LockstepKind::datagram, s.at, window);
        lockstep_.last_rt_event = s.at;
      }
    } else if (deadline < limit) {
      lockstep_exchange(rtio::LockstepKind::timeout, deadline, window);
      lockstep_.last_rt_event = deadline;
    } else {
      return;
    }
  }
}

void RigEmulator::run_lockstep(const std::atomic<bool>& stop) {
  if (setup_.cycles_total == 0)
    throw std::invalid_argument("lockstep needs a duration (--duration > 0)");
  lockstep_.stop = &stop;
  const rtio::LockstepReply hello = lockstep_receive(
      sockets_.lockstep_fd, kHelloGuard, "zerog-rt's hello", &sockets_.lockstep_peer, &stop);
  if (hello.kind != rtio::LockstepKind::hello || hello.receive_timeout_ns <= 0 ||
      !(hello.ft_rate_hz > 0.0) || hello.ft_rate_hz > physics_.physics_rate_hz())
    throw std::runtime_error(
        "lockstep: zerog-rt's hello is not one (kind, receive timeout or an "
        "F/T rate above the physics rate)");
  lockstep_.rt_receive_timeout = std::chrono::nanoseconds(hello.receive_timeout_ns);
  lockstep_.rt_ft_sample_timeout = std::chrono::nanoseconds(hello.ft_sample_timeout_ns);
  lockstep_.ft_rate_hz = hello.ft_rate_hz;
  std::fprintf(stderr,
               "zerog-emu: lockstep with zerog-rt (receive timeout %.1f ms, F/T %.0f Hz): "
               "emulated time\n",
               static_cast<double>(hello.receive_timeout_ns) * 1e-6, lockstep_.ft_rate_hz);

  setup_.t0 = Clock::time_point{} + std::chrono::hours(1);
  const double h = 1.0 / physics_.physics_rate_hz();
  auto step_time = [&](std::uint64_t k) {
    return setup_.t0 + std::chrono::duration_cast<Clock::duration>(
                           std::chrono::duration<double>(static_cast<double>(k) * h));
  };
  lockstep_.now = setup_.t0;
  lockstep_.last_rt_event = setup_.t0;
  physics_step(0, stop);
  device_faults(0.0);
  start_cycle(0);
  lockstep_events_before(step_time(1), 0);
  std::uint64_t k = 0;
  const Clock::time_point wall0 = Clock::now();
  for (std::uint64_t n = 1; n <= setup_.cycles_total && !stop.load(); ++n) {
    if (options_.lockstep_paced)
      std::this_thread::sleep_until(wall0 + (cycle_start(n) - setup_.t0));
    // Cycle n−1's window: physics steps up to tick n, and the events between them.
    const std::uint64_t tick = tick_step(n);
    while (k < tick) {
      ++k;
      lockstep_.now = step_time(k);
      physics_step(k, stop);
      device_faults(static_cast<double>(k) * h);
      if (k < tick) lockstep_events_before(step_time(k + 1), n - 1);
    }
    if (loop_.records[n - 1].reply != ReplyStatus::ok) ++loop_.delay_count;
    hand_over(n);  // tick n's correction, applied from physics step tick + 1
    if (n == setup_.cycles_total) break;
    start_cycle(n);
    lockstep_events_before(step_time(k + 1), n);
  }
  loop_.sends.clear();  // a held or late datagram due after the run: never sent
  lockstep_exchange(rtio::LockstepKind::end, lockstep_.now, 0);
  merge_tick_truth();
}

// --- Outputs ---------------------------------------------------------------------------------

std::string RigEmulator::truth_csv() const {
  std::string out = truth_csv_header() + "\n";
  out.reserve(loop_.records.size() * 420 + out.size());
  for (const CycleRecord& r : loop_.records) {
    append(out, r.t_s);
    out += ',' + std::to_string(r.ipoc) + ',' + reply_status_name(r.reply);
    for (double q : r.q_rad) out += ',', append(out, q);
    for (int i = 0; i < 3; ++i) out += ',', append(out, r.tcp.pose.p_base_tcp_m[i]);
    Eigen::Quaterniond q(r.tcp.pose.R_base_tcp);
    q.normalize();
    if (q.w() < 0.0) q.coeffs() *= -1.0;
    for (double v : {q.w(), q.x(), q.y(), q.z()}) out += ',', append(out, v);
    for (const Eigen::Vector3d* v :
         {&r.tcp.v_tcp_base_mps, &r.tcp.omega_base_radps, &r.v_com_base_mps, &r.push_force_base_N,
          &r.push_torque_com_base_Nm})
      for (int i = 0; i < 3; ++i) out += ',', append(out, (*v)[i]);
    out += ',';
    out += correction_kind_name(r.correction_kind);
    for (double c : r.correction) out += ',', append(out, c);
    out += ',' + std::to_string(r.delay) + '\n';
  }
  return out;
}

nlohmann::json RigEmulator::summary() const {
  nlohmann::json s;
  s["format"] = "zerog-emu-summary";
  s["version"] = 1;
  s["scenario"] = scenario_.source.string();
  s["cycle_s"] = scenario_.cycle_s();
  s["cycles"] = loop_.records.size();
  s["duration_s"] = static_cast<double>(loop_.records.size()) * scenario_.cycle_s();
  s["first_ipoc"] = options_.first_ipoc;
  robot_loop_summary(s);
  if (setup_.lockstep) s["lockstep"] = lockstep_summary();
  s["pushes"] = pushes_summary();
  s["faults"] = faults_summary();
  s["physics"] = physics_summary();
  s["devices"] = devices_summary();
  return s;
}

void RigEmulator::robot_loop_summary(nlohmann::json& s) const {
  std::uint64_t missing = 0, cycles_ok = 0, cycles_late = 0, not_sent = 0;
  for (const CycleRecord& r : loop_.records) {
    if (!r.sent) ++not_sent;
    if (r.reply == ReplyStatus::ok) ++cycles_ok;
    if (r.reply == ReplyStatus::late) ++cycles_late;
    if (r.sent && r.reply != ReplyStatus::ok && r.reply != ReplyStatus::late) ++missing;
  }
  const Counts& c = loop_.counts;
  s["datagrams"] = {{"sent", c.datagrams_sent},      {"good", c.good_sent},
                    {"malformed", c.malformed_sent}, {"duplicated", c.duplicates_sent},
                    {"foreign", c.foreign_sent},     {"cycles_without_good_datagram", not_sent},
                    {"send_errors", c.send_errors}};
  s["replies"] = {{"datagrams", c.reply_datagrams},
                  {"ok", c.ok},
                  {"late", c.late},
                  {"missing", missing},
                  {"wrong_ipoc", c.wrong_ipoc},
                  {"malformed", c.malformed},
                  {"duplicate", c.duplicate},
                  {"from_elsewhere", c.from_elsewhere},
                  {"to_foreign_socket", c.foreign_replies},
                  {"cycles_ok", cycles_ok},
                  {"cycles_late", cycles_late},
                  {"before_first_ok", c.before_first_ok},
                  {"first_ok_cycle", c.first_ok_cycle}};
  s["robot"] = {{"delay", loop_.delay_count},
                {"rkorr_applied", handover_.robot.counters().rkorr_applied},
                {"akorr_applied", handover_.robot.counters().akorr_applied},
                {"clamped_cycles", physics_thread_.clamped_cycles},
                {"near_singular_cycles", physics_thread_.near_singular_cycles},
                {"servo_bandwidth_hz", scenario_.robot.servo_bandwidth_hz}};
}

nlohmann::json RigEmulator::lockstep_summary() const {
  const AtiBoard::Counters b = setup_.ft != nullptr ? setup_.ft->counters() : AtiBoard::Counters{};
  return {
      {"events", lockstep_.counts.events},
      {"datagram_events", lockstep_.counts.datagram_events},
      {"timeout_events", lockstep_.counts.timeout_events},
      {"rt_receive_timeout_s", 1e-9 * static_cast<double>(lockstep_.rt_receive_timeout.count())},
      {"ft_rate_hz", lockstep_.ft_rate_hz},
      {"ft_samples_produced", lockstep_.ft_produced},
      {"ft_queue_underruns", b.queue_underruns},
      {"ft_requests_ignored", b.sample_requests_ignored},  // thermistor reads apart
      {"ft_samples_left", setup_.ft != nullptr ? setup_.ft->samples_queued() : 0},
      {"slowest_answer_s", lockstep_.counts.slowest_ack_s}};
}

nlohmann::json RigEmulator::pushes_summary() const {
  using nlohmann::json;
  json pushes = json::array();
  for (std::size_t k = 0; k < scenario_.pushes.size(); ++k) {
    const Push& p = scenario_.pushes[k];
    const PushIntegral& in = physics_.push_integrals()[k];
    json j = {{"start_s", p.start_s},
              {"duration_s", p.duration_s},
              {"profile", push_profile_name(p.profile)},
              {"force_world_N", vec(p.force_world_N)},
              {"torque_world_Nm", vec(p.torque_world_Nm)},
              {"impulse_N_s", vec(p.impulse_N_s())},
              {"torque_impulse_Nms", vec(p.torque_impulse_Nms())},
              {"integrated_impulse_N_s", vec(in.impulse_N_s)},
              {"integrated_angular_impulse_com_Nms", vec(in.angular_impulse_com_Nms)}};
    j["point_sensor_m"] = p.point_sensor_m ? vec(*p.point_sensor_m) : json("centre_of_mass");
    pushes.push_back(j);
  }
  return pushes;
}

nlohmann::json RigEmulator::faults_summary() const {
  using nlohmann::json;
  json faults = json::array();
  for (std::size_t i = 0; i < faults_.size(); ++i) {
    const Fault& f = scenario_.faults[i];
    const FaultState& st = faults_[i];
    json j = {{"kind", info(f.kind).name}, {"start_s", f.start_s}};
    if (info(f.kind).robot) {
      j["cycles"] = f.cycles;
      j["first_cycle"] = st.first_cycle;
      j["last_cycle"] = st.last_cycle;
      j["cycles_affected"] = st.cycles_hit;
      if (f.kind == FaultKind::robot_late) j["delay_ms"] = f.delay_ms;
    } else {
      j["duration_s"] = f.duration_s;
      if (f.kind == FaultKind::ft_slow) j["response_delay_ms"] = f.response_delay_ms;
      const double c = scenario_.cycle_s();
      if (st.applied_start_s >= 0.0)
        j["first_cycle"] = static_cast<std::int64_t>(std::floor(st.applied_start_s / c + 1e-9));
      if (st.applied_end_s >= 0.0)
        j["last_cycle"] = static_cast<std::int64_t>(std::floor(st.applied_end_s / c + 1e-9));
    }
    j["applied_start_s"] = st.applied_start_s >= 0.0 ? json(st.applied_start_s) : json(nullptr);
    j["applied_end_s"] = st.applied_end_s >= 0.0 ? json(st.applied_end_s) : json(nullptr);
    if (!st.note.empty()) j["note"] = st.note;
    faults.push_back(j);
  }
  return faults;
}

nlohmann::json RigEmulator::physics_summary() const {
  return {{"rate_hz", physics_.physics_rate_hz()},
          {"steps", physics_.steps()},
          {"worst_lag_s", physics_thread_.worst_lag_s},
          {"late_batches", physics_thread_.late_batches},
          {"largest_batch", physics_thread_.largest_batch},
          {"imu_samples", physics_thread_.imu_samples},
          {"handover_waits", physics_thread_.handover_waits},
          {"stale_datagrams", loop_.stale_datagrams},
          {"worst_datagram_lag_s", loop_.worst_datagram_lag_s}};
}

// The device counters the summary reports (proto/emulator.md), by nlohmann's field macro.
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(AtiBoard::Counters, requests, sample_requests, samples_sent,
                                   ignored, saturated_samples, critical_samples, other_frames,
                                   tx_failed, diagnostic_reads, thermistor_reads)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(Stim300Emulator::Counters, written, dropped, garbage_bytes,
                                   bad_crc, skipped)

nlohmann::json RigEmulator::devices_summary() const {
  nlohmann::json devices = nlohmann::json::object();
  if (setup_.ft != nullptr) devices["ft"] = setup_.ft->counters();
  if (setup_.imu != nullptr) {
    devices["imu"] = setup_.imu->counters();
    devices["imu"]["write_failures"] = physics_thread_.imu_dropped;
  }
  return devices;
}

}  // namespace zerog::emu
