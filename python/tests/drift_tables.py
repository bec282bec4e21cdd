"""Synthetic recordings tables (the fleet's schema-1 columns the drift analysis reads) with known
truth: per unit and parameter a true bias line, the between-recording scatter tau and the
per-recording standard deviations sigma_i, drawn from a seeded generator."""

from __future__ import annotations

import numpy as np
import pyarrow as pa

EPOCH = np.datetime64("2026-01-01T00:00:00", "ns")
NS_PER_DAY = 86_400 * 10**9
SENSORS = (("accel", "m_s2"), ("gyro", "rad_s"))
PARAMETERS = [f"{s}_bias_{a}" for s, _ in SENSORS for a in "xyz"]

# Realistic MEMS magnitudes: the turn-on scatter tau larger than a recording's own sigma.
TAU = {"accel": 2e-3, "gyro": 1e-4}
SIGMA = {"accel": 5e-4, "gyro": 3e-5}


def column_names(parameter: str):
    """(value, std, calibration) column names of a bias parameter such as "gyro_bias_z"."""
    sensor, _, axis = parameter.split("_")
    unit = dict(SENSORS)[sensor]
    return (
        f"{sensor}_bias_{axis}_{unit}",
        f"{sensor}_bias_std_{axis}_{unit}",
        f"cal_{sensor}_bias_{axis}_{unit}",
    )


def unit_rows(
    rng,
    unit: str,
    days,
    *,
    slope_per_day=None,
    offset=None,
    calibration=None,
    tau=None,
    sigma=None,
):
    """Rows of one unit recorded at ``days`` (days after 2026-01-01). Per parameter (dicts keyed by
    parameter name, missing: the defaults): the true line offset + slope * (day - days[0]); the
    calibration in force per recording (a scalar or an array over ``days``); tau; sigma scale."""
    days = np.asarray(days, dtype=float)
    n = days.size
    rows = {
        "path": [f"/fleet/{unit}/{i}.mcap" for i in range(n)],
        "unit": [unit] * n,
        "start_utc": EPOCH + np.round(days * NS_PER_DAY).astype("timedelta64[ns]"),
        "error": [None] * n,
    }
    for parameter in PARAMETERS:
        sensor = parameter.split("_")[0]
        value_col, std_col, cal_col = column_names(parameter)
        t = (tau or {}).get(parameter, TAU[sensor])
        s = (sigma or {}).get(parameter, SIGMA[sensor]) * rng.uniform(0.5, 2.0, n)
        r = (slope_per_day or {}).get(parameter, 0.0)
        b0 = (offset or {}).get(parameter, 0.0)
        truth = b0 + r * (days - days[0])
        rows[value_col] = truth + rng.normal(0.0, 1.0, n) * t + rng.normal(0.0, 1.0, n) * s
        rows[std_col] = s
        cal = (calibration or {}).get(parameter, 0.0)
        rows[cal_col] = np.broadcast_to(np.asarray(cal, dtype=float), (n,)).copy()
    return rows


def table(*unit_row_dicts) -> pa.Table:
    """One recordings table from the rows of several units."""
    merged: dict = {}
    for rows in unit_row_dicts:
        for key, values in rows.items():
            merged.setdefault(key, []).extend(list(values))
    merged["start_utc"] = pa.array(
        np.asarray(merged["start_utc"], dtype="datetime64[ns]"), type=pa.timestamp("ns")
    ).cast(pa.timestamp("ns", tz="UTC"))
    merged["error"] = pa.array(merged["error"], type=pa.string())
    return pa.table(merged)


def fleet(rng, n_units=8, per_unit=6, span_days=180.0, slopes=None, tau=None):
    """A fleet of ``n_units`` units with ``per_unit`` recordings each, uniformly over
    ``span_days``; ``slopes``: {unit index: {parameter: slope per day}}; ``tau``: {parameter:
    between-recording scatter} (default :data:`TAU`)."""
    units = []
    for u in range(n_units):
        days = np.sort(rng.uniform(0.0, span_days, per_unit))
        units.append(unit_rows(rng, f"GX1 {1000 + u}", days, slope_per_day=(slopes or {}).get(u),
                               tau=tau))
    return table(*units)
