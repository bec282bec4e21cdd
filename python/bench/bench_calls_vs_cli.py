"""The Python calls against the command-line clients on the same recording (issue 25): wall time
and peak resident memory of `imud.calibrate`, `imud.diagnose` and `imud.ladder` against
`imu-calibrate`, `imu-diagnose` and `imu-diagnose ladder` with the same options and `--json`, each
in a fresh process so that neither sees the other's allocations; and `imud.read` and
`Calibration.correct` on their own (no client reads without analysing, and none corrects a
recording offline: the daemon corrects live).

    python3 python/bench/bench_calls_vs_cli.py --bin-dir target/release --repeat 3 \\
        --latitude-deg 40 REC.mcap

REC.mcap: a reference-free recording (still poses and the moves between them, e.g. the shipped
multi-pose scenario recorded by `imud --sim config/scenarios/multi-pose.toml --offline`). The
package must be installed from the same build profile as the binaries. Prints one JSON document;
BENCHMARKS.md records a run.
"""

import argparse
import json
import os
import subprocess
import sys

# Each Python call in a fresh interpreter: (seconds of the call, RSS after import, peak RSS).
PY_CALL = """
import resource, sys, time
import numpy as np
import imud
what, rec, lat = sys.argv[1], sys.argv[2], float(sys.argv[3])
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
if what == "correct":
    cal = imud.calibrate(rec, reference_free=True, latitude_deg=lat).calibration
    n = int(sys.argv[4])
    rng = np.random.default_rng(1)
    accel = rng.normal(0.0, 9.81, (n, 3))
    gyro = rng.normal(0.0, 1.0, (n, 3))
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t0 = time.perf_counter()
if what == "calibrate":
    r = imud.calibrate(rec, reference_free=True, latitude_deg=lat)
elif what == "diagnose":
    r = imud.diagnose(rec, reference_free=True, latitude_deg=lat)
elif what == "ladder":
    r = imud.ladder(rec, reference_free=True, latitude_deg=lat)
elif what == "read":
    r = imud.read(rec, source="raw")
    r = (r.time_s, r.accel_m_s2, r.gyro_rad_s)
elif what == "correct":
    r = cal.correct(accel, gyro, temperature_c=25.0)
t1 = time.perf_counter()
print(t1 - t0, base, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""

CLI_ARGS = {
    "calibrate": ("imu-calibrate", []),
    "diagnose": ("imu-diagnose", []),
    "ladder": ("imu-diagnose", ["ladder"]),
}


def timed(cmd):
    """(wall s, peak KiB, stdout) of `cmd` under /usr/bin/time."""
    out = subprocess.run(
        ["/usr/bin/time", "-f", "%e %M", *cmd], capture_output=True, text=True
    )
    if out.returncode != 0:
        sys.exit(f"{cmd}: {out.stderr}")
    wall_s, peak_kib = out.stderr.strip().splitlines()[-1].split()
    return float(wall_s), int(peak_kib), out.stdout


def python_call(what, rec, lat, extra=()):
    """(call s, process s, RSS after import KiB, process peak KiB)."""
    proc_s, proc_kib, stdout = timed(
        [sys.executable, "-c", PY_CALL, what, rec, str(lat), *extra]
    )
    call_s, base_kib, _ = stdout.split()
    return float(call_s), proc_s, int(base_kib), proc_kib


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("recording")
    ap.add_argument("--bin-dir", default="target/release")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--latitude-deg", type=float, default=40.0)
    ap.add_argument("--correct-samples", type=int, default=10_000_000)
    ap.add_argument(
        "--calls",
        default="calibrate,diagnose,ladder,read,correct",
        help="which calls to measure, comma separated",
    )
    a = ap.parse_args()
    calls = a.calls.split(",")
    rec, lat = a.recording, a.latitude_deg
    result = {"recording": rec, "repeat": a.repeat}
    for what, (tool, sub) in CLI_ARGS.items():
        if what not in calls:
            continue
        exe = os.path.join(a.bin_dir, tool)
        cmd = [exe, *sub, rec, "--reference-free", "--latitude-deg", str(lat), "--json"]
        if what == "ladder":
            cmd += ["-o", os.devnull]
        # Interleaved, so that a change of the machine's load falls on both alike.
        cli, py = [], []
        for _ in range(a.repeat):
            cli.append(timed(cmd)[:2])
            py.append(python_call(what, rec, lat))
        cli_s, cli_kib = min(c[0] for c in cli), min(c[1] for c in cli)
        call_s, proc_s = min(p[0] for p in py), min(p[1] for p in py)
        base_kib, proc_kib = min(p[2] for p in py), min(p[3] for p in py)
        result[what] = {
            "cli_wall_s": cli_s,
            "python_call_s": call_s,
            "python_process_s": proc_s,
            "call_overhead_pct": 100 * (call_s / cli_s - 1),
            "cli_peak_mib": cli_kib / 1024,
            "python_import_mib": base_kib / 1024,
            "python_peak_mib": proc_kib / 1024,
            "python_peak_less_import_mib": (proc_kib - base_kib) / 1024,
        }
    for what, extra in (("read", ()), ("correct", (str(a.correct_samples),))):
        if what not in calls:
            continue
        py = [python_call(what, rec, lat, extra) for _ in range(a.repeat)]
        result[what] = {
            "python_call_s": min(p[0] for p in py),
            "python_peak_less_before_mib": min(p[3] - p[2] for p in py) / 1024,
        }
    if "correct" in result:
        result["correct"]["samples"] = a.correct_samples
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
