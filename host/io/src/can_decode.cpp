#include "zerog/io/can_decode.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "zerog/formats/log.hpp"
#include "zerog/io/candump.hpp"

namespace zerog::io {

using formats::InputError;
using formats::write_file_atomic;

namespace nc = proto::netcanoem;

namespace {

// Follows the recorded start-up read-out passively: a matrix-row request (opcode 0x2 with one
// byte) announces the row of the next three responses 0x2, 0x3, 0x4.
struct CalibrationTracker {
  std::uint8_t base_id;
  nc::Calibration cal;
  int row = -1;
  std::array<std::array<bool, 3>, nc::kGaugeCount> seen{};
  bool units = false;

  void feed(const proto::CanFrame& f) {
    if (nc::base_id_of(f.id) != base_id) return;
    const auto op = nc::opcode_of(f.id);
    if (op == static_cast<std::uint8_t>(nc::Opcode::matrix_sg01) && f.len == 1) {
      row = f.data[0] < nc::kGaugeCount ? f.data[0] : -1;
      return;
    }
    if (op >= 0x2 && op <= 0x4 && f.len == nc::kMatrixPartLength && row >= 0) {
      std::array<double, 2> c{};
      const int part = op - 0x2;
      if (nc::decode_matrix_part(f, base_id, part, c) == nc::DecodeStatus::ok) {
        cal.matrix[row][2 * part] = c[0];
        cal.matrix[row][2 * part + 1] = c[1];
        seen[row][part] = true;
      }
      return;
    }
    if (op == static_cast<std::uint8_t>(nc::Opcode::counts) && f.len == nc::kCountsLength) {
      if (nc::decode_counts(f, base_id, cal.counts_per_force, cal.counts_per_torque) ==
          nc::DecodeStatus::ok)
        cal.counts_from_device = true;
      return;
    }
    if (op == static_cast<std::uint8_t>(nc::Opcode::units) && f.len == nc::kUnitsLength) {
      units = nc::decode_units(f, base_id, cal.force_unit, cal.torque_unit) == nc::DecodeStatus::ok;
    }
  }
  bool complete() const {
    for (const auto& r : seen)
      for (bool b : r)
        if (!b) return false;
    return units;
  }
};

// Pairs the board's 0x9 requests with their answers: the request names the channel, the answer
// that follows is its reading (the answer does not carry the index).
struct DiagnosticTracker {
  std::uint8_t base_id;
  DiagnosticCounters& counters;
  std::vector<ThermistorReading>& readings;
  int open_index = -1;  // index of the request waiting for its answer, -1: none

  void feed(const proto::CanFrame& f, double t_s) {
    if (f.id != nc::can_id(base_id, nc::Opcode::diagnostic_adc)) return;
    if (f.len == nc::kDiagnosticRequestLength) {
      if (open_index >= 0) ++counters.unanswered;
      ++counters.requests;
      if (f.data[0] > nc::kMaxDiagnosticIndex) ++counters.unknown_index;
      open_index = f.data[0];
      return;
    }
    std::uint16_t counts = 0;
    if (nc::decode_diagnostic_adc(f, base_id, counts) != nc::DecodeStatus::ok) {
      ++counters.wrong_length;
      return;
    }
    const int index = open_index;
    open_index = -1;
    if (index < 0) {
      ++counters.unrequested;
    } else if (index == static_cast<int>(nc::DiagnosticIndex::thermistor)) {
      ++counters.thermistor_readings;
      readings.push_back({t_s, counts});
    } else if (index <= nc::kMaxDiagnosticIndex) {
      ++counters.other_channel;
    }  // an unknown index: counted at its request
  }
};

}  // namespace

CanDecodeResult decode_netcanoem_log(const std::filesystem::path& candump,
                                     const CanDecodeOptions& o) {
  std::ifstream in(candump);
  if (!in) throw InputError(candump, 0, 0, "cannot open");
  std::vector<io::CandumpRecord> records;
  io::CandumpError error;
  CanDecodeResult r;
  if (!io::parse_candump(in, proto::CanFilter{}, records, error, &r.log, o.clock))
    throw InputError(candump, error.line, error.column, error.reason);
  if (o.assume_rate_hz && !(*o.assume_rate_hz > 0.0 && std::isfinite(*o.assume_rate_hz)))
    throw std::runtime_error("--assume-rate must be a positive rate in Hz");
  if (r.log.clock == io::CandumpClock::none && !records.empty() && !o.assume_rate_hz)
    throw std::runtime_error(
        candump.string() + ": the log has no timestamps (" + r.log.clock_reason +
        "), so the wrenches would have no time. Give the sensor's sample rate with --assume-rate "
        "HZ (each complete sample k gets t = k / HZ; gaps in the recording then shift the "
        "times), or record again with timestamps: candump -L, or candump -ta");
  if (r.log.clock != io::CandumpClock::none && o.assume_rate_hz)
    throw std::runtime_error(candump.string() + ": the log has timestamps (" + r.log.clock_reason +
                             "): drop --assume-rate");
  r.time_assumed = r.log.clock == io::CandumpClock::none;

  r.records = records.size();
  CalibrationTracker tracker{o.base_id, {}, -1, {}, false};
  for (const auto& rec : records)
    if (!rec.fd) tracker.feed(rec.frame);
  if (o.calibration) {
    r.calibration = *o.calibration;
  } else if (tracker.complete()) {
    r.calibration = tracker.cal;
    r.calibration_from_log = true;
  } else {
    throw std::runtime_error(
        candump.string() + ": the log holds no complete calibration read-out of board 0x" +
        [&] {
          char b[8];
          std::snprintf(b, sizeof b, "%02X", o.base_id);
          return std::string(b);
        }() +
        " (matrix rows 0x2-0x4 and units 0x8): record the bus from before the sensor's start-up "
        "(zerog-rt reads the calibration at every start)");
  }
  if (o.thermistor && !nc::thermistor_conversion_valid(*o.thermistor))
    throw std::runtime_error(
        "--thermistor: both numbers must be finite and the °C per count must not be 0");
  if (!nc::newton_per_force_unit(r.calibration.force_unit) ||
      !nc::newton_metre_per_torque_unit(r.calibration.torque_unit))
    throw std::runtime_error(candump.string() + ": unknown force/torque unit codes " +
                             std::to_string(r.calibration.force_unit) + "/" +
                             std::to_string(r.calibration.torque_unit));

  // Pairing in order (SampleAssembler): a 0x1 overtaken by later 0x0 frames still completes
  // its own 0x0. A pairing made while later halves wait is confirmed once the queue of waiting
  // halves empties again; if it does not within kMaxUnconfirmedRun pairings (or before the log
  // ends), some 0x1 was lost and the run may pair halves of different polls: its samples are
  // dropped (counted `unconfirmed`) and the waiting halves with them.
  nc::SampleAssembler assembler(o.base_id);
  std::size_t complete = 0;  // complete samples, usable or not (the clock of assume_rate_hz)
  std::vector<std::pair<double, nc::GaugeSample>> run;  // paired, not yet confirmed
  auto commit = [&](double t_s, const nc::GaugeSample& g) {
    if (!g.usable()) {
      ++r.unusable;
      return;
    }
    const auto w = nc::gauges_to_wrench_si(r.calibration, g.gauges, o.bias_gauges);
    r.samples.push_back({t_s, *w, g.status, std::nullopt, std::nullopt});
  };
  DiagnosticTracker diagnostic{o.base_id, r.diagnostic, r.thermistor, -1};
  for (const auto& rec : records) {
    if (rec.fd) continue;  // CAN FD traffic: counted in r.log.fd_frames
    if (nc::base_id_of(rec.frame.id) != o.base_id) {
      ++r.other_traffic;
      continue;
    }
    if (nc::opcode_of(rec.frame.id) == static_cast<std::uint8_t>(nc::Opcode::diagnostic_adc)) {
      // Never gauge data. Without timestamps a reading gets the time of the samples so far.
      const double t_s = r.time_assumed ? static_cast<double>(complete) / *o.assume_rate_hz
                                        : static_cast<double>(rec.timestamp_ns) * 1e-9;
      diagnostic.feed(rec.frame, t_s);
      continue;
    }
    nc::GaugeSample g;
    if (assembler.feed(rec.frame, g) != nc::FeedResult::sample) continue;
    const double t_s = r.time_assumed ? static_cast<double>(complete) / *o.assume_rate_hz
                                      : static_cast<double>(rec.timestamp_ns) * 1e-9;
    ++complete;
    run.emplace_back(t_s, g);
    if (!assembler.pending()) {  // every half paired: the run is confirmed
      for (const auto& [t, s] : run) commit(t, s);
      run.clear();
    } else if (run.size() > kMaxUnconfirmedRun) {
      r.unconfirmed += run.size();
      run.clear();
      assembler.drop_pending_before(std::numeric_limits<std::uint64_t>::max());
    }
  }
  r.unconfirmed += run.size();  // the log ended with halves still waiting
  r.counters = assembler.counters();

  // Each sample gets the latest thermistor reading at or before it; those before the first
  // reading get the first (zerog-rt reads it with its first poll, then about once a second: the
  // temperature moves far less in that time than the conversion is uncertain).
  std::size_t next = 0;
  for (DecodedWrench& s : r.samples) {
    if (r.thermistor.empty()) break;
    while (next + 1 < r.thermistor.size() && r.thermistor[next + 1].t_s <= s.t_s) ++next;
    s.thermistor_counts = r.thermistor[next].counts;
    if (o.thermistor) s.temperature_C = nc::thermistor_celsius(*o.thermistor, *s.thermistor_counts);
  }
  r.temperature_converted = o.thermistor.has_value() && !r.thermistor.empty();
  return r;
}

void write_ft_recording(const CanDecodeResult& r, const std::filesystem::path& out,
                        const std::vector<std::filesystem::path>& inputs) {
  std::ostringstream os;
  os << "# zerog-ft 1: F/T samples decoded from CAN by zerog decode-can (sensor frame, N and "
        "N*m)\n";
  const bool counts = !r.thermistor.empty();
  const bool celsius = counts && r.temperature_converted;
  if (counts && !celsius) {
    os << "# thermistor_counts: raw 0x9 readings (diagnostic index 2); no temp_C without a "
          "conversion (--thermistor, proto/netcanoem.md)\n";
  }
  os << "t_s,Fx_N,Fy_N,Fz_N,Mx_Nm,My_Nm,Mz_Nm,status" << (counts ? ",thermistor_counts" : "")
     << (celsius ? ",temp_C" : "") << "\n";
  char line[256];
  for (const auto& s : r.samples) {
    int n = std::snprintf(line, sizeof line, "%.6f,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%u", s.t_s,
                          s.wrench[0], s.wrench[1], s.wrench[2], s.wrench[3], s.wrench[4],
                          s.wrench[5], static_cast<unsigned>(s.status));
    if (counts) {
      n += std::snprintf(line + n, sizeof line - static_cast<std::size_t>(n), ",%u",
                         static_cast<unsigned>(s.thermistor_counts.value_or(0)));
    }
    if (celsius) {
      std::snprintf(line + n, sizeof line - static_cast<std::size_t>(n), ",%.4f",
                    s.temperature_C.value_or(0.0));
    }
    os << line << "\n";
  }
  write_file_atomic(out, os.str(), inputs);
}

}  // namespace zerog::io
