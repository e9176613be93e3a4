#!/usr/bin/env python3
"""Writes the small synthetic recordings of the `zerog import` worked example.

Three files as a user's own rig might produce them, 0.2 s of a KR 210 turning axis A1 at
20 deg/s with a 100 kg payload (centre of mass 10 mm off the sensor axis, 150 mm out):
  wrench_1khz.csv  F/T sensor, 1 kHz, comma separated, time in microseconds, N and N*mm
  imu_2khz.csv     IMU, 2 kHz, semicolon separated with decimal commas, time in ms, g, deg/s;
                   its clock runs 1.5 ms ahead of the sensor's (time_offset_s = -0.0015)
  robot_83hz.txt   robot pose and joints, 83.33 Hz (12 ms), whitespace separated, s, deg, mm;
                   the pose is the flange's (KUKA X Y Z A B C), starting 4 ms after the sensor
Run it from this folder: python3 make_example.py
"""
import math

G = 9.80665
MASS_KG = 100.0
COM_M = (0.01, 0.0, 0.15)
RATE_DEG_S = 20.0
A1_0_DEG = 10.0
DURATION_S = 0.2


def a1_deg(t):
    return A1_0_DEG + RATE_DEG_S * t


def wrench(t):
    # Flange (and sensor) axes: Rz(A) * Rx(180 deg): tool pointing down, gravity along +z_S.
    wiggle = 2.0 * math.sin(2 * math.pi * 5.0 * t)  # a slow 5 Hz wiggle of the payload, N
    force = (1.5, -0.8, MASS_KG * G + wiggle)
    cx, cy, cz = COM_M
    fx, fy, fz = force
    torque = (cy * fz - cz * fy, cz * fx - cx * fz, cx * fy - cy * fx)
    return force, torque


with open("wrench_1khz.csv", "w") as out:
    out.write("# F/T sensor export (synthetic example for zerog import)\n")
    out.write("time_us,Fx_N,Fy_N,Fz_N,Tx_Nmm,Ty_Nmm,Tz_Nmm,sensor_temp_C\n")
    for i in range(int(DURATION_S * 1000)):
        t = i / 1000.0
        f, m = wrench(t)
        out.write("%d,%.4f,%.4f,%.4f,%.2f,%.2f,%.2f,%.2f\n"
                  % (i * 1000, *f, *(1000 * v for v in m), 31.5 + 2.0 * t))

with open("imu_2khz.csv", "w") as out:
    out.write("t_ms;acc_x_g;acc_y_g;acc_z_g;gyr_x_dps;gyr_y_dps;gyr_z_dps\n")
    for i in range(int(DURATION_S * 2000) + 4):
        t_imu_ms = 0.5 * i  # IMU clock; sensor time = IMU time - 1.5 ms
        row = (t_imu_ms, 0.0, 0.0, -1.0, 0.0, 0.0, -RATE_DEG_S)
        out.write(";".join(("%.4f" % v).replace(".", ",") for v in row) + "\n")

with open("robot_83hz.txt", "w") as out:
    out.write("# KUKA RSI log, flange pose in the base frame\n")
    out.write("t_s   A1      A2      A3     A4    A5     A6    X_mm      Y_mm      Z_mm    "
              "A_deg   B_deg  C_deg\n")
    t = 0.004
    while t < DURATION_S - 0.01:
        a1 = a1_deg(t)
        x = 1800.0 * math.cos(math.radians(a1))
        y = 1800.0 * math.sin(math.radians(a1))
        out.write("%.3f %7.3f %7.3f %6.3f %5.3f %6.3f %5.3f %9.3f %9.3f %8.3f %7.3f %6.3f %6.3f\n"
                  % (t, a1, -90.0, 90.0, 0.0, 30.0, 0.0, x, y, 1500.0, a1, 0.0, 180.0))
        t += 0.012
