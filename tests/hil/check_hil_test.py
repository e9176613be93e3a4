#!/usr/bin/env python3
"""check_hil.py's mode bands (mode_band_rows), on synthetic contact noise of 12-ms cycles:

  white   white noise of the floor's σ on every axis: every mode band holds its floor's share
          (within 20 %, 2,000 cycles, three seeds);
  ringing the same plus a 6 Hz sinusoid of amplitude 0.3 N on Fx and 0.06 N·m on My: A1's band
          (6 Hz) holds it (√(share² + A²/2 / 3), pooled over the three axes, within 10 %), the
          others stay at their share; a mode above the cycles' Nyquist (A4, 55 Hz) is left out;
  gap     a window with a gap: the longest stretch of consecutive cycles is the one measured.

Exits 1 naming the first failed check."""
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import check_hil  # noqa: E402

JOINTS = [{"mode_hz": 6.0}, {"mode_hz": 8.0}, {"mode_hz": 10.0}, {"mode_hz": 55.0},
          {"mode_hz": 23.0}, {"mode_hz": 50.0}]
DT = 0.012
FLOOR = np.array([0.15, 0.15, 0.15, 0.02, 0.02, 0.02])
failures = []


def expect(ok, what):
    print(f"{'ok  ' if ok else 'FAIL'}  {what}")
    if not ok:
        failures.append(what)


def bands(t, r):
    rows = check_hil.mode_band_rows(t, r, FLOOR, JOINTS)
    return {b["joint"]: b for b in rows}


for seed in (1, 2, 3):
    rng = np.random.default_rng(seed)
    n = 2000
    t = np.arange(n) * DT
    white = rng.normal(size=(n, 6)) * FLOOR
    b = bands(t, white)
    expect(sorted(b) == ["A1", "A2", "A3", "A5"],
           f"seed {seed}: the bands below Nyquist (41.7 Hz) only: {sorted(b)}")
    for j, row in b.items():
        for q in ("force_N", "torque_Nm"):
            ratio = row[q] / row[f"floor_{q}"]
            expect(abs(ratio - 1.0) < 0.2, f"seed {seed} white: {j} {q} at its floor's share "
                   f"({ratio:.2f}x)")
    ringing = white.copy()
    ringing[:, 0] += 0.3 * np.sin(2 * math.pi * 6.0 * t)
    ringing[:, 4] += 0.06 * np.sin(2 * math.pi * 6.0 * t + 0.4)
    b = bands(t, ringing)
    for q, amp in (("force_N", 0.3), ("torque_Nm", 0.06)):
        share = b["A1"][f"floor_{q}"]
        want = math.sqrt(share ** 2 + amp ** 2 / 2 / 3)
        got = b["A1"][q]
        expect(abs(got / want - 1.0) < 0.1, f"seed {seed} ringing: A1 {q} {got:.4f} "
               f"(expected {want:.4f})")
        for j in ("A2", "A3", "A5"):
            ratio = b[j][q] / b[j][f"floor_{q}"]
            expect(ratio < 1.25, f"seed {seed} ringing: {j} {q} stays near its share ({ratio:.2f}x)")
    # A gap: 300 cycles, then 50 missing, then 1,500: the 1,500 are measured (a ringing only in
    # them is seen at its full amplitude).
    tg = np.r_[np.arange(300), np.arange(350, 1850)] * DT
    rg = rng.normal(size=(len(tg), 6)) * FLOOR
    rg[300:, 0] += 0.3 * np.sin(2 * math.pi * 6.0 * tg[300:])
    b = bands(tg, rg)
    want = math.sqrt(b["A1"]["floor_force_N"] ** 2 + 0.3 ** 2 / 2 / 3)
    expect(abs(b["A1"]["force_N"] / want - 1.0) < 0.1,
           f"seed {seed} gap: the longest stretch measured (A1 force {b['A1']['force_N']:.4f}, "
           f"expected {want:.4f})")
expect(check_hil.mode_band_rows(np.arange(50) * DT, np.zeros((50, 6)), FLOOR, JOINTS) is None,
       "fewer than 64 consecutive cycles: not measured")

if failures:
    print(f"check_hil_test: {len(failures)} failed, first: {failures[0]}", file=sys.stderr)
    sys.exit(1)
print("check_hil_test: all passed")
