"""imud over a fleet: which units' calibrations no longer hold.

:func:`analyze` runs one job per recording (on Ray, or in-process with ``engine="local"``):
the unit, time span, samples and losses, the calibration in force, imud's health checks of
that calibration on every still window (offsets from gravity and Earth rate) and the noise
terms of the longest rest. The rows make the *recordings* table; per unit and parameter a
drift test over time makes the *units* table and the list of units to recalibrate
(:mod:`imud.fleet.drift`); :meth:`FleetResult.write` writes both as a Parquet dataset (any
pyarrow filesystem) and :meth:`FleetResult.write_report` the HTML report. The command line is
``python -m imud.fleet``; the column names are in :mod:`imud.fleet.schema`.
"""

from __future__ import annotations

import os
import posixpath
from dataclasses import dataclass, field
from typing import Any, List, Optional

import pyarrow as pa

from . import schema
from .drift import Tolerances
from .engine import run
from .inputs import find_recordings, resolve
from .job import DEFAULT_MIN_NOISE_SPAN_S, JobOptions

__all__ = ["analyze", "FleetResult", "Tolerances", "schema"]


@dataclass
class FleetResult:
    """The fleet job's result: the recordings table (one row per recording), the units table
    (one row per unit and parameter) and the units to recalibrate."""

    recordings: pa.Table
    units: pa.Table
    flagged: List[str] = field(default_factory=list)

    def write(self, out: Any, filesystem: Any = None) -> None:
        """Writes ``out/recordings/part-0.parquet`` and ``out/units/part-0.parquet``: a local
        directory, a URI any pyarrow filesystem opens, or a path on ``filesystem``. Each file
        carries the schema version in its metadata."""
        import pyarrow.parquet as pq

        fs, root, _ = resolve(os.fspath(out), filesystem)
        for name, table in (("recordings", self.recordings), ("units", self.units)):
            d = posixpath.join(root, name)
            fs.create_dir(d, recursive=True)
            pq.write_table(table, posixpath.join(d, "part-0.parquet"), filesystem=fs)

    def write_report(self, path: Any) -> None:
        """Writes the HTML report (one self-contained file)."""
        from .report import write_report

        write_report(os.fspath(path), self.recordings, self.units, self.flagged)


def analyze(
    recordings: Any,
    *,
    engine: str = "ray",
    ray_address: Optional[str] = None,
    calibration: Any = None,
    unit_column: Optional[str] = None,
    unit_pattern: Optional[str] = None,
    tolerances: Optional[Tolerances] = None,
    alpha: float = 0.01,
    min_noise_span_s: float = DEFAULT_MIN_NOISE_SPAN_S,
    latitude_deg: Optional[float] = None,
    gravity_m_s2: Optional[float] = None,
    filesystem: Any = None,
    now_utc: Any = None,
) -> FleetResult:
    """Analyzes a fleet's recordings.

    ``recordings``: a path, URI or list of them (files, directories searched for recordings,
    imud sessions' rotated files joined). ``engine``: ``"ray"`` (one task per recording; joins
    ``ray_address``, the cluster this process is in, or starts a local instance) or
    ``"local"``. ``calibration``: an :class:`imud.Calibration` or file used where a recording
    carries no calibration in force. ``unit_column``: the device metadata field naming a unit
    (default model and serial number); ``unit_pattern``: a regex on the path (group ``unit``,
    else group 1, else the match). ``tolerances``, ``alpha``: the drift test's
    (:class:`Tolerances`; the fleet's false-alarm rate). ``min_noise_span_s``: shortest rest
    the noise terms are computed on. ``latitude_deg``: where the recordings were made (Earth
    rate in the gyro check, normal gravity; unknown: as :func:`imud.health_check` treats it);
    ``gravity_m_s2``: the local gravity where known (default: normal gravity at the latitude).
    ``filesystem``: a pyarrow filesystem the paths are on.

    Raises FileNotFoundError naming a path that does not exist; a recording that cannot be
    read is a row with ``error`` and the job goes on.
    """
    from .. import Calibration
    from . import drift

    if isinstance(recordings, (str, bytes, os.PathLike)):
        recordings = [recordings]
    specs = find_recordings(list(recordings), filesystem)
    options = JobOptions(
        unit_column=unit_column,
        unit_pattern=unit_pattern,
        min_noise_span_s=float(min_noise_span_s),
        latitude_deg=latitude_deg,
        gravity_m_s2=gravity_m_s2,
    )
    if calibration is not None:
        if not isinstance(calibration, Calibration):
            source = os.fspath(calibration)
            calibration = Calibration.load(source)
            options.calibration_source = source
        options.calibration_toml = calibration.to_toml()
    rows = run(specs, options, engine=engine, ray_address=ray_address)
    table = schema.recordings_table(rows)
    tol = tolerances if tolerances is not None else Tolerances()
    units = schema.conform(drift.analyze_units(table, tol, alpha=alpha, now_utc=now_utc), schema.UNITS)
    return FleetResult(recordings=table, units=units, flagged=drift.flagged_units(units))
