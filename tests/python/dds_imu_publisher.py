#!/usr/bin/env python3
"""An independent ROS 2 IMU driver for imud's DDS input (`imud --ros2-input`): Eclipse Cyclone
DDS (the C library of the `cyclonedds` wheel) publishing sensor_msgs/msg/Imu under ROS 2's wire
names (topic `rt/...`, type `sensor_msgs::msg::dds_::Imu_`), with the message types of
dds_imu_peer.py (written from the upstream .msg files, not from imud's code).

Waits until a reader matches (imud's), lets discovery settle, then publishes --n messages at
--rate-hz, stamped --rate-hz apart from the current wall-clock time, each with values that
identify it; the indices in --skip are not published (a driver that drops messages). Prints one
JSON object: every message published (index, stamp, values) and the reader matches seen.
Exit 77 when cyclonedds is not installed, 3 when no reader matched within --match-timeout-s.
"""

import argparse
import json
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from dds_imu_peer import Header, Imu, Quaternion, Time, Vector3  # noqa: E402 (exits 77 without cyclonedds)

from cyclonedds.core import Listener, Policy, Qos  # noqa: E402
from cyclonedds.domain import DomainParticipant  # noqa: E402
from cyclonedds.pub import DataWriter  # noqa: E402
from cyclonedds.topic import Topic  # noqa: E402
from cyclonedds.util import duration  # noqa: E402


def values(k):
    """The values of message k: distinct per message and per axis, exact in binary floating point
    only by accident (the comparison is bit for bit after the daemon's correction is undone)."""
    return {
        "angular_velocity": [0.001 * k, -0.002 * k + 0.05, 0.3 + 1e-4 * k],
        "linear_acceleration": [0.1 + 0.003 * k, -0.2, 9.81 - 0.0005 * k],
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--domain", type=int, default=0)
    ap.add_argument("--topic", required=True, help="DDS topic, e.g. rt/camera/imu")
    ap.add_argument("--n", type=int, required=True)
    ap.add_argument("--rate-hz", type=float, required=True)
    ap.add_argument("--skip", default="", help="comma-separated indices not published")
    ap.add_argument("--qos", choices=["reliable", "best-effort"], default="reliable")
    ap.add_argument("--frame-id", default="camera_imu_frame")
    ap.add_argument("--match-timeout-s", type=float, default=60.0)
    ap.add_argument("--settle-s", type=float, default=1.0)
    ap.add_argument("--linger-s", type=float, default=1.0)
    args = ap.parse_args()
    skip = {int(s) for s in args.skip.split(",") if s}

    matched = {"current": 0, "total": 0}

    def on_matched(_writer, status):
        matched["current"] = status.current_count
        matched["total"] = status.total_count

    dp = DomainParticipant(args.domain)
    topic = Topic(dp, args.topic, Imu)
    reliability = (
        Policy.Reliability.Reliable(duration(seconds=1))
        if args.qos == "reliable"
        else Policy.Reliability.BestEffort
    )
    writer = DataWriter(
        dp,
        topic,
        qos=Qos(reliability, Policy.History.KeepLast(args.n + 1)),
        listener=Listener(on_publication_matched=on_matched),
    )
    deadline = time.monotonic() + args.match_timeout_s
    while matched["current"] == 0:
        if time.monotonic() > deadline:
            print(f"no reader matched {args.topic} within {args.match_timeout_s} s", file=sys.stderr)
            return 3
        time.sleep(0.02)
    # The reader's side learns of this writer by its own discovery; give it that time.
    time.sleep(args.settle_s)

    period_ns = round(1e9 / args.rate_hz)
    t0_ns = time.time_ns()
    start = time.monotonic()
    sent = []
    for k in range(args.n):
        due = start + k * period_ns * 1e-9
        now = time.monotonic()
        if due > now:
            time.sleep(due - now)
        if k in skip:
            continue
        t_ns = t0_ns + k * period_ns
        v = values(k)
        msg = Imu(
            header=Header(
                stamp=Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000),
                frame_id=args.frame_id,
            ),
            orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=[-1.0] + [0.0] * 8,
            angular_velocity=Vector3(*v["angular_velocity"]),
            angular_velocity_covariance=[0.0] * 9,
            linear_acceleration=Vector3(*v["linear_acceleration"]),
            linear_acceleration_covariance=[0.0] * 9,
        )
        writer.write(msg)
        sent.append({"k": k, "stamp_ns": t_ns, **v})
    # Best effort does not resend: give the last messages time to arrive before leaving.
    time.sleep(args.linger_s)
    json.dump({"sent": sent, "matched": matched}, sys.stdout)
    return 0


if __name__ == "__main__":
    sys.exit(main())
