#include "zerog/rt/realtime.hpp"

#include <sched.h>
#include <sys/mman.h>

#include <cerrno>
#include <cstring>

namespace zerog::rt {

namespace {

void* trampoline(void* arg) {
  (*static_cast<std::function<void()>*>(arg))();
  return nullptr;
}

}  // namespace

Status lock_memory() {
  if (::mlockall(MCL_CURRENT | MCL_FUTURE) == 0) return {};
  const int error = errno;
  return {StatusCode::system_error, "realtime.lock_memory",
          std::string("mlockall(MCL_CURRENT|MCL_FUTURE) failed (") + std::strerror(error) +
              "): memory may be paged out and the cycle may miss its deadline; grant it with "
              "'LimitMEMLOCK=infinity' in the systemd unit or '<user> - memlock unlimited' in "
              "/etc/security/limits.conf (or run with CAP_IPC_LOCK)"};
}

void prefault_stack() {
  // One write per page of a stack array the compiler may not remove (volatile).
  volatile unsigned char stack[kPrefaultStackBytes];
  for (std::size_t i = 0; i < kPrefaultStackBytes; i += 512) stack[i] = 0;
  static_cast<void>(stack[kPrefaultStackBytes - 1]);
}

Thread::~Thread() { join(); }

Status sched_warning(const std::string& threads, int priority, int error) {
  return {StatusCode::system_error, "realtime.priority",
          "SCHED_FIFO priority " + std::to_string(priority) + " for " + threads + " refused (" +
              std::strerror(error) +
              "): they run as SCHED_OTHER and may miss deadlines; grant it with 'LimitRTPRIO=99' "
              "in the systemd unit or '<user> - rtprio 99' in /etc/security/limits.conf (or "
              "CAP_SYS_NICE; in a container also a real-time budget, cpu.rt_runtime_us)"};
}

Status affinity_warning(const std::string& thread, int cpu, int error) {
  return {StatusCode::system_error, "realtime.cpu",
          "pinning the " + thread + " thread to CPU " + std::to_string(cpu) + " failed (" +
              std::strerror(error) +
              "): it may run on any CPU; check [realtime] cpu against the CPUs of this machine "
              "and the process's cpuset"};
}

Status Thread::start(const std::string& name, std::function<void()> body, int priority, int cpu,
                     ThreadSetup& setup, std::size_t stack_bytes) {
  setup = ThreadSetup{};
  if (started_) return {StatusCode::already_started, "thread " + name + " already running"};
  body_ = std::make_unique<std::function<void()>>(std::move(body));
  pthread_attr_t attr;
  ::pthread_attr_init(&attr);
  ::pthread_attr_setstacksize(&attr, stack_bytes);
  const int error = ::pthread_create(&thread_, &attr, trampoline, body_.get());
  ::pthread_attr_destroy(&attr);
  if (error != 0) {
    return {
        StatusCode::system_error,
        "cannot create the " + name + " thread: " + std::strerror(error) +
            (error == EAGAIN ? " (with locked memory: is the memlock limit large enough?)" : "")};
  }
  started_ = true;
  ::pthread_setname_np(thread_, ("zerog-" + name).substr(0, 15).c_str());
  if (priority > 0) {
    sched_param param{};
    param.sched_priority = priority;
    setup.sched_error = ::pthread_setschedparam(thread_, SCHED_FIFO, &param);
  }
  if (cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(cpu, &set);
    setup.affinity_error = ::pthread_setaffinity_np(thread_, sizeof set, &set);
  }
  return {};
}

void Thread::join() {
  if (!started_) return;
  ::pthread_join(thread_, nullptr);
  started_ = false;
}

}  // namespace zerog::rt
