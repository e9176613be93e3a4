#include <string>

#include "zerog/rt/runtime.hpp"

namespace zerog::rt {

namespace {

std::string transition_text(const loop::Transition& t) {
  return std::string(loop::state_name(t.from)) + " -> " + loop::state_name(t.to) + " (" +
         (t.by_fault ? std::string("fault ") + loop::fault_name(t.fault)
                     : std::string(loop::command_name(t.command))) +
         ")";
}

}  // namespace

SupervisorEvents StatusAnnouncer::update(const CycleStatus& s) {
  SupervisorEvents ev;
  if (s.transitions != transitions_seen_) {
    if (s.transitions > transitions_seen_ + 1) {
      ev.err.push_back("zerog-rt: " + std::to_string(s.transitions - transitions_seen_ - 1) +
                       " more state transitions (in the summary)");
    }
    ev.err.push_back("zerog-rt: cycle " + std::to_string(s.last_transition.cycle) + ": " +
                     transition_text(s.last_transition));
    transitions_seen_ = s.transitions;
  }
  if (auto_pending()) {
    const loop::State target = auto_enable_zero_g_ ? loop::State::zero_g : loop::State::collecting;
    if (s.state == target) {
      const std::uint64_t at = s.last_transition.to == target ? s.last_transition.cycle : s.cycle;
      ev.out.push_back(std::string("zerog-rt: ") +
                       (auto_enable_zero_g_ ? "zero-g enabled" : "collection started") +
                       " at cycle " + std::to_string(at));
      auto_done_ = true;
    } else if (s.state == loop::State::fault) {
      ev.err.push_back(std::string("zerog-rt: ") +
                       (auto_enable_zero_g_ ? "--enable-zero-g" : "--collect") +
                       " gave up: fault " + loop::fault_name(s.fault) + " before it started");
      auto_gave_up_ = true;
    }
  }
  // In zero-g, the rows on which no push is confirmed yet (the motion estimator settling, the
  // contact's tare being taken: proto/loop.md): said when seen, and when they end. The
  // statuses are sampled, so a short spell may pass unsaid, and the cycle is the status's.
  if (s.state != loop::State::zero_g) {
    untrusted_said_ = false;
  } else if ((s.flags & (loop::kEstimatorSettling | loop::kContactTaring)) != 0) {
    if (!untrusted_said_) {
      const bool settling = (s.flags & loop::kEstimatorSettling) != 0;
      const bool taring = (s.flags & loop::kContactTaring) != 0;
      ev.out.push_back(std::string("zerog-rt: zero-g: hands off the part, no push is taken yet (") +
                       (settling ? "the motion estimator settling" : "") +
                       (settling && taring ? ", then " : "") +
                       (taring ? "the contact's tare" : "") + ")");
      untrusted_said_ = true;
    }
  } else if (untrusted_said_) {
    ev.out.push_back("zerog-rt: zero-g: the part takes pushes from cycle " +
                     std::to_string(s.cycle));
    untrusted_said_ = false;
  }
  if (s.commands_refused != refused_seen_) {
    refused_seen_ = s.commands_refused;
    ev.err.push_back(std::string("zerog-rt: command refused in state ") +
                     loop::state_name(s.state) + " (proto/states.md)");
  }
  if (s.collections_done != collections_seen_) {
    collections_seen_ = s.collections_done;
    ev.out.push_back("zerog-rt: collection finished at cycle " + std::to_string(s.cycle));
    if (auto_collect_) collection_finished_ = true;
  }
  return ev;
}

}  // namespace zerog::rt
