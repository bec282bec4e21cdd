"""Writes a rosbag2 directory (MCAP storage) with `rosbags`, an independent writer, holding two
`sensor_msgs/msg/Imu` topics whose values are a known function of the sample index, split over
two files as a bag split by size is: the Rust input tests read it back and compare with the
truth.

Topic /imu/a, sample k (k = 0..N-1), stamp T0 + k x 10 ms:
  linear_acceleration = (0.125 k, -0.5, 9.75), angular_velocity = (0.001 k, 0.002, -0.003 k)
Topic /imu/b: the same values negated. Samples k < N/2 go to the first file, the rest to the
second.

Usage: write_rosbag2.py OUT_DIR N T0_NS
Exit status 77 means the peer package is missing (the caller decides whether that is a skip).
"""

import shutil
import sys
from pathlib import Path

try:
    import numpy as np
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
except ImportError as e:  # pragma: no cover - depends on the machine
    print(f"missing Python peer: {e}", file=sys.stderr)
    sys.exit(77)


def imu(ts, k, t0_ns, sign):
    Imu = ts.types["sensor_msgs/msg/Imu"]
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
    Vector3 = ts.types["geometry_msgs/msg/Vector3"]
    Quaternion = ts.types["geometry_msgs/msg/Quaternion"]
    t = t0_ns + k * 10_000_000
    cov = np.zeros(9, dtype=np.float64)
    return t, Imu(
        header=Header(stamp=Time(sec=t // 1_000_000_000, nanosec=t % 1_000_000_000), frame_id="imu"),
        orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=cov,
        angular_velocity=Vector3(x=sign * 0.001 * k, y=sign * 0.002, z=sign * -0.003 * k),
        angular_velocity_covariance=cov,
        linear_acceleration=Vector3(x=sign * 0.125 * k, y=sign * -0.5, z=sign * 9.75),
        linear_acceleration_covariance=cov,
    )


def write_part(path, ks, t0_ns, ts):
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conns = [(w.add_connection(topic, "sensor_msgs/msg/Imu", typestore=ts), sign)
                 for topic, sign in (("/imu/a", 1.0), ("/imu/b", -1.0))]
        for k in ks:
            for conn, sign in conns:
                t, msg = imu(ts, k, t0_ns, sign)
                w.write(conn, t, ts.serialize_cdr(msg, "sensor_msgs/msg/Imu"))


def main(out, n, t0_ns):
    out = Path(out)
    ts = get_typestore(Stores.ROS2_HUMBLE)
    parts = [out.parent / (out.name + "-part0"), out.parent / (out.name + "-part1")]
    write_part(parts[0], range(0, n // 2), t0_ns, ts)
    write_part(parts[1], range(n // 2, n), t0_ns, ts)
    # One bag of two files: the first part's metadata listing both.
    out.mkdir()
    names = []
    for i, p in enumerate(parts):
        (mcap,) = p.glob("*.mcap")
        names.append(f"{out.name}_{i}.mcap")
        shutil.move(str(mcap), out / names[-1])
    meta = (parts[0] / "metadata.yaml").read_text()
    old = f"  relative_file_paths:\n  - {parts[0].name}.mcap\n"
    assert old in meta, meta
    meta = meta.replace(old, "  relative_file_paths:\n" + "".join(f"  - {n}\n" for n in names))
    (out / "metadata.yaml").write_text(meta)
    for p in parts:
        shutil.rmtree(p)


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]))
