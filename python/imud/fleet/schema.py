"""The fleet job's two tables as Arrow schemas (version 1): one home for their column names.

- the *recordings* table: one row per recording (:func:`imud.fleet.job.analyze_recording`);
- the *units* table: one row per unit and parameter (:func:`imud.fleet.drift.analyze_units`).

Every Parquet file the job writes carries :data:`SCHEMA_VERSION` under :data:`META_SCHEMA_VERSION`
and the package's version under :data:`META_IMUD_VERSION` in its key-value metadata. A change to
a column's name, type or meaning is a new version.
"""

from __future__ import annotations

from typing import Dict, List, Tuple

import pyarrow as pa

SCHEMA_VERSION = "1"
META_SCHEMA_VERSION = "imud.fleet.schema-version"
META_IMUD_VERSION = "imud.version"
META_TABLE = "imud.fleet.table"

#: The two triads checked and the unit suffix of their columns (accel m/s^2, gyro rad/s).
TRIADS: Tuple[Tuple[str, str], ...] = (("accel", "m_s2"), ("gyro", "rad_s"))
AXES = "xyz"
#: Wall-clock time of a recording's stages, s: excluded when results are compared.
TIMING_COLUMNS = ("read_s", "check_s", "noise_s")

UTC = pa.timestamp("ns", tz="UTC")


def cal_bias(triad: str, axis: str) -> str:
    """The calibration in force's bias (0 when it has no bias effect)."""
    return f"cal_{triad}_bias_{axis}_{_unit(triad)}"


def offset(triad: str, axis: str) -> str:
    """The calibrated stream's offset from physics over the recording's still windows."""
    return f"{triad}_offset_{axis}_{_unit(triad)}"


def offset_std(triad: str, axis: str) -> str:
    return f"{triad}_offset_std_{axis}_{_unit(triad)}"


def bias(triad: str, axis: str) -> str:
    """The bias the recording shows: the calibration's plus the offset."""
    return f"{triad}_bias_{axis}_{_unit(triad)}"


def bias_std(triad: str, axis: str) -> str:
    return f"{triad}_bias_std_{axis}_{_unit(triad)}"


def scale(triad: str, axis: str) -> str:
    """Scale factor error (dimensionless) where the recording calibrates it."""
    return f"{triad}_scale_{axis}"


def scale_std(triad: str, axis: str) -> str:
    return f"{triad}_scale_std_{axis}"


#: Noise terms kept per axis: (column stem, key of ``NoiseAxis.fit``, unit suffix after the
#: triad's unit), in the noise fit's own words (``n_u_per_sqrt_hz``: white noise density,
#: velocity/angle random walk; ``b_u``: bias instability; ``k_u_sqrt_hz``: rate/acceleration
#: random walk).
NOISE_TERMS: Tuple[Tuple[str, str, str], ...] = (
    ("white", "n_u_per_sqrt_hz", "_per_sqrt_hz"),
    ("bias_instability", "b_u", ""),
    ("random_walk", "k_u_sqrt_hz", "_sqrt_hz"),
)


def noise(triad: str, term: str, axis: str) -> str:
    """A noise term's column, e.g. ``gyro_white_z_rad_s_per_sqrt_hz``."""
    for stem, _, suffix in NOISE_TERMS:
        if stem == term:
            return f"{triad}_{stem}_{axis}_{_unit(triad)}{suffix}"
    raise KeyError(f"no noise term {term!r}; terms: {[t[0] for t in NOISE_TERMS]}")


def noise_std(triad: str, term: str, axis: str) -> str:
    """The noise fit's standard uncertainty of that term, same unit."""
    for stem, _, suffix in NOISE_TERMS:
        if stem == term:
            return f"{triad}_{stem}_std_{axis}_{_unit(triad)}{suffix}"
    raise KeyError(f"no noise term {term!r}; terms: {[t[0] for t in NOISE_TERMS]}")


def _unit(triad: str) -> str:
    return dict(TRIADS)[triad]


def _recording_fields() -> List[pa.Field]:
    f = pa.field
    out = [
        f("path", pa.string(), nullable=False),
        f("unit", pa.string()),
        f("model", pa.string()),
        f("serial", pa.string()),
        f("start_utc", UTC),
        f("duration_s", pa.float64()),
        f("samples", pa.int64()),
        f("missing_samples", pa.int64()),
        f("stopped_early", pa.string()),
        f("calibration_id", pa.string()),
        f("error", pa.string()),
        f("still_windows", pa.int32()),
        f("still_s", pa.float64()),
        f("rejections", pa.int32()),
        f("health_state", pa.string()),
        f("noise_source", pa.string()),
        f("gravity_m_s2", pa.float64()),
        f("accel_offset_3d", pa.bool_()),
    ]
    for t, _ in TRIADS:
        for a in AXES:
            out += [
                f(cal_bias(t, a), pa.float64()),
                f(offset(t, a), pa.float64()),
                f(offset_std(t, a), pa.float64()),
                f(bias(t, a), pa.float64()),
                f(bias_std(t, a), pa.float64()),
            ]
    for t, _ in TRIADS:
        for a in AXES:
            out += [f(scale(t, a), pa.float64()), f(scale_std(t, a), pa.float64())]
    out.append(f("noise_span_s", pa.float64()))
    for t, _ in TRIADS:
        for stem, _, _ in NOISE_TERMS:
            for a in AXES:
                out.append(f(noise(t, stem, a), pa.float64()))
            for a in AXES:
                out.append(f(noise_std(t, stem, a), pa.float64()))
    out += [f(c, pa.float64()) for c in TIMING_COLUMNS]
    return out


def _metadata(table: str) -> Dict[bytes, bytes]:
    from .. import __version__

    return {
        META_SCHEMA_VERSION.encode(): SCHEMA_VERSION.encode(),
        META_IMUD_VERSION.encode(): str(__version__).encode(),
        META_TABLE.encode(): table.encode(),
    }


RECORDINGS = pa.schema(_recording_fields(), metadata=_metadata("recordings"))

UNITS = pa.schema(
    [
        pa.field("unit", pa.string()),
        pa.field("parameter", pa.string()),
        pa.field("quantity_unit", pa.string()),
        pa.field("n", pa.int32()),
        pa.field("first_utc", UTC),
        pa.field("last_utc", UTC),
        pa.field("value_at_last", pa.float64()),
        pa.field("value_std_at_last", pa.float64()),
        pa.field("calibration_value", pa.float64()),
        pa.field("slope_per_day", pa.float64()),
        pa.field("slope_std_per_day", pa.float64()),
        pa.field("excess_std", pa.float64()),
        pa.field("dof", pa.int32()),
        pa.field("t_stat", pa.float64()),
        pa.field("p_value", pa.float64()),
        pa.field("drifting", pa.bool_()),
        pa.field("tolerance", pa.float64()),
        pa.field("crossing_utc", UTC),
        pa.field("out_of_tolerance", pa.bool_()),
        pa.field("flagged", pa.bool_()),
        pa.field("reason", pa.string()),
    ],
    metadata=_metadata("units"),
)


def recordings_table(rows: List[dict]) -> pa.Table:
    """The recordings table of rows (dicts keyed by column; a missing key is null)."""
    cols = {
        fld.name: pa.array([r.get(fld.name) for r in rows], type=fld.type)
        for fld in RECORDINGS
    }
    return pa.Table.from_pydict(cols, schema=RECORDINGS)


def conform(table: pa.Table, schema: pa.Schema) -> pa.Table:
    """``table`` checked against ``schema`` (same column names, order and types; ValueError
    naming the differences otherwise), with the schema's metadata added to its own (the drift
    test's parameters stay)."""
    got = [(f.name, f.type) for f in table.schema]
    want = [(f.name, f.type) for f in schema]
    if got != want:
        raise ValueError(
            f"the table's columns differ from schema version {SCHEMA_VERSION}'s: missing "
            f"{[w for w in want if w not in got]}, unexpected {[g for g in got if g not in want]}"
        )
    meta = dict(table.schema.metadata or {})
    meta.update(schema.metadata or {})
    return table.replace_schema_metadata(meta)


def without_timings(table: pa.Table) -> pa.Table:
    """The table without its wall-clock columns: what two runs of the job must agree on."""
    return table.drop_columns([c for c in TIMING_COLUMNS if c in table.column_names])
