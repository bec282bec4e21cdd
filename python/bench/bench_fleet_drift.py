"""The fleet's per-unit drift analysis and HTML report at fleet scale (issue 29): wall time of
`imud.fleet.drift.analyze_units` on a synthetic recordings table of N recordings from U units
(6 bias parameters each, 2 % of the units drifting), and of `imud.fleet.report.write_report` on
its result.

    python3 python/bench/bench_fleet_drift.py --recordings 100000 --units 2000 [--repeat 3]

The synthetic table is the one the tests build (python/tests/drift_tables.py). Prints one JSON
document; BENCHMARKS.md records a run.
"""

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from drift_tables import table, unit_rows  # noqa: E402

from imud.fleet import drift, report  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--recordings", type=int, default=100_000)
    ap.add_argument("--units", type=int, default=2_000)
    ap.add_argument("--span-days", type=float, default=365.0)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    rng = np.random.default_rng(1)
    per_unit = args.recordings // args.units
    rows = []
    for u in range(args.units):
        slopes = {"gyro_bias_z": 3e-6} if u % 50 == 0 else None
        days = np.sort(rng.uniform(0.0, args.span_days, per_unit))
        rows.append(unit_rows(rng, f"GX1 {u:05d}", days, slope_per_day=slopes))
    recordings = table(*rows)
    analyze_s, report_s = [], []
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        units = drift.analyze_units(recordings)
        analyze_s.append(time.perf_counter() - t0)
        flagged = drift.flagged_units(units)
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            report.write_report(os.path.join(tmp, "fleet.html"), recordings, units, flagged)
            report_s.append(time.perf_counter() - t0)
            size = os.path.getsize(os.path.join(tmp, "fleet.html"))
    print(json.dumps({
        "recordings": recordings.num_rows,
        "units": args.units,
        "tests": int(units.schema.metadata[b"imud.fleet.drift.tests"]),
        "flagged": len(flagged),
        "analyze_units_s": sorted(analyze_s),
        "write_report_s": sorted(report_s),
        "report_bytes": size,
        "cpu": os.cpu_count(),
    }, indent=1))


if __name__ == "__main__":
    main()
