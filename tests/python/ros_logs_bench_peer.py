"""The Python side of `crates/imu-rec/benches/ros_logs.rs`: writes a large ROS 1 bag or rosbag2
sqlite3 bag of `sensor_msgs/Imu` with `rosbags` (at run time, into the bench's temporary
directory), and reads one back the way a `rosbags` user does (AnyReader, every message
deserialized, stamps and vectors collected), timing the read.

Message k: stamp T0 + k x 5 ms (200 Hz), linear_acceleration = (k mod 1000, 0, 9.8),
angular_velocity = (0, 0, 0.001). Messages are serialized once and their stamp and
linear_acceleration.x patched per message (offsets found by serializing markers), so
writing is fast enough for a gigabyte.

Usage:
  ros_logs_bench_peer.py gen ros1|sqlite3 OUT N
  ros_logs_bench_peer.py read PATH       -> JSON {"n", "seconds", "sum_accel_x", "max_rss_kib"}
Exit status 77 means the peer package is missing.
"""

import json
import resource
import struct
import sys
import time
from pathlib import Path

try:
    import numpy as np
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys import Stores, get_typestore
except ImportError as e:  # pragma: no cover - depends on the machine
    print(f"missing Python peer: {e}", file=sys.stderr)
    sys.exit(77)

IMU = "sensor_msgs/msg/Imu"
T0_NS = 1_700_000_000_000_000_000
SEC_MARK, NSEC_MARK, ACCEL_MARK = 0x7EADBEEF, 0x1234567, 12345.678


def template(ts, ros1):
    """The serialized message with markers, and the offsets of stamp sec, nsec and accel x."""
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
    V = ts.types["geometry_msgs/msg/Vector3"]
    Q = ts.types["geometry_msgs/msg/Quaternion"]
    stamp = Time(sec=SEC_MARK, nanosec=NSEC_MARK)
    header = Header(seq=0, stamp=stamp, frame_id="imu") if ros1 else Header(stamp=stamp, frame_id="imu")
    cov = np.zeros(9, dtype=np.float64)
    msg = ts.types[IMU](
        header=header, orientation=Q(x=0.0, y=0.0, z=0.0, w=1.0), orientation_covariance=cov,
        angular_velocity=V(x=0.0, y=0.0, z=0.001), angular_velocity_covariance=cov,
        linear_acceleration=V(x=ACCEL_MARK, y=0.0, z=9.8), linear_acceleration_covariance=cov)
    raw = bytes(ts.serialize_ros1(msg, IMU) if ros1 else ts.serialize_cdr(msg, IMU))
    at = lambda b: raw.index(b)
    return (bytearray(raw), at(struct.pack("<I", SEC_MARK)), at(struct.pack("<I", NSEC_MARK)),
            at(struct.pack("<d", ACCEL_MARK)))


def messages(ts, ros1, n):
    buf, sec_at, nsec_at, accel_at = template(ts, ros1)
    for k in range(n):
        t = T0_NS + k * 5_000_000
        struct.pack_into("<II", buf, sec_at, t // 1_000_000_000, t % 1_000_000_000)
        struct.pack_into("<d", buf, accel_at, float(k % 1000))
        if ros1:
            struct.pack_into("<I", buf, 0, k & 0xFFFFFFFF)
        yield t, bytes(buf)


def gen(kind, out, n):
    if kind == "ros1":
        ts = get_typestore(Stores.ROS1_NOETIC)
        with Writer1(out) as w:
            c = w.add_connection("/imu/data", IMU, typestore=ts)
            for t, raw in messages(ts, True, n):
                w.write(c, t, raw)
    else:
        ts = get_typestore(Stores.ROS2_HUMBLE)
        with Writer2(out, version=9, storage_plugin=StoragePlugin.SQLITE3) as w:
            c = w.add_connection("/imu/data", IMU, typestore=ts)
            for t, raw in messages(ts, False, n):
                w.write(c, t, raw)


def read(path):
    start = time.perf_counter()
    stamps, accel, gyro = [], [], []
    with AnyReader([Path(path)]) as reader:
        conns = [c for c in reader.connections if c.msgtype == IMU]
        for c, _t, raw in reader.messages(connections=conns):
            m = reader.deserialize(raw, c.msgtype)
            stamps.append(m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec)
            a, w = m.linear_acceleration, m.angular_velocity
            accel.append((a.x, a.y, a.z))
            gyro.append((w.x, w.y, w.z))
    seconds = time.perf_counter() - start
    print(json.dumps({
        "n": len(stamps),
        "seconds": seconds,
        "sum_accel_x": sum(a[0] for a in accel),
        "max_rss_kib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
    }))


if __name__ == "__main__":
    if sys.argv[1] == "gen":
        gen(sys.argv[2], sys.argv[3], int(sys.argv[4]))
    else:
        read(sys.argv[2])
