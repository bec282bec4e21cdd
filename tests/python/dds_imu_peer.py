#!/usr/bin/env python3
"""An independent ROS 2 peer for imud's DDS output: Eclipse Cyclone DDS (the C library the
`cyclonedds` wheel ships) subscribing with ROS 2's wire names (topic `rt/...`, type
`sensor_msgs::msg::dds_::Imu_`), its message types written here as IDL dataclasses from the
upstream .msg files, not from imud's code.

Readers:
  early     best effort, from the start: imu/data, imu/data_raw, imu/mag, imu/temperature,
            and /diagnostics (reliable: imud's diagnostics writer is reliable)
  reliable  a reliable imu/data reader from the start (matches only a reliable writer; its
            incompatible-QoS events are counted, proving it saw a best-effort one)
  late      best effort imu/data, created --late-after-s after the early reader's first sample

Writes the ready file once the readers exist, ends when the early reader got samples and then
none for --idle-s (or at --timeout-s), and prints one JSON object. Every sample carries its
receipt wall-clock time (`rx_ns`: when this loop's wait on the readers woke and took it) for the
latency benchmark.
Exit 77 when cyclonedds is not installed.
"""

import argparse
import json
import sys
import time
from dataclasses import dataclass

try:
    from cyclonedds.core import (
        InstanceState,
        Listener,
        Policy,
        Qos,
        ReadCondition,
        SampleState,
        ViewState,
        WaitSet,
    )
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.idl import IdlStruct
    from cyclonedds.internal import InvalidSample
    from cyclonedds.idl.types import array, float64, int32, sequence, uint8, uint32
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
    from cyclonedds.util import duration
except ImportError as e:  # the test skips (or fails under IMUD_REQUIRE_PEERS)
    print(f"cyclonedds not available: {e}", file=sys.stderr)
    sys.exit(77)


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32
    nanosec: uint32


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time
    frame_id: str


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float64
    y: float64
    z: float64
    w: float64


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64
    y: float64
    z: float64


@dataclass
class Imu(IdlStruct, typename="sensor_msgs::msg::dds_::Imu_"):
    header: Header
    orientation: Quaternion
    orientation_covariance: array[float64, 9]
    angular_velocity: Vector3
    angular_velocity_covariance: array[float64, 9]
    linear_acceleration: Vector3
    linear_acceleration_covariance: array[float64, 9]


@dataclass
class MagneticField(IdlStruct, typename="sensor_msgs::msg::dds_::MagneticField_"):
    header: Header
    magnetic_field: Vector3
    magnetic_field_covariance: array[float64, 9]


@dataclass
class Temperature(IdlStruct, typename="sensor_msgs::msg::dds_::Temperature_"):
    header: Header
    temperature: float64
    variance: float64


@dataclass
class KeyValue(IdlStruct, typename="diagnostic_msgs::msg::dds_::KeyValue_"):
    key: str
    value: str


@dataclass
class DiagnosticStatus(IdlStruct, typename="diagnostic_msgs::msg::dds_::DiagnosticStatus_"):
    level: uint8
    name: str
    message: str
    hardware_id: str
    values: sequence[KeyValue]


@dataclass
class DiagnosticArray(IdlStruct, typename="diagnostic_msgs::msg::dds_::DiagnosticArray_"):
    header: Header
    status: sequence[DiagnosticStatus]


def vec(v):
    return [v.x, v.y, v.z]


def stamp(h):
    return {"sec": h.stamp.sec, "nanosec": h.stamp.nanosec, "frame_id": h.frame_id}


def imu_json(m):
    return {
        **stamp(m.header),
        "orientation": [m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w],
        "orientation_covariance": list(m.orientation_covariance),
        "angular_velocity": vec(m.angular_velocity),
        "angular_velocity_covariance": list(m.angular_velocity_covariance),
        "linear_acceleration": vec(m.linear_acceleration),
        "linear_acceleration_covariance": list(m.linear_acceleration_covariance),
    }


def mag_json(m):
    return {
        **stamp(m.header),
        "magnetic_field": vec(m.magnetic_field),
        "magnetic_field_covariance": list(m.magnetic_field_covariance),
    }


def temperature_json(m):
    return {**stamp(m.header), "temperature": m.temperature, "variance": m.variance}


def diagnostics_json(m):
    return {
        **stamp(m.header),
        "status": [
            {
                "level": s.level,
                "name": s.name,
                "message": s.message,
                "hardware_id": s.hardware_id,
                "values": {kv.key: kv.value for kv in s.values},
            }
            for s in m.status
        ],
    }


class Collector:
    """One reader's samples, each stamped with its receipt time: when the peer's wait on the
    reader's data woke up and took it (wall clock, ns)."""

    def __init__(self, reader, to_json):
        self.reader = reader
        self.to_json = to_json
        self.taken = []  # (rx_ns, sample)
        self.incompatible_qos = 0

    def take(self, rx_ns):
        for m in self.reader.take(N=1024):
            if not isinstance(m, InvalidSample):  # a writer leaving: no data
                self.taken.append((rx_ns, m))

    def result(self):
        return {
            "samples": [{**self.to_json(m), "rx_ns": rx} for rx, m in self.taken],
            "incompatible_qos": self.incompatible_qos,
        }


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--domain", type=int, default=0)
    ap.add_argument("--namespace", default="", help="e.g. robot1 (topics rt/robot1/imu/...)")
    ap.add_argument("--ready", required=True, help="file created once the readers exist")
    ap.add_argument("--idle-s", type=float, default=2.0)
    ap.add_argument("--timeout-s", type=float, default=60.0)
    ap.add_argument("--late-after-s", type=float, default=1.0)
    ap.add_argument(
        "--topics",
        help="comma-separated keys of the only early readers to make (imu, imu_raw, mag, temperature, "
        "diagnostics; imu must be one), and no reliable reader; default: every topic",
    )
    args = ap.parse_args()

    ns = args.namespace.strip("/")
    rel = (lambda t: f"rt/{ns}/{t}") if ns else (lambda t: f"rt/{t}")
    dp = DomainParticipant(args.domain)
    # Deep histories: the readers keep every sample until this loop takes it.
    best_effort = Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(100_000))
    reliable = Qos(Policy.Reliability.Reliable(duration(seconds=1)), Policy.History.KeepLast(100_000))
    waitset = WaitSet(dp)
    topics = {}
    collectors = []

    def reader(name, ty, to_json, qos):
        if name not in topics:
            topics[name] = Topic(dp, name, ty)
        c = Collector(None, to_json)

        def on_incompatible(_reader, _status):
            c.incompatible_qos += 1

        c.reader = DataReader(
            dp, topics[name], qos=qos, listener=Listener(on_requested_incompatible_qos=on_incompatible)
        )
        waitset.attach(ReadCondition(c.reader, ViewState.Any | InstanceState.Any | SampleState.Any))
        collectors.append(c)
        return c

    only = set(args.topics.split(",")) if args.topics else None
    every = [
        ("imu", rel("imu/data"), Imu, imu_json, best_effort),
        ("imu_raw", rel("imu/data_raw"), Imu, imu_json, best_effort),
        ("mag", rel("imu/mag"), MagneticField, mag_json, best_effort),
        ("temperature", rel("imu/temperature"), Temperature, temperature_json, best_effort),
        ("diagnostics", "rt/diagnostics", DiagnosticArray, diagnostics_json, reliable),
    ]
    if only is not None and ("imu" not in only or not only <= {e[0] for e in every}):
        ap.error(f"--topics {args.topics}: the keys are {[e[0] for e in every]}, imu among them")
    early = {}
    for key, name, ty, conv, qos in every:
        if only is None or key in only:
            early[key] = reader(name, ty, conv, qos)
    rel_c = None if only is not None else reader(rel("imu/data"), Imu, imu_json, reliable)
    with open(args.ready, "w") as f:
        f.write("ready\n")

    start = time.monotonic()
    late_c = None
    first_rx = None
    last_rx = None
    while time.monotonic() - start < args.timeout_s:
        waitset.wait(duration(milliseconds=50))
        rx_ns = time.time_ns()
        now = time.monotonic()
        before = len(early["imu"].taken)
        for c in collectors:
            c.take(rx_ns)
        if len(early["imu"].taken) > before:
            last_rx = now
            first_rx = first_rx or now
        if late_c is None and first_rx is not None and now - first_rx >= args.late_after_s:
            late_c = reader(rel("imu/data"), Imu, imu_json, best_effort)
        if last_rx is not None and now - last_rx > args.idle_s:
            break

    out = {
        "early": {k: c.result() for k, c in early.items()},
        "reliable": rel_c.result() if rel_c else None,
        "late": late_c.result() if late_c else None,
    }
    json.dump(out, sys.stdout)
    return 0


if __name__ == "__main__":
    sys.exit(main())
