"""Reads an imu-sim truth file with the reference Python `mcap` reader (an independent peer) and
prints a JSON summary for the Rust test to compare with its own reading."""

import json
import sys

from mcap.reader import make_reader


def main(path: str) -> None:
    summary = {"samples": 0, "segments": 0, "seqs_in_order": True, "metadata": [], "ticks": []}
    last_seq = -1
    with open(path, "rb") as f:
        reader = make_reader(f)
        for _schema, channel, message in reader.iter_messages():
            record = json.loads(message.data)
            if channel.topic == "/truth/sample":
                summary["samples"] += 1
                if record["seq"] != last_seq + 1:
                    summary["seqs_in_order"] = False
                last_seq = record["seq"]
                summary["ticks"].append(record["ticks"])
            elif channel.topic == "/truth/segment":
                summary["segments"] += 1
        for meta in reader.iter_metadata():
            summary["metadata"].append(meta.name)
        stats = reader.get_summary().statistics
        summary["statistics_message_count"] = stats.message_count
    print(json.dumps(summary))


if __name__ == "__main__":
    main(sys.argv[1])
