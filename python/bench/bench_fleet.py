"""The fleet job on Ray against a plain sequential loop, same recordings, same run (issue 29):
recordings per second each way, the per-recording cost split (read, health check, noise terms)
from the recordings table's timing columns, Ray's start-up and per-task overhead (empty tasks),
and the data size.

    python3 -m imud.fleet.simulate /tmp/fleet --recordings 7 --imud target/release/imud
    unshare -rn sh -c 'ip link set lo up && exec python3 python/bench/bench_fleet.py \\
        /tmp/fleet/recordings --cpus 2 --latitude-deg 40'

(``unshare -rn``: Ray's servers listen on every interface; in a namespace of their own they
listen on loopback only.) The package must be installed from the build being measured. Prints
one JSON document; BENCHMARKS.md records a run and what 100,000 recordings cost on N nodes.
"""

import argparse
import json
import os
import statistics
import time

import imud
from imud.fleet import engine
from imud.fleet.inputs import find_recordings
from imud.fleet.job import JobOptions


def _split(rows):
    out = {}
    for c in ("read_s", "check_s", "noise_s"):
        v = [r[c] for r in rows if r.get(c) is not None]
        out[c] = {"mean": statistics.fmean(v), "median": statistics.median(v), "n": len(v)}
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("recordings", nargs="+")
    p.add_argument("--cpus", type=int, default=2, help="CPUs of the local Ray cluster")
    p.add_argument("--latitude-deg", type=float)
    p.add_argument("--empty-tasks", type=int, default=2000)
    a = p.parse_args()

    specs = find_recordings(a.recordings)
    files = [f for s in specs for f in s.files]
    size = sum(os.path.getsize(f) for f in files)
    opts = JobOptions(latitude_deg=a.latitude_deg)
    doc = {
        "imud": imud.__version__,
        "recordings": len(specs),
        "bytes": size,
        "bytes_per_recording": size / len(specs),
        "cpus": a.cpus,
    }

    t0 = time.perf_counter()
    rows = engine.run(specs, opts, engine="local")
    seq_s = time.perf_counter() - t0
    doc["sequential"] = {"s": seq_s, "recordings_per_s": len(specs) / seq_s}
    doc["samples_per_recording"] = statistics.fmean(r.get("samples") or 0 for r in rows)
    doc["split_s"] = _split(rows)

    import ray

    t0 = time.perf_counter()
    ray.init(num_cpus=a.cpus, include_dashboard=False, log_to_driver=False)
    doc["ray_init_s"] = time.perf_counter() - t0
    try:
        # First run: the workers start and import imud; second: warm workers.
        for name in ("ray_cold", "ray_warm"):
            t0 = time.perf_counter()
            ray_rows = engine.run(specs, opts, engine="ray")
            s = time.perf_counter() - t0
            doc[name] = {"s": s, "recordings_per_s": len(specs) / s}
        doc["ray_split_s"] = _split(ray_rows)

        @ray.remote(num_cpus=1)
        def empty(i):
            return i

        ray.get([empty.remote(i) for i in range(100)])  # warm
        t0 = time.perf_counter()
        ray.get([empty.remote(i) for i in range(a.empty_tasks)])
        s = time.perf_counter() - t0
        doc["ray_empty_task"] = {"n": a.empty_tasks, "s": s, "per_task_s": s / a.empty_tasks}
    finally:
        ray.shutdown()
    doc["speedup_warm"] = doc["ray_warm"]["recordings_per_s"] / doc["sequential"]["recordings_per_s"]
    print(json.dumps(doc, indent=1))


if __name__ == "__main__":
    main()
