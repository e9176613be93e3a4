#!/usr/bin/env python3
"""The timing of one real-time HIL run (tests/hil/hil.sh --mode realtime): how long zerog-rt took
from a robot datagram to its reply, how long the cycle computed, how many replies the emulated
controller counted late or missing, how far the emulated rig fell behind the wall clock. A
benchmark, not a check: on a cabinet PC the figures are the real-time budget; on a shared machine
they say how loaded it was.

    tests/hil/timing.py RESULTS/push [--json OUT.json]
"""
import argparse
import json
import sys


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("case_dir", help="one case's results (rt.json, emu.json, check.json)")
    ap.add_argument("--json", help="also write the figures here")
    a = ap.parse_args()
    with open(f"{a.case_dir}/rt.json") as f:
        rt = json.load(f)
    with open(f"{a.case_dir}/emu.json") as f:
        emu = json.load(f)
    if "lockstep" in emu:
        sys.exit(f"timing.py: {a.case_dir} is a lockstep run: its wall-clock timing means nothing")
    cycle_ms = emu["cycle_s"] * 1e3
    reply, compute = rt["reply_latency_ns"], rt["compute_ns"]
    with open(f"{a.case_dir}/check.json") as f:
        check = json.load(f)
    out = {
        "cycle_ms": cycle_ms,
        "cycles": rt["cycles"]["messages"],
        "reply_latency_us": {k: reply[k] / 1e3 for k in ("median", "p99", "max")},
        "compute_us": {k: compute[k] / 1e3 for k in ("median", "p99", "max")},
        "datagrams_answered_window": check.get("datagrams_after_first_reply"),
        "replies_late": check.get("replies_late"),
        "replies_missing": check.get("replies_missing"),
        "rig_worst_lag_ms": emu["physics"]["worst_lag_s"] * 1e3,
    }
    print(f"real-time run ({out['cycles']} cycles of {cycle_ms:g} ms, wall clock):")
    print(f"  datagram -> reply  median {out['reply_latency_us']['median']:7.1f} us   "
          f"p99 {out['reply_latency_us']['p99']:7.1f} us   max {out['reply_latency_us']['max']:7.1f} us")
    print(f"  cycle compute      median {out['compute_us']['median']:7.1f} us   "
          f"p99 {out['compute_us']['p99']:7.1f} us   max {out['compute_us']['max']:7.1f} us")
    print(f"  of {out['datagrams_answered_window']} datagrams from zerog-rt's first reply to its "
          f"stop, the controller counted {out['replies_late']} answered late, "
          f"{out['replies_missing']} unanswered")
    print(f"  emulated rig's worst lag behind the wall clock {out['rig_worst_lag_ms']:.1f} ms")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(out, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
