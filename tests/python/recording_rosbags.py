"""Opens an imud MCAP recording as a ROS 2 bag with `rosbags` (AnyReader, the reader the issue's
acceptance names) and prints JSON: the connections it sees and a few decoded fields per topic,
for the Rust interoperability test to compare with what it wrote.

Usage: recording_rosbags.py FILE
Exit status 77 means the peer package is missing (the caller decides whether that is a skip).
"""

import json
import sys
from pathlib import Path

try:
    from rosbags.highlevel import AnyReader
except ImportError as e:  # pragma: no cover - depends on the machine
    print(f"missing Python peer: {e}", file=sys.stderr)
    sys.exit(77)


def main(path):
    out = {"connections": {}, "imu": [], "raw_seq": [], "raw_frame_data": [], "temperature": [], "mag": []}
    with AnyReader([Path(path)]) as reader:
        for c in reader.connections:
            out["connections"][c.topic] = c.msgtype
        for connection, _timestamp, raw in reader.messages():
            msg = reader.deserialize(raw, connection.msgtype)
            if connection.topic == "/imu/data":
                out["imu"].append({
                    "stamp_ns": msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec,
                    "frame_id": msg.header.frame_id,
                    "angular_velocity": [msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z],
                    "linear_acceleration": [msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z],
                    "orientation_covariance_0": float(msg.orientation_covariance[0]),
                    "linear_acceleration_covariance": [float(x) for x in msg.linear_acceleration_covariance],
                })
            elif connection.topic == "/imu/raw":
                out["raw_seq"].append(int(msg.seq))
            elif connection.topic == "/imu/raw_frame":
                out["raw_frame_data"].append([int(x) for x in msg.data])
            elif connection.topic == "/imu/temperature":
                out["temperature"].append(float(msg.temperature))
            elif connection.topic == "/imu/mag":
                out["mag"].append([msg.magnetic_field.x, msg.magnetic_field.y, msg.magnetic_field.z])
    print(json.dumps(out))


if __name__ == "__main__":
    main(sys.argv[1])
