"""``python -m imud.fleet RECORDINGS... --out results.parquet --report fleet.html``: the fleet
job from the command line (see :func:`imud.fleet.analyze`)."""

from __future__ import annotations

import argparse
import sys
from typing import List, Optional

from .job import DEFAULT_MIN_NOISE_SPAN_S


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m imud.fleet",
        description=(
            "Which units' calibrations no longer hold: one job per recording (on Ray or "
            "in-process) checks the calibration in force on every still window against gravity "
            "and Earth rate; per unit, a drift test over the recordings' dates flags the units "
            "to recalibrate. Writes a Parquet dataset (OUT/recordings, OUT/units) and an HTML "
            "report."
        ),
    )
    p.add_argument(
        "recordings", nargs="+", metavar="RECORDINGS",
        help="recording files, directories searched for recordings (an imud session's rotated "
        "files are one recording), or URIs any pyarrow filesystem opens (s3://, gs://, ...)",
    )
    p.add_argument("--out", required=True, help="the Parquet dataset to write (directory or URI)")
    p.add_argument("--report", help="the HTML report to write")
    p.add_argument("--engine", choices=("ray", "local"), default="ray",
                   help="ray: one task per recording (default); local: in this process")
    p.add_argument("--ray-address", help="the Ray cluster to join (default: the one this "
                   "process runs in, else a local instance)")
    p.add_argument("--calibration", metavar="FILE",
                   help="calibration in force for recordings that carry none")
    p.add_argument("--unit-column", metavar="COL",
                   help="device metadata field naming a unit (default: model and serial number)")
    p.add_argument("--unit-pattern", metavar="REGEX",
                   help="regex on the path naming a unit (group 'unit', else group 1, else the match)")
    p.add_argument("--tolerance", metavar="SPEC",
                   help="tolerances around the calibration, e.g. accel-bias=0.02,gyro-bias=1e-3 "
                   "(m/s^2, rad/s)")
    p.add_argument("--alpha", type=float, default=0.01,
                   help="the fleet's false-alarm rate of the drift test (default 0.01)")
    p.add_argument("--min-noise-span-s", type=float, default=DEFAULT_MIN_NOISE_SPAN_S,
                   help=f"shortest rest the noise terms are computed on, s (default "
                   f"{DEFAULT_MIN_NOISE_SPAN_S:g})")
    p.add_argument("--latitude-deg", type=float,
                   help="latitude of the recordings (Earth rate in the gyro check, normal gravity)")
    p.add_argument("--gravity-m-s2", type=float,
                   help="local gravity, m/s^2 (default: normal gravity at --latitude-deg)")
    return p


def main(argv: Optional[List[str]] = None) -> int:
    args = parser().parse_args(argv)
    from .. import ImudError
    from . import Tolerances, analyze

    try:
        tol = Tolerances.parse(args.tolerance) if args.tolerance else None
        result = analyze(
            args.recordings,
            engine=args.engine,
            ray_address=args.ray_address,
            calibration=args.calibration,
            unit_column=args.unit_column,
            unit_pattern=args.unit_pattern,
            tolerances=tol,
            alpha=args.alpha,
            min_noise_span_s=args.min_noise_span_s,
            latitude_deg=args.latitude_deg,
            gravity_m_s2=args.gravity_m_s2,
        )
        result.write(args.out)
        if args.report:
            result.write_report(args.report)
    except (FileNotFoundError, ValueError, ImudError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    rec = result.recordings
    with_evidence = rec.column("error").null_count
    print(
        f"{rec.num_rows} recordings ({with_evidence} with evidence), "
        f"{len(set(rec.column('unit').to_pylist()) - {None})} units; "
        f"to recalibrate: {', '.join(result.flagged) if result.flagged else 'none'}"
    )
    print(f"wrote {args.out}" + (f" and {args.report}" if args.report else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
