#!/usr/bin/env python3
"""A ROS 2-side subscriber to zerog-rt's rt/ topics (proto/telemetry.md, "ROS 2 topics").

It knows nothing of zerog's IDL: every DDS type is built at run time from the ROS 2 message
definitions that PyPI's `rosbags` ships (rosbags.typesys, ROS 2 Humble by default), named as
ROS 2's DDS mapping names them (`pkg::msg::dds_::Name_`, members with rosidl_generator_dds_idl's
trailing underscore; proto/ros2.idl cites the sources), and read with PyPI's `cyclonedds` (its own
Cyclone C library). The QoS are ROS 2's: sensor data (best-effort, volatile) for the streams,
reliable transient-local for the diagnostics. Run with the repository's .venv python.

  ros2_subscriber.py --domain N [--interface lo --peer 127.0.0.1 --no-multicast]
                     --out R.jsonl [--ready FILE] [--duration S] [--idle S] [--mutant NAME]

Writes one JSON object per line: {"topic": "wrench", "type": "geometry_msgs/msg/WrenchStamped",
"msg": {...}} with the ROS field names. --mutant breaks the types on purpose, to show that
check_ros2_telemetry.py sees it: `type_name` (WrenchStamped without dds_:: and the trailing
underscore: ROS 1's name) or `member_order` (geometry_msgs/Vector3 declared y, x, z).
"""
import argparse
import math
import sys
import types
from dataclasses import dataclass, fields

from cyclonedds.idl import IdlStruct
from cyclonedds.idl.annotations import final
import cyclonedds.idl.types as t
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.base import Nodetype

# The DDS plumbing only (participant, QoS, the take loop), not zerog's types.
from dds_subscriber import listen, participant, reader_qos  # noqa: E402

# ROS topic (in the namespace) → ROS message type. The same list as proto/telemetry.md's.
STREAMS = {
    "wrench": "geometry_msgs/msg/WrenchStamped",
    "wrench_at_eval": "geometry_msgs/msg/WrenchStamped",
    "wrench_predicted": "geometry_msgs/msg/WrenchStamped",
    "wrench_contact": "geometry_msgs/msg/WrenchStamped",
    "imu": "sensor_msgs/msg/Imu",
    "joint_states": "sensor_msgs/msg/JointState",
    "sensor_pose": "geometry_msgs/msg/PoseStamped",
    "body_pose": "geometry_msgs/msg/PoseStamped",
    "body_twist": "geometry_msgs/msg/TwistStamped",
}
LATCHED = {"diagnostics": "diagnostic_msgs/msg/DiagnosticArray"}

# ROS's primitive types (rosidl) → Cyclone's Python IDL types.
BASE = {
    "bool": bool, "byte": t.uint8, "char": t.uint8, "int8": t.int8, "uint8": t.uint8,
    "int16": t.int16, "uint16": t.uint16, "int32": t.int32, "uint32": t.uint32,
    "int64": t.int64, "uint64": t.uint64, "float32": t.float32, "float64": t.float64,
    "string": str,
}


def dds_type_name(ros_name):
    """ROS 2's DDS type name: pkg/msg/Name → pkg::msg::dds_::Name_ (rmw_cyclonedds)."""
    pkg, kind, name = ros_name.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


class TypeBuilder:
    """IdlStruct classes from rosbags' message definitions, built once per ROS type."""

    def __init__(self, store, mutant=""):
        self.typestore = get_typestore(store)
        self.mutant = mutant
        self.classes = {}

    def field_type(self, node):
        kind, arg = node
        if kind == Nodetype.BASE:
            name, bound = arg
            if name == "string" and bound:
                return t.bounded_str[bound]
            return BASE[name]
        if kind == Nodetype.NAME:
            return self.build(arg)
        if kind == Nodetype.ARRAY:
            sub, count = arg
            return t.array[self.field_type(sub), count]
        if kind == Nodetype.SEQUENCE:
            sub, bound = arg
            inner = self.field_type(sub)
            return t.sequence[inner, bound] if bound else t.sequence[inner]
        raise ValueError(f"unsupported rosbags node {node}")

    def build(self, ros_name):
        if ros_name in self.classes:
            return self.classes[ros_name]
        _, members = self.typestore.fielddefs[ros_name]
        members = list(members)
        if self.mutant == "member_order" and ros_name == "geometry_msgs/msg/Vector3":
            members[0], members[1] = members[1], members[0]
        typename = dds_type_name(ros_name)
        if self.mutant == "type_name" and ros_name == "geometry_msgs/msg/WrenchStamped":
            typename = "geometry_msgs::msg::WrenchStamped"
        annotations = {m + "_": self.field_type(node) for m, node in members}

        def body(ns):
            ns["__annotations__"] = annotations

        cls = types.new_class(ros_name.replace("/", "_"), (IdlStruct,), {"typename": typename},
                              body)
        cls = dataclass(final(cls))
        cls.ros_name = ros_name
        self.classes[ros_name] = cls
        return cls


def plain(sample):
    """The message as JSON, with ROS's field names (the trailing underscore dropped)."""
    if isinstance(sample, IdlStruct):
        return {f.name[:-1]: plain(getattr(sample, f.name)) for f in fields(sample)}
    if isinstance(sample, (list, tuple)):
        return [plain(x) for x in sample]
    if isinstance(sample, float) and not math.isfinite(sample):
        return repr(sample)
    if isinstance(sample, bytes):
        return list(sample)
    return sample


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--domain", type=int, default=0)
    ap.add_argument("--interface", default="")
    ap.add_argument("--peer", action="append", default=[])
    ap.add_argument("--no-multicast", action="store_true")
    ap.add_argument("--namespace", default="/zerog", help="ROS namespace of the topics")
    ap.add_argument("--distro", default="ROS2_HUMBLE", choices=[s.name for s in Stores
                                                                if s.name.startswith("ROS2")])
    ap.add_argument("--duration", type=float, default=10.0, help="seconds to listen at most")
    ap.add_argument("--idle", type=float, default=0.0,
                    help="stop after this many seconds without any sample, once some came")
    ap.add_argument("--out", required=True, help="JSON lines output")
    ap.add_argument("--ready", default="", help="touch this file once the readers exist")
    ap.add_argument("--mutant", default="", choices=["", "type_name", "member_order"])
    args = ap.parse_args()

    builder = TypeBuilder(Stores[args.distro], args.mutant)
    domain, dp = participant(args)
    # rmw_qos_profile_sensor_data is keep-last 5 (best-effort, volatile); the latched profile
    # reliable, keep-last 1, transient-local: the readers' deeper histories only keep this script
    # from losing samples between two take()s (history is the reader's own).
    sensor_qos, latched_qos = reader_qos()
    prefix = "rt" + args.namespace.rstrip("/") + "/"
    readers, ros_types = {}, {}
    for topics, qos in ((STREAMS, sensor_qos), (LATCHED, latched_qos)):
        for name, ros_type in topics.items():
            cls = builder.build(ros_type)
            readers[name] = DataReader(dp, Topic(dp, prefix + name, cls), qos=qos)
            ros_types[name] = ros_type
    if args.ready:
        open(args.ready, "w").close()
    counts = listen(readers, args.out, args.duration, args.idle,
                    lambda name, s: {"topic": name, "type": ros_types[name], "msg": plain(s)})
    assert domain is not None
    print("ros2_subscriber: " + ", ".join(f"{k} {v}" for k, v in counts.items()), file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
