"""Writes ROS logs with `rosbags`, an independent writer, for the Rust readers' tests: ROS 1
bags and rosbag2 sqlite3 bags holding a known truth, and one of our MCAP recordings converted
into a ROS 1 bag, a sqlite3 bag and a rosbag2 MCAP bag (its IMU and temperature topics).

Truth (modes `ros1` and `sqlite3`), sample k = 0..N-1, stamp T0 + k x 10 ms:
  /imu/a: linear_acceleration = (0.125 k, -0.5, 9.75), angular_velocity = (0.001 k, 0.002, -0.003 k)
  /imu/b: the same values negated
  /imu/temperature: 20 + 0.01 k deg C (sensor_msgs/Temperature)

Usage:
  write_ros_logs.py ros1 OUT.bag N T0_NS none|bz2|lz4 CHUNK_BYTES
  write_ros_logs.py sqlite3 OUT_DIR N T0_NS none|file|message
      (two files, samples k < N/2 in the first: a split bag)
  write_ros_logs.py convert RECORDING.mcap OUT_PREFIX
      (OUT_PREFIX.bag, OUT_PREFIX-db3/, OUT_PREFIX-mcap/)
Exit status 77 means the peer package is missing (the caller decides whether that is a skip).
"""

import shutil
import sys
from pathlib import Path

try:
    import numpy as np
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys import Stores, get_typestore
except ImportError as e:  # pragma: no cover - depends on the machine
    print(f"missing Python peer: {e}", file=sys.stderr)
    sys.exit(77)

IMU = "sensor_msgs/msg/Imu"
TEMPERATURE = "sensor_msgs/msg/Temperature"
TOPICS = (("/imu/a", 1.0), ("/imu/b", -1.0))


def stamp(ts, t):
    return ts.types["builtin_interfaces/msg/Time"](sec=t // 1_000_000_000, nanosec=t % 1_000_000_000)


def header(ts, t, ros1, seq):
    Header = ts.types["std_msgs/msg/Header"]
    if ros1:
        return Header(seq=seq, stamp=stamp(ts, t), frame_id="imu")
    return Header(stamp=stamp(ts, t), frame_id="imu")


def truth(ts, k, t0_ns, sign, ros1):
    """The IMU message of sample k (and its time)."""
    Vector3 = ts.types["geometry_msgs/msg/Vector3"]
    Quaternion = ts.types["geometry_msgs/msg/Quaternion"]
    t = t0_ns + k * 10_000_000
    cov = np.zeros(9, dtype=np.float64)
    return t, ts.types[IMU](
        header=header(ts, t, ros1, k),
        orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=cov,
        angular_velocity=Vector3(x=sign * 0.001 * k, y=sign * 0.002, z=sign * -0.003 * k),
        angular_velocity_covariance=cov,
        linear_acceleration=Vector3(x=sign * 0.125 * k, y=sign * -0.5, z=sign * 9.75),
        linear_acceleration_covariance=cov,
    )


def temperature(ts, k, t0_ns, ros1):
    t = t0_ns + k * 10_000_000
    return t, ts.types[TEMPERATURE](header=header(ts, t, ros1, k), temperature=20.0 + 0.01 * k, variance=0.0)


def ros1(out, n, t0_ns, compression, chunk_bytes):
    ts = get_typestore(Stores.ROS1_NOETIC)
    w = Writer1(out)
    if compression != "none":
        w.set_compression(getattr(Writer1.CompressionFormat, compression.upper()))
    w.chunk_threshold = chunk_bytes
    with w:
        conns = [(w.add_connection(topic, IMU, typestore=ts), sign) for topic, sign in TOPICS]
        temp = w.add_connection("/imu/temperature", TEMPERATURE, typestore=ts)
        for k in range(n):
            for conn, sign in conns:
                t, msg = truth(ts, k, t0_ns, sign, True)
                w.write(conn, t, ts.serialize_ros1(msg, IMU))
            t, msg = temperature(ts, k, t0_ns, True)
            w.write(temp, t, ts.serialize_ros1(msg, TEMPERATURE))


def sqlite3_part(path, ks, t0_ns, mode, ts):
    w = Writer2(path, version=9, storage_plugin=StoragePlugin.SQLITE3)
    if mode != "none":
        w.set_compression(getattr(CompressionMode, mode.upper()), CompressionFormat.ZSTD)
    with w:
        conns = [(w.add_connection(topic, IMU, typestore=ts), sign) for topic, sign in TOPICS]
        temp = w.add_connection("/imu/temperature", TEMPERATURE, typestore=ts)
        for k in ks:
            for conn, sign in conns:
                t, msg = truth(ts, k, t0_ns, sign, False)
                w.write(conn, t, ts.serialize_cdr(msg, IMU))
            t, msg = temperature(ts, k, t0_ns, False)
            w.write(temp, t, ts.serialize_cdr(msg, TEMPERATURE))


def sqlite3(out, n, t0_ns, mode):
    """A bag of two files, as a bag split by size is: the first part's metadata listing both."""
    out = Path(out)
    ts = get_typestore(Stores.ROS2_HUMBLE)
    parts = [out.parent / (out.name + "-part0"), out.parent / (out.name + "-part1")]
    sqlite3_part(parts[0], range(0, n // 2), t0_ns, mode, ts)
    sqlite3_part(parts[1], range(n // 2, n), t0_ns, mode, ts)
    out.mkdir()
    names = []
    for i, p in enumerate(parts):
        (f,) = [f for f in p.iterdir() if f.name != "metadata.yaml"]
        names.append(f.name.replace(p.name, f"{out.name}_{i}"))
        shutil.move(str(f), out / names[-1])
    meta = (parts[0] / "metadata.yaml").read_text()
    first = next(line for line in meta.splitlines() if line.startswith("  - ") and parts[0].name in line)
    old = f"  relative_file_paths:\n{first}\n"
    assert old in meta, meta
    meta = meta.replace(old, "  relative_file_paths:\n" + "".join(f"  - {n}\n" for n in names))
    (out / "metadata.yaml").write_text(meta)
    for p in parts:
        shutil.rmtree(p)


def convert(recording, prefix):
    """The recording's IMU and temperature topics, as written, into the three formats."""
    ts2 = get_typestore(Stores.ROS2_HUMBLE)
    ts1 = get_typestore(Stores.ROS1_NOETIC)
    prefix = Path(prefix)
    bag1 = prefix.parent / (prefix.name + ".bag")
    w1 = Writer1(bag1)
    w1.set_compression(Writer1.CompressionFormat.LZ4)
    w1.open()
    writers2 = [Writer2(prefix.parent / (prefix.name + f"-{s}"), version=9, storage_plugin=p)
                for s, p in (("db3", StoragePlugin.SQLITE3), ("mcap", StoragePlugin.MCAP))]
    for w in writers2:
        w.open()
    conns = {}
    with AnyReader([Path(recording)]) as reader:
        wanted = [c for c in reader.connections if c.msgtype in (IMU, TEMPERATURE)]
        for c in wanted:
            conns[c.id] = (
                w1.add_connection(c.topic, c.msgtype, typestore=ts1),
                [w.add_connection(c.topic, c.msgtype, typestore=ts2) for w in writers2],
            )
        for c, t, raw in reader.messages(connections=wanted):
            c1, c2s = conns[c.id]
            w1.write(c1, t, ts2.cdr_to_ros1(raw, c.msgtype))
            for w, c2 in zip(writers2, c2s):
                w.write(c2, t, raw)
    w1.close()
    for w in writers2:
        w.close()


if __name__ == "__main__":
    mode = sys.argv[1]
    if mode == "ros1":
        ros1(sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), sys.argv[5], int(sys.argv[6]))
    elif mode == "sqlite3":
        sqlite3(sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), sys.argv[5])
    elif mode == "convert":
        convert(sys.argv[2], sys.argv[3])
    else:
        sys.exit(f"unknown mode {mode}")
