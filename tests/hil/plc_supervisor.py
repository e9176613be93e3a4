#!/usr/bin/env python3
"""The cell PLC of the HIL case `supervisor`, played by Debian's mbpoll (an independent Modbus TCP
client) against zerog-rt's Modbus server (proto/modbus.md):

  wait for the server and for `ready`; read the virtual mass; write a new one while idle (must be
  accepted and read back); enable zero-g with the coil; read the state (zero_g); write another
  mass during zero-g (must be refused with exception 06, busy) and read back the unchanged mass.

Every step (command line, exit status, output) goes to --out as JSON; check_hil.py judges it and
checks that the push then moved the part with the PLC's mass.
"""
import argparse
import json
import re
import subprocess
import sys
import time

STEPS = []


def mbpoll(host, port, args, values=()):
    cmd = ["mbpoll", "-m", "tcp", "-p", str(port), "-1", "-0"] + args + [host]
    if values:
        cmd += ["--"] + [str(v) for v in values]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=10)
    return r.returncode, r.stdout + r.stderr, " ".join(cmd)


def read_values(out):
    """mbpoll prints one `[ref]: \\tvalue` line per value."""
    return [int(v) for v in re.findall(r"^\[\d+\]:\s+(-?\d+)", out, re.M)]


def step(name, host, port, args, values=()):
    code, out, cmd = mbpoll(host, port, args, values)
    vals = read_values(out) if not values else []
    STEPS.append({"step": name, "command": cmd, "exit": code, "values": vals,
                  "output": out.strip().splitlines()[-3:], "t": time.monotonic()})
    return code, vals


def poll_until(name, host, port, args, done, deadline):
    """Reads until done(values) or the deadline; the last read is the step's result."""
    while True:
        code, vals = step(name, host, port, args)
        if (code == 0 and done(vals)) or time.monotonic() >= deadline:
            return vals
        time.sleep(0.05)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--mass-raw", type=int, default=80000, help="0.001 kg (proto/modbus.md)")
    ap.add_argument("--refused-mass-raw", type=int, default=50000)
    ap.add_argument("--timeout", type=float, default=20.0)
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    h, p = a.host, a.port
    result = {"ok": False}
    deadline = time.monotonic() + a.timeout
    # The server and the loop come up; `ready` (input register 3) once both sensors deliver.
    while time.monotonic() < deadline:
        code, out, _ = mbpoll(h, p, ["-t", "3", "-r", "3"])
        if code == 0 and read_values(out) == [1]:
            step("read ready", h, p, ["-t", "3", "-r", "3"])
            break
        time.sleep(0.2)
    else:
        result["error"] = "zerog-rt's Modbus server never reported ready"
    if "error" not in result:
        _, state0 = step("read state (idle)", h, p, ["-t", "3", "-r", "1"])
        _, mass0 = step("read mass", h, p, ["-t", "4:int", "-B", "-r", "0"])
        w1, _ = step("write mass while idle", h, p, ["-t", "4:int", "-B", "-r", "0"], [a.mass_raw])
        # As a PLC does: wait for the loop to take the write (proposal status no longer 1
        # pending), and for the state to follow the command, rather than read once and hope a
        # cycle has passed (the loop's cycles are the emulated rig's, not this script's clock).
        status1 = poll_until("read proposal status", h, p, ["-t", "3", "-r", "4"],
                             lambda v: v != [1], deadline)
        _, mass1 = step("read mass back", h, p, ["-t", "4:int", "-B", "-r", "0"])
        en, _ = step("enable zero-g (coil 0)", h, p, ["-t", "0", "-r", "0"], [1])
        state1 = poll_until("read state (zero_g)", h, p, ["-t", "3", "-r", "1"],
                            lambda v: v == [2], deadline)
        w2, _ = step("write mass during zero-g", h, p, ["-t", "4:int", "-B", "-r", "0"],
                     [a.refused_mass_raw])
        _, mass2 = step("read mass after the refusal", h, p, ["-t", "4:int", "-B", "-r", "0"])
        status2 = poll_until("read proposal status", h, p, ["-t", "3", "-r", "4"],
                             lambda v: v != [1], deadline)
        refusal = next(st["output"] for st in STEPS if st["step"] == "write mass during zero-g")
        result.update({
            "state_idle": state0, "mass_raw_before": mass0, "write_idle_exit": w1,
            "mass_raw_after_write": mass1, "proposal_status_after_write": status1,
            "enable_exit": en, "state_after_enable": state1, "write_zero_g_exit": w2,
            "write_zero_g_output": refusal, "mass_raw_after_refusal": mass2,
            "proposal_status_after_refusal": status2, "mass_raw_written": a.mass_raw,
            "mass_raw_refused": a.refused_mass_raw,
        })
        result["ok"] = True
    result["steps"] = STEPS
    with open(a.out, "w") as f:
        json.dump(result, f, indent=1)
    return 0 if result["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
