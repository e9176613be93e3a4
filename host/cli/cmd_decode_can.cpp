// zerog decode-can: recorded NETCANOEM traffic (candump text in any of its forms) → an F/T
// recording in N and N·m.
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "commands.hpp"
#include "zerog/formats/log.hpp"
#include "zerog/io/can_decode.hpp"

namespace zerog::cli {

void add_decode_can_command(CLI::App& app) {
  struct Args {
    std::string log, out;
    int base_id = 0x20;
    std::string timestamps = "auto";
    std::optional<double> assume_rate_hz;
    std::vector<double> thermistor;
  };
  auto a = std::make_shared<Args>();
  CLI::App* s = app.add_subcommand(
      "decode-can",
      "Decode candump text of an ATI NETCANOEM F/T sensor's bus into wrenches (N, N*m, sensor "
      "frame). Reads candump -L logs and candump's default output, with -ta, -tz, -td or -tA "
      "timestamps or none (then give --assume-rate); the form is detected (proto/candump.md). "
      "The calibration comes from the start-up read-out recorded in the log; other traffic on the "
      "bus is ignored; critical and saturated samples are dropped and counted. Writes an F/T "
      "recording (t_s, Fx_N .. Mz_Nm, status) that zerog import merges with pose and IMU files.");
  s->add_option("candump", a->log, "candump text: -L log or default output (-ta/-tz/-td/-tA)")
      ->required()
      ->check(CLI::ExistingFile);
  s->add_option("-o,--out", a->out, "F/T recording to write (CSV, atomically)")->required();
  s->add_option("--base-id", a->base_id,
                "The board's 7-bit CAN base id (CAN id = base << 4 | opcode)")
      ->check(CLI::Range(0, 0x7F))
      ->capture_default_str();
  s->add_option("--timestamps", a->timestamps,
                "How to read the timestamps: auto (detect), absolute (-L, -ta), zero (-tz), delta "
                "(-td), date (-tA), none")
      ->check(CLI::IsMember({"auto", "absolute", "zero", "delta", "date", "none"}))
      ->capture_default_str();
  s->add_option("--assume-rate", a->assume_rate_hz,
                "Sample rate of the sensor, Hz, for a log without timestamps (candump's default "
                "output): sample k gets t = k / HZ")
      ->check(CLI::PositiveNumber);
  s->add_option("--thermistor", a->thermistor,
                "Thermistor conversion (opcode 0x9, index 2): C_AT_0,C_PER_COUNT, i.e. degC at 0 "
                "counts and degC per count; adds temp_C. UNVERIFIED: no datasheet default, fit "
                "it on your sensor (proto/netcanoem.md). Without it: raw thermistor_counts only")
      ->expected(2)
      ->delimiter(',');
  s->callback([a] {
    io::CanDecodeOptions o;
    o.base_id = static_cast<std::uint8_t>(a->base_id);
    io::parse_candump_clock(a->timestamps, o.clock);
    o.assume_rate_hz = a->assume_rate_hz;
    if (!a->thermistor.empty())
      o.thermistor = proto::netcanoem::ThermistorConversion{a->thermistor[0], a->thermistor[1]};
    const io::CanDecodeResult r = io::decode_netcanoem_log(a->log, o);
    io::write_ft_recording(r, a->out, {a->log});
    const auto& c = r.counters;
    std::printf("%zu frames: %zu usable samples written to %s\n", r.records, r.samples.size(),
                a->out.c_str());
    std::printf(
        "format: %s; time: %s (%s)%s\n",
        r.log.form == io::CandumpForm::log ? "candump -L log file" : "candump default output",
        io::to_string(r.log.clock), r.log.clock_reason.c_str(),
        r.time_assumed ? ", times assumed from --assume-rate (t = k / rate)" : "");
    if (r.log.fd_frames > 0)
      std::printf("%zu CAN FD frames skipped (the sensor speaks classical CAN)\n", r.log.fd_frames);
    std::printf("calibration: %s, serial '%s', counts per force %u, per torque %u%s\n",
                r.calibration_from_log ? "read from the log" : "given",
                r.calibration.serial_number.data(), r.calibration.counts_per_force,
                r.calibration.counts_per_torque,
                r.calibration.counts_from_device ? "" : " (firmware before 3.7: default counts)");
    std::printf(
        "dropped: %zu unusable samples (%llu critical status, %llu saturated); %llu incomplete "
        "pairs, "
        "%llu out of order, %llu wrong length, %zu unconfirmed (a 0x1 lost); %zu frames of other "
        "ids ignored; %llu samples had their 0x1 overtaken (paired in order)\n",
        r.unusable, static_cast<unsigned long long>(c.critical),
        static_cast<unsigned long long>(c.saturated),
        static_cast<unsigned long long>(c.dropped_incomplete),
        static_cast<unsigned long long>(c.out_of_order),
        static_cast<unsigned long long>(c.wrong_length), r.unconfirmed, r.other_traffic,
        static_cast<unsigned long long>(c.overtaken));
    const io::DiagnosticCounters& d = r.diagnostic;
    if (d.requests > 0 || d.unrequested > 0 || d.wrong_length > 0) {
      std::printf(
          "thermistor (0x9, index 2): %zu readings%s; %zu requests, %zu answers of other channels "
          "and %zu of unknown indices ignored, %zu unanswered, %zu answers without a request, %zu "
          "of a wrong length\n",
          d.thermistor_readings,
          r.temperature_converted     ? ", temp_C written (conversion UNVERIFIED)"
          : d.thermistor_readings > 0 ? ", raw counts only (no --thermistor: no temp_C)"
                                      : "",
          d.requests, d.other_channel, d.unknown_index, d.unanswered, d.unrequested,
          d.wrong_length);
    }
  });
}

}  // namespace zerog::cli
