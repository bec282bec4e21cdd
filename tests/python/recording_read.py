"""Decodes an imud MCAP recording with the reference Python readers (`mcap` + `mcap-ros2-support`,
an independent peer that parses our ros2msg schema text itself) and prints JSON for the Rust
interoperability test to compare with what it wrote.

Usage: recording_read.py FILE [--stream]
  --stream  read with the non-seeking reader, front to back, as for a file whose writer was
            killed (no summary): prints what it got before the damage and the error it stopped at.

Exit status 77 means a peer package is missing (the caller decides whether that is a skip).
"""

import json
import math
import sys

try:
    from mcap.reader import NonSeekingReader, make_reader
    from mcap_ros2.decoder import DecoderFactory
except ImportError as e:  # pragma: no cover - depends on the machine
    print(f"missing Python peer: {e}", file=sys.stderr)
    sys.exit(77)


def num(x):
    """JSON has no NaN/inf: spell them as strings."""
    if isinstance(x, float) and not math.isfinite(x):
        return str(x)
    return x


def stamp(h):
    return {"sec": h.stamp.sec, "nanosec": h.stamp.nanosec, "frame_id": h.frame_id}


def vec3(v):
    return [num(v.x), num(v.y), num(v.z)]


def floats(a):
    return [num(float(x)) for x in a]


def convert(topic, m):
    if topic in ("/imu/data", "/imu/device_compensated"):
        q = m.orientation
        return {
            "header": stamp(m.header),
            "orientation": [q.x, q.y, q.z, q.w],
            "orientation_covariance": floats(m.orientation_covariance),
            "angular_velocity": vec3(m.angular_velocity),
            "angular_velocity_covariance": floats(m.angular_velocity_covariance),
            "linear_acceleration": vec3(m.linear_acceleration),
            "linear_acceleration_covariance": floats(m.linear_acceleration_covariance),
        }
    if topic == "/imu/mag":
        return {
            "header": stamp(m.header),
            "magnetic_field": vec3(m.magnetic_field),
            "magnetic_field_covariance": floats(m.magnetic_field_covariance),
        }
    if topic == "/imu/temperature":
        return {"header": stamp(m.header), "temperature": num(m.temperature), "variance": num(m.variance)}
    if topic == "/imu/raw":
        out = {"header": stamp(m.header)}
        for f in ["seq", "t_device_ns", "t_host_monotonic_ns", "t_host_wall_ns", "t_sample_ns",
                  "ticks_unwrapped", "ticks", "command", "reserved", "flags"]:
            out[f] = getattr(m, f)
        for f in ["accel_counts", "gyro_counts", "mag_counts"]:
            out[f] = [int(x) for x in getattr(m, f)]
        out["temp_c"] = num(m.temp_c)
        for f in ["accel_device_m_s2", "gyro_device_rad_s", "mag_device_gauss"]:
            out[f] = floats(getattr(m, f))
        return out
    if topic == "/imu/raw_frame":
        return {
            "header": stamp(m.header),
            "t_host_monotonic_ns": m.t_host_monotonic_ns,
            "stream_offset": m.stream_offset,
            "accepted": bool(m.accepted),
            "reject_reason": m.reject_reason,
            "data": list(bytes(m.data)),
        }
    if topic == "/imud/status":
        out = {"header": stamp(m.header)}
        for f in ["t_host_monotonic_ns", "frames", "samples", "checksum_failures", "resyncs",
                  "garbage_bytes", "truncated_frames", "samples_lost", "log_drops", "publish_drops",
                  "reconnects", "calibration_id", "device_connected", "logging", "gains_fallback",
                  "health_accel", "health_gyro", "protocol", "configuration_unverified", "reserved",
                  "gain_scale_accel", "gain_scale_gyro", "gain_scale_mag",
                  "packets_unusable", "fields_skipped", "time_source", "time_sync",
                  "gnss_valid_transitions", "gnss_lost_transitions"]:
            out[f] = getattr(m, f)
        for f in ["tick_period_est_s", "clock_drift_ppm", "temp_c", "clock_offset_s", "clock_residual_s",
                  "gnss_minus_wall_s", "gnss_drift_ppm"]:
            out[f] = num(getattr(m, f))
        return out
    if topic == "/imud/health":
        out = {"header": stamp(m.header)}
        for f in ["t_sample_ns", "t_wall_ns", "window_start_ns", "calibration_id", "still_windows",
                  "plateaus_skipped", "accel_state", "gyro_state", "checks", "noise_source",
                  "bias_tracking"]:
            out[f] = getattr(m, f)
        for f in ["accel_residual_m_s2", "accel_expected_std_m_s2", "accel_p", "gyro_residual_rad_s",
                  "gyro_vertical_residual_rad_s", "gyro_expected_std_rad_s", "gyro_p", "gravity_m_s2",
                  "temp_c"]:
            out[f] = num(getattr(m, f))
        for f in ["accel_offset_m_s2", "gyro_offset_rad_s"]:
            out[f] = [num(x) for x in getattr(m, f)]
        return out
    if topic == "/imud/calibration":
        return {"header": stamp(m.header), "id": m.id, "toml": m.toml}
    return None


def main(path, stream):
    out = {"messages": {}, "schemas": {}, "error": None}
    with open(path, "rb") as f:
        factories = [DecoderFactory()]
        reader = NonSeekingReader(f, decoder_factories=factories) if stream else make_reader(f, decoder_factories=factories)
        try:
            if not stream:  # a non-seeking reader answers one query only
                out["profile"] = reader.get_header().profile
            # File order: a non-seeking reader sorting by log time would hold everything back
            # until the end, and lose it all at the damage.
            for schema, channel, _message, decoded in reader.iter_decoded_messages(log_time_order=False):
                out["schemas"][channel.topic] = [schema.name, schema.encoding, channel.message_encoding]
                value = convert(channel.topic, decoded)
                if value is not None:
                    out["messages"].setdefault(channel.topic, []).append(value)
            if not stream:
                out["metadata"] = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
                out["statistics_message_count"] = reader.get_summary().statistics.message_count
        except Exception as e:  # a killed writer's file ends in a damaged record
            if not stream:
                raise
            out["error"] = f"{type(e).__name__}: {e}"
    print(json.dumps(out))


if __name__ == "__main__":
    args = sys.argv[1:]
    main(args[0], "--stream" in args[1:])
