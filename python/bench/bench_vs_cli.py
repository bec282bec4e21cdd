"""The Python calls against the command-line clients on the same recording (issue 25,
deliverable 4): wall time of `imud.noise(path)` against `imu-noise path --json`, and the peak
resident memory of each, in fresh processes so that neither sees the other's allocations.

    python3 python/bench/bench_vs_cli.py --bin-dir target/release REC.mcap [--repeat 3]

The package must be installed from the same build profile as the binaries (release:
`pip install ./python`). Prints one table; BENCHMARKS.md records a run.
"""

import argparse
import json
import os
import subprocess
import sys

PY_CALL = """
import resource, sys, time
import imud
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t0 = time.perf_counter()
r = imud.noise(sys.argv[1])
t1 = time.perf_counter()
d = r.to_list()
print(t1 - t0, base, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, len(d))
"""


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("recording")
    ap.add_argument("--bin-dir", default="target/release")
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    noise = os.path.join(a.bin_dir, "imu-noise")
    rows = []
    for _ in range(a.repeat):
        # CLI: whole process (read, analysis, JSON written).
        cmd = ["/usr/bin/time", "-f", "%e %M", noise, a.recording, "--json"]
        out = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        wall_s, peak_kib = out.stderr.strip().splitlines()[-1].split()
        cli = (float(wall_s), int(peak_kib))
        # Python: the call in a fresh interpreter, and the whole process.
        cmd = ["/usr/bin/time", "-f", "%e %M", sys.executable, "-c", PY_CALL, a.recording]
        out = subprocess.run(cmd, capture_output=True, text=True)
        if out.returncode != 0:
            sys.exit(out.stderr)
        call_s, base_kib, peak_py_kib, _ = out.stdout.split()
        proc_s, proc_kib = out.stderr.strip().splitlines()[-1].split()
        rows.append((cli, float(call_s), float(proc_s), int(base_kib), int(proc_kib)))
    best = lambda k: min(r[k] for r in rows)  # noqa: E731
    cli_s = min(r[0][0] for r in rows)
    cli_kib = min(r[0][1] for r in rows)
    print(json.dumps({
        "recording": a.recording,
        "cli_wall_s": cli_s,
        "python_call_s": best(1),
        "python_process_s": best(2),
        "call_overhead_pct": 100 * (best(1) / cli_s - 1),
        "process_overhead_pct": 100 * (best(2) / cli_s - 1),
        "cli_peak_mib": cli_kib / 1024,
        "python_import_peak_mib": best(3) / 1024,
        "python_peak_mib": best(4) / 1024,
        "python_peak_less_import_mib": (best(4) - best(3)) / 1024,
    }, indent=1))


if __name__ == "__main__":
    main()
