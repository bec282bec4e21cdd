"""Reads an MCAP file the way a user types it: `make_reader(f)` and its default
`iter_messages()` (log-time order, which needs the summary and chunk indexes), and prints JSON:
messages per topic, the `/imu/raw` sequence numbers in order, the last log time, and the error
if the read failed (a file without a footer raises here; a repaired one must not).

Usage: recording_default_read.py FILE
Exit status 77 means the peer package is missing (the caller decides whether that is a skip).
"""

import json
import sys

try:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
except ImportError as e:  # pragma: no cover - depends on the machine
    print(f"missing Python peer: {e}", file=sys.stderr)
    sys.exit(77)


def main(path):
    out = {"count": {}, "raw_seq": [], "last_log_time_ns": None, "error": None}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        try:
            for _schema, channel, message in reader.iter_messages():
                out["count"][channel.topic] = out["count"].get(channel.topic, 0) + 1
                t = message.log_time
                if out["last_log_time_ns"] is None or t > out["last_log_time_ns"]:
                    out["last_log_time_ns"] = t
            for _s, channel, _m, decoded in reader.iter_decoded_messages(topics=["/imu/raw"]):
                out["raw_seq"].append(int(decoded.seq))
        except Exception as e:  # what an unrepaired file does
            out["error"] = f"{type(e).__name__}: {e}"
    print(json.dumps(out))


if __name__ == "__main__":
    main(sys.argv[1])
