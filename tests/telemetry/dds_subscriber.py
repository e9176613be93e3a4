#!/usr/bin/env python3
"""Independent subscriber for zerog-rt's telemetry (proto/telemetry.md).

The wire types are declared here by hand, NOT generated from proto/telemetry.idl, so that a
mismatch between the IDL, the C code idlc generates and what the firmware writes shows up as
missing or wrong samples. Uses PyPI's `cyclonedds` (its own bundled Cyclone C library), run
with /work/main/.venv/bin/python.

Writes one JSON object per line to --out: {"topic": "wrench", "sample": {...}}.
Exits 0 after --duration seconds or once --samples wrench samples arrived (and the last
health/model are in); prints a per-topic count to stderr.
"""
import argparse
import json
import math
import sys
import time
from dataclasses import asdict, dataclass

from cyclonedds.core import Policy, Qos
from cyclonedds.domain import Domain, DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.annotations import final
import cyclonedds.idl.types as t
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

D6 = t.array[float, 6]
D3 = t.array[float, 3]
D4 = t.array[float, 4]


@dataclass
@final
class WrenchSample(IdlStruct, typename="zerog::telemetry::WrenchSample"):
    cycle: t.uint64
    t_s: float
    measured: D6
    ft_samples: t.uint16
    t_eval_s: float
    measured_at_eval: D6
    predicted: D6
    contact: D6
    model_status: t.uint8
    flags: t.uint32


@dataclass
@final
class ImuSample(IdlStruct, typename="zerog::telemetry::ImuSample"):
    cycle: t.uint64
    t_s: float
    specific_force_imu_mps2: D3
    rate_imu_radps: D3
    imu_samples: t.uint16


@dataclass
@final
class RobotSample(IdlStruct, typename="zerog::telemetry::RobotSample"):
    cycle: t.uint64
    t_s: float
    ipoc: t.uint64
    joints_rad: D6
    p_base_sensor_m: D3
    q_base_sensor_wxyz: D4


@dataclass
@final
class CommandSample(IdlStruct, typename="zerog::telemetry::CommandSample"):
    cycle: t.uint64
    t_s: float
    dt_s: float
    axis_reply: bool
    rkorr_translation_m: D3
    rkorr_abc_rad: D3
    akorr_rad: D6
    v_world_mps: D3
    omega_world_radps: D3
    limit_flags: t.uint32


@dataclass
@final
class BodySample(IdlStruct, typename="zerog::telemetry::BodySample"):
    cycle: t.uint64
    t_s: float
    p_world_m: D3
    q_world_body_wxyz: D4
    v_world_mps: D3
    omega_world_radps: D3
    momentum_world_kgmps: D3
    L_world_kgm2ps: D3
    kinetic_energy_J: float
    mass_kg: float


@dataclass
@final
class TimingSample(IdlStruct, typename="zerog::telemetry::TimingSample"):
    cycle: t.uint64
    t_s: float
    ipoc: t.uint64
    dt_s: float
    period_s: float
    jitter_s: float
    compute_s: float
    ipoc_gap: bool
    robot_late: bool
    robot_lost: bool
    datagrams_lost: t.uint64


@dataclass
@final
class Health(IdlStruct, typename="zerog::telemetry::Health"):
    health_seq: t.uint64
    cycle: t.uint64
    t_s: float
    state: t.uint8
    fault: t.uint8
    flags: t.uint32
    records_offered: t.uint64
    records_published: t.uint64
    telemetry_drops: t.uint64
    write_errors: t.uint64
    robot_lost: t.uint64
    datagrams_lost: t.uint64
    ipoc_gaps: t.uint64
    ft_held_cycles: t.uint64
    imu_held_cycles: t.uint64
    replies_failed: t.uint64
    record_drops: t.uint64
    commands_refused: t.uint64
    transitions: t.uint64
    poses_from_joints: t.uint64
    pose_disagreements: t.uint64
    poses_missing: t.uint64


@dataclass
@final
class ModelIdentity(IdlStruct, typename="zerog::telemetry::ModelIdentity"):
    rig_name: str
    robot: str
    effects: t.sequence[str]
    has_network: bool
    network_width: t.sequence[t.int32]
    network_activations: t.sequence[str]
    network_features: t.sequence[str]
    network_outputs: t.sequence[str]
    weight_bits: t.int32
    deploy_file: str
    deploy_crc32: t.uint32
    provenance_json: str


STREAMS = {
    "wrench": WrenchSample,
    "imu": ImuSample,
    "robot": RobotSample,
    "command": CommandSample,
    "body": BodySample,
    "timing": TimingSample,
}
STATE = {"health": Health, "model": ModelIdentity}


def cyclone_xml(interface, peers, multicast):
    """The same configuration zerog::telemetry::cyclone_xml builds (proto/telemetry.md)."""
    xml = '<CycloneDDS><Domain id="any"><General>'
    if interface:
        xml += f'<Interfaces><NetworkInterface name="{interface}"/></Interfaces>'
    xml += f"<AllowMulticast>{'true' if multicast else 'false'}</AllowMulticast></General>"
    if peers:
        xml += "<Discovery><ParticipantIndex>auto</ParticipantIndex><Peers>"
        xml += "".join(f'<Peer address="{p}"/>' for p in peers)
        xml += "</Peers></Discovery>"
    return xml + "</Domain></CycloneDDS>"


def participant(args):
    """(Domain, DomainParticipant) on args.domain with args.interface / peer / no_multicast. Keep
    the Domain object: once it is collected, the participant would get a default domain."""
    domain = Domain(args.domain, cyclone_xml(args.interface, args.peer, not args.no_multicast))
    return domain, DomainParticipant(args.domain)


def reader_qos():
    """(streams, state): the readers' QoS. Best-effort volatile with a deep history for the
    per-cycle streams (deeper than a writer's: it only keeps this script from losing samples
    between two take()s), reliable transient-local for the state a late reader must get."""
    return (Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(4096),
                Policy.Durability.Volatile),
            Qos(Policy.Reliability.Reliable(1_000_000_000), Policy.History.KeepLast(64),
                Policy.Durability.TransientLocal))


def listen(readers, out_path, duration, idle, encode, stop=lambda counts: False):
    """Takes every sample of `readers` ({name: DataReader}) into `out_path` as JSON lines
    (`encode(name, sample)`), for at most `duration` s, until `idle` s pass without a sample once
    some came (0: never), or until `stop(counts)`; returns the counts per reader."""
    counts = {name: 0 for name in readers}
    t0 = time.monotonic()
    last = None
    with open(out_path, "w") as out:
        while time.monotonic() - t0 < duration:
            got = 0
            for name, reader in readers.items():
                for s in reader.take(N=256):
                    if not isinstance(s, IdlStruct):
                        continue  # an invalid sample: the writer went away (unregister)
                    out.write(json.dumps(encode(name, s)) + "\n")
                    counts[name] += 1
                    got += 1
            now = time.monotonic()
            if got:
                last = now
            if stop(counts):
                break
            if idle and last is not None and now - last > idle:
                break
            if not got:
                time.sleep(0.005)
    return counts


def plain(sample):
    def fix(v):
        if isinstance(v, float) and not math.isfinite(v):
            return repr(v)
        if isinstance(v, list):
            return [fix(x) for x in v]
        return v

    return {k: fix(v) for k, v in asdict(sample).items()}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--domain", type=int, default=0)
    ap.add_argument("--interface", default="")
    ap.add_argument("--peer", action="append", default=[])
    ap.add_argument("--no-multicast", action="store_true")
    ap.add_argument("--prefix", default="zerog/")
    ap.add_argument("--duration", type=float, default=10.0, help="seconds to listen at most")
    ap.add_argument("--samples", type=int, default=0,
                    help="stop once this many wrench samples arrived (0: --duration only)")
    ap.add_argument("--idle", type=float, default=0.0,
                    help="stop after this many seconds without any sample, once some came")
    ap.add_argument("--out", required=True, help="JSON lines output")
    ap.add_argument("--ready", default="", help="touch this file once the readers exist")
    args = ap.parse_args()

    domain, dp = participant(args)
    stream_qos, state_qos = reader_qos()
    readers = {}
    for name, cls in STREAMS.items():
        readers[name] = DataReader(dp, Topic(dp, args.prefix + name, cls), qos=stream_qos)
    for name, cls in STATE.items():
        readers[name] = DataReader(dp, Topic(dp, args.prefix + name, cls), qos=state_qos)
    if args.ready:
        open(args.ready, "w").close()
    counts = listen(readers, args.out, args.duration, args.idle,
                    lambda name, s: {"topic": name, "sample": plain(s)},
                    lambda c: args.samples and c["wrench"] >= args.samples and c["model"] > 0)
    assert domain is not None
    print("dds_subscriber: " + ", ".join(f"{k} {v}" for k, v in counts.items()), file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
