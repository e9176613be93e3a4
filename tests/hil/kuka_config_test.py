#!/usr/bin/env python3
"""The KUKA side against zerog-rt (issue 27, "The KUKA side"; firmware/rt/deploy/kuka/README.md).

Reads the shipped RSI Ethernet configuration (zerog_rsi_ethernet.xml) and checks it against the
real zerog-rt over real UDP:

  static  the file's structure (CONFIG, SEND, RECEIVE, every ELEMENT's TAG/TYPE/INDX/HOLDON);
          CONFIG's IP_NUMBER, PORT, SENTYPE equal [robot] bind_address, bind_port, sensor_type of
          firmware/rt/zerog-rt.sample.toml; every SEND element is one zerog-rt reads
          (proto/rsi.md) and AIPos is there; with --context, the RSI 3.x context names this file
          and wires RECEIVE's RKorr.X..C into POSCORR's CorrX..CorrC.
  live    plays the controller: builds a <Rob> datagram from the SEND list (every element, values
          of the configured TYPE, the IPOC the controller adds itself), sends one every cycle to
          zerog-rt (fed with F/T and IMU samples by zerog-emu, whose own robot talks to a socket
          nobody reads) and checks that every datagram is answered, and that each reply is
          <Sen Type=SENTYPE> with exactly the RECEIVE list's elements and attributes (DOUBLE
          values as numbers) and the datagram's IPOC; zerog-rt's summary must show every datagram
          read, none malformed, no pose taken from the joints when RIst is sent.

A configuration whose RECEIVE list is the axis correction AKorr.A1..A6 (zerog_rsi_collect_ethernet.xml,
--config) is the calibration collection's: zerog-rt is then started with --collect on a zerog
design, its context (zerog_rsi_collect.rsi.xml) must wire AKorr into AXISCORR, every reply must
be AKorr (zeros before the approach starts), some must move the axes, and zerog-rt's summary must
count every reply as an axis reply.

--mutant send|receive runs the same check on a copy of the file with one element renamed
(send: DEF_AIPos -> DEF_ASPos, the set-point that zerog-rt skips; receive: RKorr -> RKor, or
AKorr -> AKor, on the six correction TAGs) and passes only if the check fails with that
element's mismatch named.

Exit 0 on success, 1 on a failed check, 2 on a usage or set-up error (a program missing, the
emulator not coming up). Run by ctest (tests/hil/CMakeLists.txt: hil_kuka_config,
hil_kuka_config_mutant_send, hil_kuka_config_mutant_receive, hil_kuka_config_collect,
hil_kuka_config_collect_mutant_receive).
"""
import argparse
import json
import os
import pathlib
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import tomllib
import xml.etree.ElementTree as ET
import xml.parsers.expat

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent.parent
KUKA_DIR = ROOT / "firmware/rt/deploy/kuka"
DEFAULT_CONFIG = KUKA_DIR / "zerog_rsi_ethernet.xml"
DEFAULT_CONTEXT = KUKA_DIR / "zerog_rsi.rsi.xml"
SAMPLE_TOML = ROOT / "firmware/rt/zerog-rt.sample.toml"
RT_TEMPLATE = HERE / "cases/zerog-rt.base.toml"
SCENARIO = HERE / "cases/drift.toml"  # cycle_ms = 12; the emulator only feeds the sensors here

CYCLE_MS = 12
DATAGRAMS = 150  # 1.8 s of 12 ms cycles

# The controller's built-in SEND elements (TAG "DEF_<name>", INDX "INTERNAL") and what each
# writes into the datagram. The names and attributes are those of the public drivers' parsers and
# simulators (ros-industrial/kuka_experimental kuka_rsi_hw_interface/include/kuka_rsi_hw_interface/
# rsi_state.h and kuka_rsi_simulator; kroshu/kuka_drivers kuka_rsi_driver/scripts/
# generate_krc_rsi_config.py: "RIst -> DEF_RIst, AIPos -> DEF_AIPos, EIPos -> DEF_EIPos", Delay
# as <Delay D=".."/>) and of proto/rsi.md's examples. An unknown DEF_ name is an error here:
# add it with a source rather than guess its attributes.
POSE = ("X", "Y", "Z", "A", "B", "C")
AXES = tuple(f"A{i}" for i in range(1, 7))
EXTERNAL = tuple(f"E{i}" for i in range(1, 7))
BUILTIN_SEND = {
    "RIst": POSE,  # actual TCP pose
    "RSol": POSE,  # commanded TCP pose
    "AIPos": AXES,  # actual axis angles
    "ASPos": AXES,  # commanded axis angles
    "EIPos": EXTERNAL,  # actual external axes
    "Delay": ("D",),  # late packets
}
# What zerog-rt reads of a <Rob> message (proto/rsi.md, "Controller -> zerog"): everything else is
# skipped, so a SEND element outside this set is a configuration zerog-rt silently ignores.
ZEROG_READS = {"RIst", "AIPos", "EIPos", "Delay"}
ZEROG_REQUIRES = {"AIPos"}  # and IPOC, which the controller always adds
TYPES = {"BOOL", "STRING", "LONG", "DOUBLE"}  # the comment in kuka_experimental's ros_rsi_ethernet.xml
# What zerog-rt answers (proto/rsi.md) and the RSI 3.x object that takes it, inputs 1..6 in this
# order (cjlh's POSCORR context; kuka_experimental's ros_rsi.rsi.xml for AXISCORR).
CORRECTIONS = {"RKorr": ("POSCORR", POSE), "AKorr": ("AXISCORR", AXES)}


class SetupError(Exception):
    pass


# ------------------------------------------------------------------ the configuration file
class Element:
    def __init__(self, section, line, attrs):
        self.section, self.line, self.attrs = section, line, attrs
        self.tag = attrs.get("TAG", "")
        self.type = attrs.get("TYPE", "")
        self.indx = attrs.get("INDX", "")
        self.holdon = attrs.get("HOLDON")


def read_config(path):
    """The CONFIG values and the SEND/RECEIVE ELEMENTs with their line numbers."""
    config, elements, stack, text = {}, [], [], []
    parser = xml.parsers.expat.ParserCreate()

    def start(name, attrs):
        stack.append(name)
        text.clear()
        if name == "ELEMENT":
            section = stack[-3] if len(stack) >= 3 else "?"
            elements.append(Element(section, parser.CurrentLineNumber, attrs))

    def end(name):
        if len(stack) >= 2 and stack[-2] == "CONFIG":
            config[name] = ("".join(text).strip(), parser.CurrentLineNumber)
        stack.pop()
        text.clear()

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = text.append
    try:
        parser.Parse(pathlib.Path(path).read_bytes(), True)
    except xml.parsers.expat.ExpatError as e:
        raise SetupError(f"{path}: not XML: {e}") from e
    return config, elements


def expected_structure(path, elements, section, problems):
    """{element: tuple of attributes} (or None for a text element) of one section."""
    out = {}
    for e in (x for x in elements if x.section == section):
        where = f"{path}:{e.line}: {section} ELEMENT TAG=\"{e.tag}\""
        if not e.tag or e.type not in TYPES or not e.indx:
            problems.append(f"static: {where}: needs TAG, TYPE (one of {sorted(TYPES)}) and INDX")
            continue
        if e.tag.startswith("DEF_"):
            name = e.tag[4:]
            if section != "SEND" or e.indx != "INTERNAL" or name not in BUILTIN_SEND:
                problems.append(f"static: {where}: not a built-in SEND element this test knows")
                continue
            out[name] = BUILTIN_SEND[name]
            continue
        if not e.indx.isdigit() or not 1 <= int(e.indx) <= 64:
            problems.append(f"static: {where}: INDX must be 1..64 (kuka_experimental's comment)")
        name, _, attribute = e.tag.partition(".")
        if section == "RECEIVE" and e.holdon != "0":
            problems.append(f"static: {where}: HOLDON must be \"0\": a relative correction held "
                            "on would repeat the last increment (README.md)")
        if attribute:
            out.setdefault(name, ())
            if out[name] is None or attribute in out[name]:
                problems.append(f"static: {where}: {name}.{attribute} given twice or mixed")
                continue
            out[name] = out[name] + (attribute,)
        else:
            out[name] = None
    return out


def static_checks(path, context, sample_toml, problems):
    config, elements = read_config(path)
    send = expected_structure(path, elements, "SEND", problems)
    receive = expected_structure(path, elements, "RECEIVE", problems)
    robot = tomllib.loads(pathlib.Path(sample_toml).read_text())["robot"]
    for key, want in (("IP_NUMBER", robot["bind_address"]), ("PORT", str(robot["bind_port"])),
                      ("SENTYPE", robot["sensor_type"]), ("ONLYSEND", "FALSE")):
        got, line = config.get(key, (None, 0))
        if got != want:
            problems.append(f"static: {path}:{line}: CONFIG {key} is {got!r}, zerog-rt wants "
                            f"{want!r} ({sample_toml} [robot], or the reply is awaited)")
    for name in sorted(set(send) - ZEROG_READS):
        problems.append(f"static: {path}: SEND element <{name}> is not read by zerog-rt "
                        "(proto/rsi.md: skipped)")
    for name in sorted(ZEROG_REQUIRES - set(send)):
        problems.append(f"static: {path}: SEND lacks <{name}>, which zerog-rt requires")
    if context is not None:
        check_context(path, context, elements, problems)
    return config, send, receive


def check_context(path, context, elements, problems):
    """The RSI 3.x context: its ETHERNET object reads `path`, its POSCORR takes RKorr.X..C."""
    objects = {o.get("ObjID"): o for o in ET.parse(context).getroot().iter("RSIObject")}
    ethernet = [o for o in objects.values() if o.get("ObjType") == "ETHERNET"]
    if len(ethernet) != 1:
        problems.append(f"static: {context}: {len(ethernet)} ETHERNET objects, want 1")
        return
    files = [p.get("ParamValue") for p in ethernet[0].iter("Parameter")
             if p.get("Name") == "ConfigFile"]
    if files != [pathlib.Path(path).name]:
        problems.append(f"static: {context}: ETHERNET ConfigFile is {files}, want "
                        f"{pathlib.Path(path).name!r}")
    channel = {int(e.indx): e.tag for e in elements
               if e.section == "RECEIVE" and e.indx.isdigit()}
    kind = correction_kind(elements)
    if kind is None:
        problems.append(f"static: {path}: RECEIVE has neither RKorr nor AKorr: zerog-rt answers "
                        f"one of them ({sorted(CORRECTIONS)})")
        return
    obj_type, attributes = CORRECTIONS[kind]
    corr = [o for o in objects.values() if o.get("ObjType") == obj_type]
    if len(corr) != 1:
        problems.append(f"static: {context}: {len(corr)} {obj_type} objects, want 1 for {kind}")
        return
    wired = {}
    for i in corr[0].iter("Input"):
        if i.get("OutObjID") != ethernet[0].get("ObjID"):
            continue
        # RSI 3.x contexts count from 1: InIdx 1 is CorrX (or A1), OutIdx k is RECEIVE's INDX k
        # (kuka_experimental's ros_rsi.rsi.xml and ros_rsi_ethernet.xml).
        wired[int(i.get("InIdx"))] = channel.get(int(i.get("OutIdx")))
    want = {k + 1: f"{kind}.{a}" for k, a in enumerate(attributes)}
    if wired != want:
        problems.append(f"static: {context}: {obj_type} inputs come from {wired}, want {want}")


def correction_kind(elements):
    """RKorr or AKorr: the correction element the RECEIVE list holds (None: neither)."""
    names = {e.tag.partition(".")[0] for e in elements if e.section == "RECEIVE"}
    kinds = [k for k in CORRECTIONS if k in names]
    return kinds[0] if len(kinds) == 1 else None


# ------------------------------------------------------------------ the datagram and the reply
def value_text(type_, k):
    """A value of the configured TYPE, different for every attribute (k)."""
    if type_ == "DOUBLE":
        return f"{(k + 1) * 11.125 - 40.0:.4f}"
    if type_ == "LONG":
        return str(k)
    if type_ == "BOOL":
        return str(k % 2)
    return f"s{k}"


def build_datagram(elements, send, ipoc, delay):
    """<Rob> with every SEND element, in the order of the file, and the IPOC."""
    parts, k = ['<Rob Type="KUKA">'], 0
    types = {}
    for e in (x for x in elements if x.section == "SEND"):
        name = e.tag[4:] if e.tag.startswith("DEF_") else e.tag.partition(".")[0]
        types.setdefault(name, e.type)
    for name, attributes in send.items():
        if attributes is None:
            parts.append(f"<{name}>{value_text(types[name], k)}</{name}>")
            k += 1
            continue
        values = []
        for a in attributes:
            # Plausible axis angles for AIPos (the rig's robot reads them), Delay as counted.
            text = str(delay) if (name, a) == ("Delay", "D") else value_text(types[name], k)
            if name == "AIPos":
                text = f"{(0.0, -90.0, 90.0, 0.0, 45.0, 0.0)[AXES.index(a)] + 0.5 * k:.4f}"
            values.append(f'{a}="{text}"')
            k += 1
        parts.append(f"<{name} {' '.join(values)}/>")
    parts.append(f"<IPOC>{ipoc}</IPOC></Rob>")
    return "".join(parts).encode()


def check_reply(data, ipoc, sentype, receive, problems, seen):
    """One reply against the RECEIVE list; a problem is reported once per kind (seen)."""
    def once(what):
        if what not in seen:
            seen.add(what)
            problems.append(f"live: {what}")

    try:
        root = ET.fromstring(data)
    except ET.ParseError as e:
        once(f"reply is not XML ({e}): {data[:200]!r}")
        return
    if root.tag != "Sen" or root.get("Type") != sentype:
        once(f"reply root <{root.tag} Type={root.get('Type')!r}>, want <Sen Type={sentype!r}>")
    ipocs = [c.text for c in root if c.tag == "IPOC"]
    if ipocs != [str(ipoc)]:
        once(f"reply IPOC {ipocs}, want [{ipoc}] (the datagram's)")
    got = {}
    for c in root:
        if c.tag == "IPOC":
            continue
        if c.tag in got:
            once(f"reply element <{c.tag}> twice")
        got[c.tag] = None if len(c.attrib) == 0 else tuple(sorted(c.attrib))
        for a, v in c.attrib.items():
            try:
                float(v)
            except ValueError:
                once(f"reply <{c.tag} {a}={v!r}> is not a number (RECEIVE TYPE DOUBLE)")
    for name in sorted(set(got) - set(receive)):
        once(f"reply element <{name}> is not in the RECEIVE list {sorted(receive)}")
    for name in sorted(set(receive) - set(got)):
        once(f"RECEIVE element <{name}> is missing from the reply (reply has {sorted(got)})")
    for name in sorted(set(got) & set(receive)):
        want = None if receive[name] is None else tuple(sorted(receive[name]))
        if got[name] != want:
            once(f"reply <{name}> has attributes {got[name]}, RECEIVE lists {want}")


# ------------------------------------------------------------------ zerog-emu and zerog-rt
def free_ports(n):
    socks = []
    for _ in range(n):
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.bind(("127.0.0.1", 0))
        socks.append(s)
    return socks


def run(cmd, log, **kw):
    with open(log, "w") as f:
        r = subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT, timeout=120, **kw)
    if r.returncode != 0:
        raise SetupError(f"{' '.join(map(str, cmd))} exited {r.returncode}:\n"
                         + pathlib.Path(log).read_text())


def live_checks(args, work, sentype, elements, send, receive, problems, collect):
    emu = pathlib.Path(args.bin) / "host/emu/zerog-emu"
    rt = pathlib.Path(args.bin) / "firmware/rt/zerog-rt"
    zerog = pathlib.Path(args.zerog) if args.zerog else pathlib.Path(args.bin) / "host/cli/zerog"
    for p in (emu, rt, zerog):
        if not os.access(p, os.X_OK):
            raise SetupError(f"{p} not built")
    run([emu, "--scenario", SCENARIO, "--write-model", work / "truth-model.json",
         "--write-rig", work / "rig.rig.toml", "--write-only"], work / "emu-write.out")
    run([zerog, "export", "--model", work / "truth-model.json", "--rig", work / "rig.rig.toml",
         "--out", work / "model.zgm", "-q"], work / "export.out")
    collect_args = []
    if collect:
        run([zerog, "design", "--kind", "oa", "--out", work / "design.csv"], work / "design.out")
        collect_args = ["--collect", work / "design.csv"]
    # Our controller socket; zerog-rt's port; the emulator's robot socket; and the socket the
    # emulator's robot sends to, held open and never read (so that zerog-rt sees only us).
    controller, rt_sock, emu_sock, sink = free_ports(4)
    rt_port, emu_port, sink_port = (s.getsockname()[1] for s in (rt_sock, emu_sock, sink))
    rt_sock.close()
    emu_sock.close()
    sockets = pathlib.Path(tempfile.mkdtemp(prefix="zerog-kuka."))
    template = RT_TEMPLATE.read_text()
    for old, new in (("@MODEL@", str(work / "model.zgm")), ("@RIG@", str(work / "rig.rig.toml")),
                     ("@IMU@", str(work / "imu-tty")),
                     ("bind_port = 49152\n", f"bind_port = {rt_port}\n"),
                     ("port = 49153\n", f"port = {controller.getsockname()[1]}\n"),
                     ('sensor_type = "zerog"\n', f'sensor_type = "{sentype}"\n'),
                     ('interface = "vcan0"\n',
                      f'transport = "local"\nlocal_path = "{sockets}/can"\n')):
        if old not in template:
            raise SetupError(f"{RT_TEMPLATE}: no {old.strip()!r} to replace")
        # Placeholders everywhere (the template's header names them too), keys once.
        template = template.replace(old, new, -1 if old.startswith("@") else 1)
    (work / "zerog-rt.toml").write_text(template)
    procs = []
    try:
        emu_p = subprocess.Popen(
            [emu, "--scenario", SCENARIO, "--can-local", sockets / "can", "--imu-link",
             work / "imu-tty", "--robot-bind", f"127.0.0.1:{emu_port}", "--rt-address",
             f"127.0.0.1:{sink_port}", "--duration", "60"],
            cwd=work, stdout=open(work / "emu.out", "w"), stderr=open(work / "emu.err", "w"))
        procs.append(emu_p)
        for _ in range(300):
            if "zerog-emu: ready" in (work / "emu.out").read_text() or emu_p.poll() is not None:
                break
            time.sleep(0.1)
        if "zerog-emu: ready" not in (work / "emu.out").read_text():
            raise SetupError("zerog-emu did not come up:\n" + (work / "emu.err").read_text())
        rt_p = subprocess.Popen(
            [rt, "--config", work / "zerog-rt.toml", "--duration", "30",
             "--summary-out", work / "rt.json", *collect_args],
            cwd=work, stdout=open(work / "rt.out", "w"), stderr=open(work / "rt.err", "w"))
        procs.append(rt_p)
        # zerog-rt says "zerog-rt: running: ..." (stderr) once its threads run. Then a warm-up of at most
        # 2 s, one datagram per cycle until the first answer (none comes for a configuration it
        # cannot read: the mutants); then the counted run. Every datagram counts in its summary.
        deadline = time.monotonic() + 30
        while "zerog-rt: running" not in (work / "rt.err").read_text():
            if rt_p.poll() is not None or time.monotonic() > deadline:
                raise SetupError(f"zerog-rt did not start (exit {rt_p.poll()}):\n"
                                 + (work / "rt.err").read_text())
            time.sleep(0.05)
        controller.settimeout(CYCLE_MS / 1000.0)
        ipoc, sent = 1_000_000, 0
        deadline = time.monotonic() + 2
        while time.monotonic() < deadline:
            ipoc += CYCLE_MS  # zerog-rt counts IPOC in ms (proto/loop.md)
            controller.sendto(build_datagram(elements, send, ipoc, delay=0), ("127.0.0.1", rt_port))
            sent += 1
            try:
                controller.recvfrom(4096)
                break
            except socket.timeout:
                pass
        time.sleep(CYCLE_MS / 1000.0)
        while True:  # late answers to the warm-up
            controller.settimeout(0.0)
            try:
                controller.recvfrom(4096)
            except (BlockingIOError, socket.timeout):
                break
        controller.settimeout(CYCLE_MS / 1000.0)
        answered, moving, seen = 0, 0, set()
        t0 = time.monotonic()
        for n in range(DATAGRAMS):
            ipoc += CYCLE_MS
            datagram = build_datagram(elements, send, ipoc, delay=0)
            if n == 0:
                (work / "datagram.xml").write_bytes(datagram)
            controller.sendto(datagram, ("127.0.0.1", rt_port))
            sent += 1
            try:
                while True:
                    data, _ = controller.recvfrom(4096)
                    if ET.fromstring(data).findtext("IPOC") == str(ipoc):
                        break
            except (socket.timeout, ET.ParseError):
                data = None
            if data is not None:
                answered += 1
                if answered == 1:
                    (work / "reply.xml").write_bytes(data)
                check_reply(data, ipoc, sentype, receive, problems, seen)
                akorr = ET.fromstring(data).find("AKorr")
                if akorr is not None and any(float(v) != 0.0 for v in akorr.attrib.values()):
                    moving += 1
            next_t = t0 + (n + 1) * CYCLE_MS / 1000.0
            time.sleep(max(0.0, next_t - time.monotonic()))
        if collect and moving == 0:
            problems.append(f"live: zerog-rt started with --collect answered {answered} datagrams, "
                            "none moving an axis (the approach to the design's first point)")
        if answered != DATAGRAMS:
            problems.append(f"live: zerog-rt answered {answered} of {DATAGRAMS} datagrams in time "
                            f"(first datagram: {work / 'datagram.xml'})")
        rt_p.send_signal(signal.SIGINT)
        rt_p.wait(timeout=30)
    finally:
        for p in procs:
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
                try:
                    p.wait(timeout=15)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()
        shutil.rmtree(sockets, ignore_errors=True)
        for s in (controller, sink):
            s.close()
    summary = json.loads((work / "rt.json").read_text())
    robot = summary["devices"]["robot"]
    if robot["malformed"] != 0:
        absent = [f"<{n}>" for n in sorted(ZEROG_REQUIRES - set(send))]
        why = f" (the datagram has no {', '.join(absent)}, which zerog-rt requires)" if absent else ""
        problems.append(f"live: zerog-rt found {robot['malformed']} datagrams malformed: "
                        f"{robot['malformed_by_status']}{why}")
    if robot["messages"] != sent:
        problems.append(f"live: zerog-rt read {robot['messages']} messages of {sent} sent "
                        f"(foreign {robot['foreign']})")
    axis_replies = summary["cycle_thread"]["axis_replies"]
    replies = summary["cycle_thread"]["replies_ok"]
    if axis_replies != (replies if collect else 0):
        problems.append(f"live: zerog-rt counted {axis_replies} axis replies of {replies}, want "
                        f"{'all' if collect else 'none'} ({'AKorr' if collect else 'RKorr'} "
                        "in RECEIVE)")
    if "RIst" in send and summary["cycles"]["poses_from_joints"] != 0:
        problems.append(f"live: zerog-rt took {summary['cycles']['poses_from_joints']} poses from "
                        "the joints although RIst was sent")


def check(args, path, context, work):
    problems = []
    config, send, receive = static_checks(path, context, args.sample_toml, problems)
    _, elements = read_config(path)
    sentype = config.get("SENTYPE", ("zerog", 0))[0]
    # An AKorr configuration is the calibration collection's: zerog-rt drives a design path.
    # Decided on the file as given (a mutant's renamed element must not change the mode).
    collect = correction_kind(read_config(args.config)[1]) == "AKorr"
    live_checks(args, work, sentype, elements, send, receive, problems, collect)
    return problems


def mutate(src, dst, which):
    """A copy of the configuration with one element renamed; returns what the check must say."""
    text = pathlib.Path(src).read_text()
    if which == "send":
        old, new, must = 'TAG="DEF_AIPos"', 'TAG="DEF_ASPos"', ("missing_element", "<AIPos>")
    else:
        kind = correction_kind(read_config(src)[1])
        old, new, must = f'TAG="{kind}.', f'TAG="{kind[:-1]}.', (f"<{kind[:-1]}>", f"<{kind}>")
    if old not in text:
        raise SetupError(f"{src}: no {old} to rename for the {which} mutant")
    pathlib.Path(dst).write_text(text.replace(old, new))
    return must


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bin", required=True, help="build tree with zerog-rt and zerog-emu")
    ap.add_argument("--zerog", help="the host CLI for zerog export (default: BIN/host/cli/zerog)")
    ap.add_argument("--out", required=True, help="folder for the run's files (emptied)")
    ap.add_argument("--config", default=str(DEFAULT_CONFIG), help="RSI Ethernet configuration")
    ap.add_argument("--context", default=str(DEFAULT_CONTEXT),
                    help="RSI 3.x context (.rsi.xml) to check against it; '' for none")
    ap.add_argument("--sample-toml", default=str(SAMPLE_TOML))
    ap.add_argument("--mutant", choices=("send", "receive"))
    args = ap.parse_args()
    work = pathlib.Path(args.out).resolve()
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    config, context = pathlib.Path(args.config), args.context or None
    try:
        if args.mutant:
            mutant = work / config.name  # same name: the context's ConfigFile still matches
            must = mutate(config, mutant, args.mutant)
            problems = check(args, mutant, context, work)
        else:
            problems = check(args, config, context, work)
    except (SetupError, subprocess.TimeoutExpired, OSError, KeyError) as e:
        print(f"kuka_config_test: set-up failed: {e}", file=sys.stderr)
        return 2
    for p in problems:
        print(f"  mismatch  {p}")
    if args.mutant:
        live = [p for p in problems if p.startswith("live:")]
        if all(any(m in p for p in live) for m in must):
            print(f"ok: the {args.mutant} mutant ({mutant}) fails the live check, naming "
                  f"{' / '.join(must)}")
            return 0
        print(f"FAIL: the {args.mutant} mutant was not caught by the live check with a mismatch "
              f"naming {' / '.join(must)}", file=sys.stderr)
        return 1
    if problems:
        print(f"FAIL: {config} and zerog-rt disagree ({len(problems)} mismatches)", file=sys.stderr)
        return 1
    print(f"ok: {config}: {DATAGRAMS} datagrams with every SEND element "
          f"({', '.join(send_names(config))} and IPOC) read by zerog-rt, every reply exactly "
          f"the RECEIVE list ({work / 'datagram.xml'}, {work / 'reply.xml'})")
    return 0


def send_names(path):
    _, elements = read_config(path)
    return [e.tag for e in elements if e.section == "SEND"]


if __name__ == "__main__":
    sys.exit(main())
