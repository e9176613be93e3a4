#!/usr/bin/env python3
"""The peer beside zerog-rt in the HIL fault cases that are not the rig's faults
(tests/hil/cases/fault_{modbus_flood,modbus_stall,dds_peer_gone,model_swap}.toml, started by
hil.sh through their `# plc = fault_peer.py` line). The case is the name of the folder of --out.

It plays the cell PLC over Modbus TCP with raw sockets (proto/modbus.md; no libraries): waits
for `ready`, enables zero-g with coil 0, reads the status registers, then injects its fault:

  modbus_flood   3 s of pipelined reads on every free connection, answered as fast as the server
                 goes, and connections beyond max_clients (closed at once by the server)
  modbus_stall   clients that send half a request and stop, one that connects and says nothing;
                 meanwhile the PLC's own connection must still be answered. Then a client that
                 pipelines requests and never reads the answers
  dds_peer_gone  the independent Python DDS subscriber (the repository's .venv) receives the
                 telemetry, then is killed with SIGKILL
  model_swap     the deployed model file is overwritten in place with other bytes, later replaced
                 by a rename of a truncated copy

Every step (zerog-rt's cycle count and status registers before and after, what the fault did)
goes to --out as JSON with "ok"; check_hil.py judges it together with zerog-rt's records.
"""
import argparse
import json
import os
import select
import signal
import socket
import struct
import subprocess
import sys
import time
import tomllib
import zlib

HOST = "127.0.0.1"
OUT = {"ok": False, "steps": []}


class ModbusError(Exception):
    pass


class Client:
    """One Modbus TCP connection (unit 1)."""

    def __init__(self, port, timeout=2.0):
        self.sock = socket.create_connection((HOST, port), timeout=timeout)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.tid = 0

    def close(self):
        self.sock.close()

    def fileno(self):
        return self.sock.fileno()

    def frame(self, pdu):
        self.tid = (self.tid + 1) & 0xFFFF
        return struct.pack(">HHHB", self.tid, 0, len(pdu) + 1, 1) + pdu

    def recv_exact(self, n):
        buf = b""
        while len(buf) < n:
            chunk = self.sock.recv(n - len(buf))
            if not chunk:
                raise ModbusError("the server closed the connection")
            buf += chunk
        return buf

    def read_reply(self):
        head = self.recv_exact(7)
        _, proto, length, _ = struct.unpack(">HHHB", head)
        if proto != 0 or length < 2:
            raise ModbusError(f"bad MBAP header {head.hex()}")
        return self.recv_exact(length - 1)

    def request(self, pdu):
        self.sock.sendall(self.frame(pdu))
        reply = self.read_reply()
        if reply[0] & 0x80:
            raise ModbusError(f"exception {reply[1]} to function {pdu[0]}")
        return reply

    def read_input_registers(self, addr, count):
        r = self.request(struct.pack(">BHH", 4, addr, count))
        return list(struct.unpack(f">{count}H", r[2:2 + 2 * count]))

    def read_discrete_inputs(self, addr, count):
        r = self.request(struct.pack(">BHH", 2, addr, count))
        bits = int.from_bytes(r[2:2 + r[1]], "little")
        return [(bits >> k) & 1 for k in range(count)]

    def write_coil(self, addr, on):
        self.request(struct.pack(">BHH", 5, addr, 0xFF00 if on else 0))


def u32(regs, a):
    return (regs[a] << 16) | regs[a + 1]


def status(c):
    """The input registers that the checks use (proto/modbus.md, register map)."""
    r = c.read_input_registers(0, 56)
    return {"t": time.monotonic(), "state": r[1], "fault": r[2], "ready": r[3],
            "modbus_clients": r[5], "cycle": u32(r, 6), "robot_lost": u32(r, 30),
            "datagrams_lost": u32(r, 32), "telemetry_dropped": u32(r, 36),
            "model_crc32": u32(r, 40), "modbus_requests": u32(r, 48),
            "modbus_clients_refused": u32(r, 54)}


def step(name, **values):
    values["step"] = name
    values.setdefault("t", time.monotonic())
    OUT["steps"].append(values)
    print(f"fault_peer: {name}: {json.dumps(values)}", flush=True)
    return values


def pause(ctl, seconds):
    """Wait as a PLC does: polling the status (a silent connection would be closed after the
    server's idle_timeout_s)."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        status(ctl)
        time.sleep(min(0.2, max(0.0, end - time.monotonic())))


def connect(port, deadline_s):
    end = time.monotonic() + deadline_s
    while True:
        try:
            return Client(port)
        except OSError:
            if time.monotonic() > end:
                raise
            time.sleep(0.1)


def enable_zero_g(c):
    """Waits for `ready` and enables zero-g. A fault raised in idle before that (under qemu a
    start-up stall of the guest can starve a sensor thread for 60 ms) is reset with coil 2 first,
    as a PLC would, and recorded: the checks judge only what comes after the enable."""
    end = time.monotonic() + 40.0
    resets = []
    while True:
        s = status(c)
        if s["state"] == 3 and len(resets) < 5:
            resets.append({"cycle": s["cycle"], "fault": s["fault"]})
            c.write_coil(2, True)
            time.sleep(0.2)
            continue
        if s["ready"] == 1:
            try:
                c.write_coil(0, True)
            except ModbusError:  # refused (exception 04) while a sensor holds: try again
                pass
            s = status(c)
            if s["state"] == 2:
                return step("enabled", startup_resets=resets, **s)
        if time.monotonic() > end:
            raise ModbusError(f"zero-g not enabled (state {s['state']}, fault {s['fault']}, "
                              f"resets {resets})")
        time.sleep(0.1)


# --- the faults -------------------------------------------------------------------------------

def flood(port, ctl, seconds=3.0, depth=16):
    """Pipelined reads of the first 56 input registers on 3 connections (the 4th slot is the PLC's)."""
    conns = [Client(port) for _ in range(3)]
    for c in conns:
        c.sock.setblocking(False)
    req = struct.pack(">BHH", 4, 0, 56)
    sent = received = refused_conns = extra_conns = plc_reads = 0
    pending = {c: 0 for c in conns}
    inbox = {c: b"" for c in conns}
    t0 = time.monotonic()
    next_extra = t0
    while time.monotonic() - t0 < seconds:
        for c in conns:
            if pending[c] == 0:
                c.sock.sendall(b"".join(c.frame(req) for _ in range(depth)))
                pending[c] = depth
                sent += depth
        ready, _, _ = select.select(conns, [], [], 0.05)
        for c in ready:
            data = c.sock.recv(65536)
            if not data:
                raise ModbusError("the server closed a flooding connection")
            inbox[c] += data
            while len(inbox[c]) >= 6:
                length = struct.unpack(">H", inbox[c][4:6])[0]
                if len(inbox[c]) < 6 + length:
                    break
                inbox[c] = inbox[c][6 + length:]
                pending[c] -= 1
                received += 1
        if time.monotonic() >= next_extra:  # one more than max_clients: closed at once
            next_extra += 0.2
            status(ctl)  # and the PLC is still answered
            plc_reads += 1
            extra_conns += 1
            try:
                x = socket.create_connection((HOST, port), timeout=0.3)
                try:
                    closed = x.recv(16) == b""
                except ConnectionResetError:
                    closed = True
                except OSError:  # still open after 0.3 s: not refused
                    closed = False
                x.close()
            except OSError:
                closed = True
            refused_conns += closed
    elapsed = time.monotonic() - t0
    for c in conns:
        c.close()
    return step("flood", requests_sent=sent, replies_received=received, seconds=elapsed,
                replies_per_s=received / elapsed, plc_reads_answered=plc_reads,
                extra_connections=extra_conns,
                extra_connections_closed_at_once=refused_conns, after=status(ctl))


def stall(port, ctl):
    """Two half requests and one silent connection take the 3 free slots; the PLC keeps
    reading meanwhile. Then a client that never reads its answers."""
    half = [Client(port) for _ in range(2)]
    silent = Client(port)
    for c in half:
        c.sock.sendall(c.frame(struct.pack(">BHH", 4, 0, 56))[:5])
    t0 = time.monotonic()
    answered = 0
    while time.monotonic() - t0 < 0.4:  # before the request timeout (0.5 s)
        status(ctl)
        answered += 1
        time.sleep(0.02)
    closed_at = {}
    for name, c in [("half_1", half[0]), ("half_2", half[1]), ("silent", silent)]:
        c.sock.settimeout(5.0)
        try:
            data = c.sock.recv(64)
            closed_at[name] = round(time.monotonic() - t0, 3) if data == b"" else f"got {data.hex()}"
        except OSError as e:
            closed_at[name] = f"not closed ({e})"
        c.close()
    step("stall", plc_reads_answered_during_stall=answered, closed_after_s=closed_at,
         after=status(ctl))
    # A client that pipelines requests and never reads.
    deaf = Client(port)
    deaf.sock.setblocking(False)
    req = deaf.frame(struct.pack(">BHH", 4, 0, 56))
    sent = 0
    t0 = time.monotonic()
    answered = 0
    while time.monotonic() - t0 < 2.0:
        try:
            sent += deaf.sock.send(req * 64) // len(req)
        except BlockingIOError:
            pass
        except OSError:
            break
        status(ctl)
        answered += 1
    deaf.close()
    return step("deaf", requests_sent=sent, plc_reads_answered=answered, after=status(ctl))


def dds_peer_gone(w, here, ctl, sub):
    """The subscriber (started before zero-g) has received telemetry; kill it, go on."""
    out = f"{w}/telemetry.jsonl"
    # Up (its readers exist), then received: the subscriber's output is block-buffered, so bytes
    # in the file mean a few hundred samples came.
    end = time.monotonic() + 15.0
    while not os.path.exists(f"{w}/telemetry.ready") and time.monotonic() < end:
        if sub.poll() is not None:
            break
        pause(ctl, 0.2)
    end = time.monotonic() + 8.0
    size = 0
    while time.monotonic() < end and sub.poll() is None:
        size = os.path.getsize(out) if os.path.exists(out) else 0
        if size > 0:
            break
        pause(ctl, 0.2)
    lines = size
    before = status(ctl)
    alive = sub.poll() is None
    if alive:
        os.kill(sub.pid, signal.SIGKILL)
    sub.wait()
    step("killed", subscriber_was_running=alive, bytes_received=lines, before=before)
    pause(ctl, 4.0)
    return step("after", after=status(ctl))


def model_swap(w, ctl):
    path = f"{w}/model.zgm"
    with open(path, "rb") as f:
        original = f.read()
    crc = zlib.crc32(original)
    before = status(ctl)
    step("loaded", file_crc32=crc, register_crc32=before["model_crc32"], before=before)
    # 1: overwritten in place (a careless copy onto the running file), other bytes, same size.
    with open(path, "r+b") as f:
        f.write(bytes(b ^ 0x5A for b in original))
        f.flush()
        os.fsync(f.fileno())
    with open(path, "rb") as f:
        crc1 = zlib.crc32(f.read())
    step("overwritten", file_crc32=crc1)
    pause(ctl, 2.0)
    s1 = step("after_overwrite", **status(ctl))
    # 2: replaced by a rename (a new deployment): half of the original file.
    tmp = f"{path}.new"
    with open(tmp, "wb") as f:
        f.write(original[:len(original) // 2])
    os.replace(tmp, path)
    with open(path, "rb") as f:
        crc2 = zlib.crc32(f.read())
    step("replaced", file_crc32=crc2)
    pause(ctl, 2.0)
    s2 = step("after_replace", **status(ctl))
    return crc, crc1, crc2, s1, s2


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    w = os.path.dirname(os.path.abspath(a.out))
    here = os.path.dirname(os.path.abspath(__file__))
    mode = os.path.basename(w).removeprefix("fault_")
    OUT["mode"] = mode
    sub = None
    try:
        if mode == "dds_peer_gone":
            with open(f"{w}/zerog-rt.toml", "rb") as f:
                domain = tomllib.load(f)["telemetry"]["domain_id"]
            py = os.path.join(here, "..", "..", ".venv", "bin", "python")
            sub = subprocess.Popen(
                [py, os.path.join(here, "..", "telemetry", "dds_subscriber.py"), "--domain",
                 str(domain), "--interface", "lo", "--peer", "127.0.0.1", "--no-multicast",
                 "--duration", "60", "--out", f"{w}/telemetry.jsonl",
                 "--ready", f"{w}/telemetry.ready"],
                stdout=subprocess.DEVNULL, stderr=open(f"{w}/telemetry.err", "w"))
            step("subscriber_started", pid=sub.pid, domain=domain)
        ctl = connect(a.port, 40.0)
        enable_zero_g(ctl)
        pause(ctl, 1.0)
        step("before", **status(ctl))
        if mode == "modbus_flood":
            flood(a.port, ctl)
        elif mode == "modbus_stall":
            stall(a.port, ctl)
        elif mode == "dds_peer_gone":
            dds_peer_gone(w, here, ctl, sub)
        elif mode == "model_swap":
            model_swap(w, ctl)
        else:
            raise ModbusError(f"no fault '{mode}' (folder {w})")
        pause(ctl, 0.5)
        step("end", **status(ctl))
        ctl.close()
        OUT["ok"] = True
    except (OSError, ModbusError) as e:
        OUT["error"] = f"{type(e).__name__}: {e}"
        print(f"fault_peer: {OUT['error']}", file=sys.stderr)
    finally:
        if sub is not None and sub.poll() is None:
            sub.kill()
            sub.wait()
    tmp = a.out + ".tmp"
    with open(tmp, "w") as f:
        json.dump(OUT, f, indent=1)
    os.replace(tmp, a.out)
    return 0 if OUT["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
