"""Per-unit drift of a fleet's calibration parameters: which biases (and scales) walk, how fast, how
sure we are, and by when each leaves the calibration's tolerance.

Input is the fleet's recordings table (one row per recording, schema version 1, see
``ISSUE29``'s plan and :mod:`imud.fleet`); output is the units table (one row per unit x parameter).

The model, per unit and parameter, for the recordings i = 1..n at dates t_i (days)::

    b_i = a + r (t_i - t_w) + u_i + e_i,   e_i ~ N(0, sigma_i^2),   u_i ~ N(0, tau^2)

b_i is the recording's absolute estimate (``T_bias_a_U`` = the calibration in force + the offset the
still windows saw), sigma_i its reported standard deviation (``T_bias_std_a_U``), known; u_i the
scatter between recordings that no single recording's sigma covers (turn-on repeatability, bias
instability between power cycles), whose variance tau^2 is estimated from the data. Because b_i is
absolute, a recalibration within the history changes nothing in the fit (the bias did not move, only
the calibration did); the tolerance is taken around the calibration in force at the latest recording.

tau^2 is the Paule-Mandel estimate: the tau^2 at which the generalised Q statistic of the weighted
fit, sum w_i (b_i - a - r (t_i - t_w))^2 with w_i = 1 / (sigma_i^2 + tau^2), equals its expectation
n - 2 (0 when even tau^2 = 0 gives less). Why Paule-Mandel rather than REML: a unit has few
recordings (3 to a few dozen), where REML's likelihood is flat and often sits on the boundary, and
REML leans on u_i being normal; Paule-Mandel is a moment estimator with a unique root (Q falls
monotonically in tau^2) and, paired with the t distribution with n - 2 degrees of freedom and the
truncated Knapp-Hartung variance (with Paule-Mandel the factor max(1, Q / (n - 2)) is 1), keeps the
slope test's level near nominal for small n (Knapp and Hartung 2003; Veroniki et al. 2016, Res.
Synth. Methods 7:55). The Monte Carlo tests in python/tests/test_fleet_drift.py check that level and
the slope interval's coverage.

One unit alone pays for that in power: with few recordings t(n - 2) allows for a tau the data
cannot rule out (with 5 recordings, tau = 0 and the Bonferroni threshold of a 48-test fleet, a drift
over the span must exceed ~28 sigma). But turn-on repeatability and bias instability between power
cycles are properties of the sensor model, not of one unit: tau^2 is estimated once per model and
parameter from all of that model's units (:func:`pooled_tau2`: Paule-Mandel on the summed Q, each
unit's own line removed so a drifting unit does not inflate it), with sum (n_u - 2) degrees of
freedom, and a unit is tested with it unless its own estimate is larger (a unit noisier than its
siblings is then tested on its own, with n - 2). Eight units of five recordings give 24 degrees of
freedom instead of 3. The rule is conservative by design (measured in the Monte Carlo test: 0.0035
of null p-values below 0.01 with six recordings a unit). Its assumption is that one model's units
scatter alike: a unit several times noisier than its siblings whose few recordings happen to line
up looks quiet on its own and is tested with the model's tau, so its noise is now and then called a
drift (measured: 2 of 240 tests for a unit 5x noisier, 1 of 240 at 2x, where the threshold
allows 0.05; a unit that much noisier than its model is worth a look anyway).

A slope is ``drifting`` when its two-sided p-value is below alpha / m, m the number of slope tests in
the whole fleet (Bonferroni: the chance that any unit of a drift-free fleet is called drifting is at
most alpha).
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import math
from typing import Optional

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
from scipy import optimize, stats

from . import schema as _schema

__all__ = [
    "Tolerances",
    "ParameterSpec",
    "PARAMETERS",
    "DriftFit",
    "fit_drift",
    "Evidence",
    "unit_points",
    "spec_of",
    "display_scale",
    "analyze_units",
    "flagged_units",
    "UNITS_SCHEMA",
]

_NS_PER_DAY = 86_400 * 1_000_000_000
_TIMESTAMP = pa.timestamp("ns", tz="UTC")


@dataclasses.dataclass(frozen=True)
class Tolerances:
    """How far each kind of parameter may move from the calibration in force before the calibration
    no longer holds.

    Defaults are what makes a typical MEMS calibration worth having:

    - ``accel_bias_m_s2 = 0.01`` (~1 mg): an uncalibrated consumer MEMS accelerometer's bias is tens
      of mg; a calibration that leaves ~1 mg keeps a level estimate within ~0.06 deg, and more than
      that erodes what the calibration bought;
    - ``gyro_bias_rad_s = 5e-4`` (~0.03 deg/s, ~100 deg/h): the turn-on bias spread of good MEMS
      gyros is about this size, and a heading integrated through a minute still drifts < 2 deg;
    - ``scale = 1e-3`` (0.1 %, a ratio): a scale error of 1e-3 on gravity is ~1 mg, matching the
      accelerometer bias tolerance; calibrated MEMS scales hold a few hundred ppm.
    """

    accel_bias_m_s2: float = 0.01
    gyro_bias_rad_s: float = 5e-4
    scale: float = 1e-3

    _KEYS = {"accel-bias": "accel_bias_m_s2", "gyro-bias": "gyro_bias_rad_s", "scale": "scale"}

    def __post_init__(self) -> None:
        for field in ("accel_bias_m_s2", "gyro_bias_rad_s", "scale"):
            value = getattr(self, field)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"tolerance {field} must be a positive finite number, not {value!r}")

    @classmethod
    def parse(cls, text: str) -> "Tolerances":
        """Reads the command line's ``accel-bias=0.02,gyro-bias=1e-3,scale=2e-3`` (m/s^2, rad/s, ratio);
        keys left out keep their defaults, an empty text gives the defaults."""
        known = ", ".join(cls._KEYS)
        values: dict = {}
        for item in (part.strip() for part in text.split(",")):
            if not item:
                continue
            key, sep, raw = item.partition("=")
            key = key.strip()
            if not sep:
                raise ValueError(f"tolerance {item!r} is not KEY=VALUE (keys: {known})")
            if key not in cls._KEYS:
                raise ValueError(f"unknown tolerance {key!r} in {item!r} (keys: {known})")
            field = cls._KEYS[key]
            if field in values:
                raise ValueError(f"tolerance {key!r} given twice in {text!r}")
            try:
                value = float(raw)
            except ValueError:
                raise ValueError(f"tolerance {key!r}: {raw.strip()!r} is not a number") from None
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"tolerance {key!r} must be positive and finite, not {raw.strip()!r}")
            values[field] = value
        return cls(**values)

    def for_kind(self, kind: str) -> float:
        """The tolerance of a parameter kind ("accel-bias", "gyro-bias", "scale")."""
        return getattr(self, self._KEYS[kind])


@dataclasses.dataclass(frozen=True)
class ParameterSpec:
    """One tested parameter and where the recordings table keeps it."""

    name: str  # e.g. "gyro_bias_z"
    kind: str  # key of Tolerances: "accel-bias", "gyro-bias", "scale"
    quantity_unit: str  # "m/s^2", "rad/s", "1"
    value_column: str
    std_column: str
    cal_column: str
    default_calibration: float  # when the table has no calibration column for it
    required: bool  # bias columns are always in schema 1; scale ones only where calibrated
    label: str  # for people: "gyro bias z"


def _specs() -> list:
    specs = []
    for sensor, unit_text in (("accel", "m/s^2"), ("gyro", "rad/s")):
        for axis in "xyz":
            specs.append(
                ParameterSpec(
                    name=f"{sensor}_bias_{axis}",
                    kind=f"{sensor}-bias",
                    quantity_unit=unit_text,
                    value_column=_schema.bias(sensor, axis),
                    std_column=_schema.bias_std(sensor, axis),
                    cal_column=_schema.cal_bias(sensor, axis),
                    default_calibration=0.0,
                    required=True,
                    label=f"{sensor} bias {axis}",
                )
            )
    for sensor in ("accel", "gyro"):
        for axis in "xyz":
            specs.append(
                ParameterSpec(
                    name=f"{sensor}_scale_{axis}",
                    kind="scale",
                    quantity_unit="1",
                    value_column=_schema.scale(sensor, axis),
                    std_column=_schema.scale_std(sensor, axis),
                    # Schema 1's scale is the scale factor error (dimensionless, 0 when the
                    # calibration holds) and has no column for the calibration's own: the band
                    # sits around 0 (the column is read when a later schema adds it).
                    cal_column=f"cal_{sensor}_scale_{axis}",
                    default_calibration=0.0,
                    required=False,
                    label=f"{sensor} scale error {axis}",
                )
            )
    return specs


PARAMETERS: tuple = tuple(_specs())
_SPEC_BY_NAME = {spec.name: spec for spec in PARAMETERS}


@dataclasses.dataclass(frozen=True)
class DriftFit:
    """The weighted straight line through one unit's estimates of one parameter.

    ``t_ref_day`` is the weighted mean date (days since 1970-01-01 UTC), where the intercept and the
    slope are uncorrelated; ``intercept`` is the line's value there."""

    n: int
    t_ref_day: float
    intercept: float
    intercept_var: float
    slope_per_day: float
    slope_var: float
    tau2: float  # between-recording variance beyond the sigma_i (Paule-Mandel)
    #: Degrees of freedom of the slope's t test: n - 2 with the unit's own tau^2, the pooled
    #: sum over the units it was pooled from otherwise (see :func:`pooled_tau2`).
    dof: int

    @property
    def slope_std_per_day(self) -> float:
        return math.sqrt(self.slope_var)

    @property
    def t_stat(self) -> float:
        return self.slope_per_day / self.slope_std_per_day

    @property
    def p_value(self) -> float:
        """Two-sided p-value of "no drift" (t distribution with :attr:`dof` degrees of freedom)."""
        return float(2.0 * stats.t.sf(abs(self.t_stat), self.dof))

    def value_at(self, t_day):
        """The line's value and its standard deviation at dates ``t_day`` (days since the epoch)."""
        d = np.asarray(t_day, dtype=float) - self.t_ref_day
        value = self.intercept + self.slope_per_day * d
        std = np.sqrt(self.intercept_var + d * d * self.slope_var)
        return value, std

    def t_quantile(self, level: float = 0.95) -> float:
        """The two-sided ``level`` quantile of the slope's t distribution (band half-width in stds)."""
        return float(stats.t.ppf(0.5 + level / 2.0, self.dof))


def _wls(t, v, s2, tau2):
    w = 1.0 / (s2 + tau2)
    sw = w.sum()
    t_ref = float((w * t).sum() / sw)
    a = float((w * v).sum() / sw)
    d = t - t_ref
    sxx = float((w * d * d).sum())
    r = float((w * d * (v - a)).sum() / sxx)
    resid = v - a - r * d
    q = float((w * resid * resid).sum())
    return t_ref, a, r, sw, sxx, q


def _points(t_day, value, std):
    t = np.asarray(t_day, dtype=float)
    v = np.asarray(value, dtype=float)
    s2 = np.asarray(std, dtype=float) ** 2
    n = t.size
    if n < 3 or not (v.size == n and s2.size == n):
        raise ValueError(f"a drift fit needs >= 3 estimates with one std each, got {n}")
    if np.ptp(t) <= 0:
        raise ValueError("a drift fit needs estimates at two or more distinct dates")
    if not (np.all(np.isfinite(v)) and np.all(np.isfinite(s2)) and np.all(s2 > 0)):
        raise ValueError("a drift fit needs finite values and positive finite stds")
    return t, v, s2


def _paule_mandel(series) -> float:
    """The tau^2 at which the summed generalised Q of the straight lines through ``series`` (a list
    of (t, v, s2), each line fitted on its own) equals its expectation sum (n_u - 2); 0 when even
    tau^2 = 0 gives less."""
    target = float(sum(t.size - 2 for t, _, _ in series))

    def excess_q(tau2):
        return sum(_wls(t, v, s2, tau2)[5] for t, v, s2 in series) - target

    if excess_q(0.0) <= 0:
        return 0.0
    # Q(tau2) falls monotonically to 0 as tau2 grows: bracket the root from the scale of the
    # unweighted residuals, then solve with a tolerance relative to that scale (biases in rad/s
    # have variances ~1e-8, far below brentq's default absolute tolerance).
    hi = 0.0
    for t, v, s2 in series:
        d = t - t.mean()
        r0 = float((d * (v - v.mean())).sum() / (d * d).sum())
        resid = v - v.mean() - r0 * d
        hi = max(hi, float((resid * resid).sum()) / max(t.size - 2, 1), float(s2.max()))
    while excess_q(hi) > 0:
        hi *= 4.0
    return float(optimize.brentq(excess_q, 0.0, hi, xtol=hi * 1e-12, rtol=1e-12))


def pooled_tau2(units) -> "tuple[float, int]":
    """The between-recording variance tau^2 shared by several units of one sensor model, and its
    degrees of freedom: Paule-Mandel over all their recordings, each unit's own line removed (so a
    drifting unit does not inflate it). ``units``: (t_day, value, std) per unit, each with >= 3
    estimates at >= 2 dates. Turn-on repeatability and bias instability between power cycles are
    properties of the sensor model, so a fleet estimates them from every unit at once with
    sum (n_u - 2) degrees of freedom, where one unit alone has n - 2 (3 for five recordings)."""
    series = [_points(*u) for u in units]
    if not series:
        raise ValueError("pooled_tau2 needs at least one unit")
    return _paule_mandel(series), int(sum(t.size - 2 for t, _, _ in series))


def fit_drift(t_day, value, std, *, tau2=None, dof=None) -> DriftFit:
    """Fits b_i = a + r (t_i - t_w) + u_i + e_i (module docstring) to n >= 3 estimates at >= 2
    distinct dates with standard deviations ``std`` (> 0). ``tau2`` (with its ``dof``): a
    between-recording variance estimated elsewhere (:func:`pooled_tau2`); default the unit's own
    Paule-Mandel estimate with n - 2 degrees of freedom."""
    t, v, s2 = _points(t_day, value, std)
    if tau2 is None:
        tau2, dof = _paule_mandel([(t, v, s2)]), t.size - 2
    elif dof is None or dof < 1 or not (math.isfinite(tau2) and tau2 >= 0):
        raise ValueError(f"a given tau2 needs a finite value >= 0 and dof >= 1, got {tau2}, {dof}")
    t_ref, a, r, sw, sxx, _ = _wls(t, v, s2, tau2)
    return DriftFit(
        n=t.size,
        t_ref_day=t_ref,
        intercept=a,
        intercept_var=1.0 / sw,
        slope_per_day=r,
        slope_var=1.0 / sxx,
        tau2=float(tau2),
        dof=int(dof),
    )


class Evidence:
    """The recordings table's columns the drift test reads, as numpy arrays read once, and the
    rows of each unit in date order."""

    def __init__(self, recordings: pa.Table):
        names = set(recordings.column_names)
        missing = [c for c in ("unit", "start_utc") if c not in names]
        missing += [s.value_column for s in PARAMETERS if s.required and s.value_column not in names]
        missing += [s.std_column for s in PARAMETERS if s.required and s.std_column not in names]
        if missing:
            raise ValueError(
                "the recordings table lacks column(s) " + ", ".join(missing) + " (schema version 1)"
            )
        units = recordings.column("unit").to_pylist()
        self.units = np.array(["" if u is None else u for u in units], dtype=object)
        # The sensor model of each row ("" when the table does not say): units of one model
        # share their between-recording scatter (:func:`pooled_tau2`).
        models = recordings.column("model").to_pylist() if "model" in names else [None] * len(units)
        self.models = np.array(["" if m is None else str(m) for m in models], dtype=object)
        start = recordings.column("start_utc")
        if not pa.types.is_timestamp(start.type):
            raise ValueError(f"the recordings table's start_utc is {start.type}, not a timestamp")
        start = pc.cast(start, pa.timestamp("ns", tz=start.type.tz))
        self.start_valid = np.asarray(pc.is_valid(start).to_numpy(zero_copy_only=False), dtype=bool)
        self.start_ns = np.asarray(
            pc.fill_null(pc.cast(start, pa.int64()), 0).to_numpy(zero_copy_only=False), dtype=np.int64
        )
        if "error" in names:
            self.ok = np.asarray(pc.is_null(recordings.column("error")).to_numpy(zero_copy_only=False))
        else:
            self.ok = np.ones(recordings.num_rows, dtype=bool)
        self.ok = self.ok & self.start_valid
        self.columns: dict = {}
        for spec in PARAMETERS:
            for col in (spec.value_column, spec.std_column, spec.cal_column):
                if col in names and col not in self.columns:
                    self.columns[col] = _float_column(recordings.column(col), col)

        # Rows grouped by unit, each group in date order (stable: equal dates keep the table's
        # order, so "latest" is well defined); one sort for the whole table.
        names, inverse = np.unique(self.units.astype(str), return_inverse=True)
        order = np.lexsort((self.start_ns, inverse))
        bounds = np.searchsorted(inverse[order], np.arange(names.size + 1))
        self._rows = {str(name): order[bounds[i]:bounds[i + 1]] for i, name in enumerate(names)}

    def model_of(self, unit: str) -> str:
        """The unit's sensor model: its latest recording's that names one ("" if none does)."""
        named = [m for m in self.models[self.rows_of(unit)] if m]
        return named[-1] if named else ""

    @property
    def unit_names(self) -> list:
        """The units, sorted."""
        return sorted(self._rows)

    def rows_of(self, unit: str) -> np.ndarray:
        """Row indices of ``unit`` in date order (empty for an unknown unit)."""
        return self._rows.get(unit, np.zeros(0, dtype=np.int64))

    def unit_points(self, unit: str, parameter: str):
        """See :func:`unit_points`."""
        return self.points(self.rows_of(unit), _SPEC_BY_NAME[parameter])

    def points(self, rows: np.ndarray, spec: ParameterSpec):
        """(start_ns, value, std, calibration in force) of the rows that carry evidence on ``spec``."""
        if spec.value_column not in self.columns or spec.std_column not in self.columns:
            empty = np.zeros(0)
            return np.zeros(0, dtype=np.int64), empty, empty, empty
        v = self.columns[spec.value_column][rows]
        s = self.columns[spec.std_column][rows]
        keep = self.ok[rows] & np.isfinite(v) & np.isfinite(s) & (s > 0)
        cal = self.columns.get(spec.cal_column)
        cal = np.full(rows.size, spec.default_calibration) if cal is None else cal[rows]
        return self.start_ns[rows][keep], v[keep], s[keep], cal[keep]

    def calibration(self, rows: np.ndarray, spec: ParameterSpec) -> float:
        """The calibration in force at the unit's latest recording that says which one it had."""
        col = self.columns.get(spec.cal_column)
        if col is None:
            return spec.default_calibration
        values = col[rows][self.start_valid[rows]]
        values = values[np.isfinite(values)]
        return float(values[-1]) if values.size else float("nan")


def _float_column(column: pa.ChunkedArray, name: str) -> np.ndarray:
    if not (pa.types.is_floating(column.type) or pa.types.is_integer(column.type)):
        raise ValueError(f"the recordings table's {name} is {column.type}, not a number")
    return np.asarray(pc.cast(column, pa.float64()).to_numpy(zero_copy_only=False), dtype=float)


def unit_points(recordings: pa.Table, unit: str, parameter: str):
    """One unit's evidence on one parameter in date order, the rows :func:`analyze_units` fits (no
    error, finite value, positive finite std): (start_ns int64, value, std, calibration in force,
    NaN where a recording does not say)."""
    return Evidence(recordings).unit_points(unit, parameter)


def spec_of(parameter: str) -> ParameterSpec:
    """The :class:`ParameterSpec` of a parameter name of the units table."""
    return _SPEC_BY_NAME[parameter]


#: The units table's columns: schema version 1's, whose one home is :mod:`imud.fleet.schema`.
UNITS_SCHEMA = _schema.UNITS


# How a parameter is shown to people: (factor from the table's unit, unit text).
_DISPLAY = {"m/s^2": (1.0, "m/s^2"), "rad/s": (180.0 / math.pi, "deg/s"), "1": (1e6, "ppm")}


def display_scale(quantity_unit: str):
    """(factor, unit text) turning a value in ``quantity_unit`` into what a reason or plot shows."""
    return _DISPLAY[quantity_unit]


def short(x: float) -> str:
    """A number in three significant digits, without an exponent where it reads as a plain
    number (1000 rather than 1e+03)."""
    text = f"{x:.3g}"
    return f"{x:.0f}" if "e+" in text and abs(x) < 1e6 else text


def _fmt_p(p: float) -> str:
    if p == 0:
        return "0"
    if p < 1e-3:
        mantissa, exponent = f"{p:.0e}".split("e")
        return f"{mantissa}e{int(exponent)}"
    return f"{p:.2g}"


def _date(ns: int) -> str:
    return _dt.datetime.fromtimestamp(ns / 1e9, tz=_dt.timezone.utc).strftime("%Y-%m-%d")


def _to_ns(when) -> int:
    if isinstance(when, _dt.datetime):
        if when.tzinfo is None:
            raise ValueError("now_utc must be timezone-aware (UTC), not a naive datetime")
        return int(round(when.timestamp() * 1e9))
    if isinstance(when, np.datetime64):
        return int(when.astype("datetime64[ns]").astype(np.int64))
    if isinstance(when, pa.TimestampScalar):
        return int(pc.cast(when, pa.timestamp("ns", tz=when.type.tz)).cast(pa.int64()).as_py())
    raise ValueError(f"now_utc must be a timezone-aware datetime or numpy datetime64, not {when!r}")


def analyze_units(
    recordings: pa.Table,
    tolerances: Optional[Tolerances] = None,
    alpha: float = 0.01,
    now_utc=None,
    horizon_days: float = 365.0,
    *,
    min_recordings: int = 3,
    min_span_days: float = 7.0,
) -> pa.Table:
    """The units table (one row per unit x parameter, :data:`UNITS_SCHEMA`) of a recordings table.

    A slope is tested where a unit has >= ``min_recordings`` usable estimates spanning more than
    ``min_span_days``; ``drifting`` when its p-value < alpha / (number of tests in the fleet).
    ``crossing_utc``: the date the drifting line leaves calibration_value +- tolerance (already past
    or within ``horizon_days`` of ``now_utc``; ``now_utc`` defaults to the unit's last recording, so
    the result depends on the data only). ``out_of_tolerance``: the value at the last recording (the
    line's, or the last estimate's when too few to fit) lies outside the band by more than 2 of its
    standard deviations. ``flagged`` = drifting with a crossing, or out of tolerance.
    """
    tolerances = tolerances or Tolerances()
    if not (0 < alpha < 1):
        raise ValueError(f"alpha must lie in (0, 1), not {alpha}")
    if not (horizon_days >= 0):
        raise ValueError(f"horizon_days must be >= 0, not {horizon_days}")
    now_ns = None if now_utc is None else _to_ns(now_utc)
    cols = Evidence(recordings)

    pending = []
    testable: dict = {}  # (model, parameter) -> [(t_day, value, std)] of the units with a test
    for unit in cols.unit_names:
        rows = cols.rows_of(unit)
        model = cols.model_of(unit)
        for spec in PARAMETERS:
            start_ns, v, s, _ = cols.points(rows, spec)
            if not spec.required and v.size == 0:
                continue  # no recording of this unit calibrates this scale
            test = v.size >= min_recordings and np.ptp(start_ns) > min_span_days * _NS_PER_DAY
            if test:
                testable.setdefault((model, spec.name), []).append((start_ns / _NS_PER_DAY, v, s))
            pending.append((unit, model, spec, rows, start_ns, v, s, test))
    pooled = {key: pooled_tau2(units) for key, units in testable.items() if len(units) >= 2}

    fits = []
    for unit, model, spec, rows, start_ns, v, s, test in pending:
        fit = None
        if test:
            # The unit's own scatter when it is the larger (a unit noisier than its model's
            # others is tested on its own, with n - 2 degrees of freedom), else its model's.
            fit = fit_drift(start_ns / _NS_PER_DAY, v, s)
            shared = pooled.get((model, spec.name))
            if shared is not None and shared[0] >= fit.tau2:
                fit = fit_drift(start_ns / _NS_PER_DAY, v, s, tau2=shared[0], dof=shared[1])
        fits.append((unit, spec, rows, start_ns, v, s, fit))
    pending = fits

    tests = sum(1 for p in pending if p[-1] is not None)
    threshold = alpha / max(tests, 1)
    out = {field.name: [] for field in UNITS_SCHEMA}
    for unit, spec, rows, start_ns, v, s, fit in pending:
        row = _unit_row(unit, spec, cols.calibration(rows, spec), tolerances.for_kind(spec.kind),
                        start_ns, v, s, fit, threshold, now_ns, horizon_days, min_recordings,
                        min_span_days)
        for key, value in row.items():
            out[key].append(value)
    table = pa.Table.from_pydict(out, schema=UNITS_SCHEMA)
    return table.replace_schema_metadata(
        {
            "imud.fleet.drift.alpha": repr(alpha),
            "imud.fleet.drift.tests": str(tests),
            "imud.fleet.drift.p-threshold": repr(threshold),
            "imud.fleet.drift.horizon-days": repr(horizon_days),
            "imud.fleet.drift.tau2-estimator": (
                "Paule-Mandel, pooled over the units of one model (a unit's own when larger)"
            ),
        }
    )


def _unit_row(unit, spec, cal, tol, start_ns, v, s, fit, threshold, now_ns, horizon_days,
              min_recordings, min_span_days) -> dict:
    factor, shown_unit = display_scale(spec.quantity_unit)
    n = int(v.size)
    row = {
        "unit": unit,
        "parameter": spec.name,
        "quantity_unit": spec.quantity_unit,
        "n": n,
        "first_utc": int(start_ns[0]) if n else None,
        "last_utc": int(start_ns[-1]) if n else None,
        "value_at_last": None,
        "value_std_at_last": None,
        "calibration_value": cal if math.isfinite(cal) else None,
        "slope_per_day": None,
        "slope_std_per_day": None,
        "excess_std": None,
        "dof": None,
        "t_stat": None,
        "p_value": None,
        "drifting": False,
        "tolerance": tol,
        "crossing_utc": None,
        "out_of_tolerance": False,
        "flagged": False,
        "reason": "",
    }
    if n == 0:
        row["reason"] = f"{spec.label}: no usable recording (every one failed or lacked an estimate)"
        return row
    last_day = start_ns[-1] / _NS_PER_DAY
    if fit is None:
        value, std = float(v[-1]), float(s[-1])
    else:
        value, std = (float(x) for x in fit.value_at(last_day))
        row.update(
            slope_per_day=fit.slope_per_day,
            slope_std_per_day=fit.slope_std_per_day,
            excess_std=math.sqrt(fit.tau2),
            dof=fit.dof,
            t_stat=fit.t_stat,
            p_value=fit.p_value,
            drifting=fit.p_value < threshold,
        )
    row["value_at_last"], row["value_std_at_last"] = value, std
    parts = []
    if not math.isfinite(cal):
        parts.append(f"{spec.label}: calibration in force unknown, tolerance not checked")
    else:
        row["out_of_tolerance"] = bool(abs(value - cal) - tol > 2.0 * std)
        if row["drifting"]:
            r = fit.slope_per_day
            edge = cal + math.copysign(tol, r)
            cross_day = fit.t_ref_day + (edge - fit.intercept) / r
            ref_day = (now_ns if now_ns is not None else start_ns[-1]) / _NS_PER_DAY
            if cross_day <= ref_day + horizon_days:
                # Whole seconds: a line's crossing is not known to the nanosecond, and whole
                # seconds convert to datetime without pandas.
                row["crossing_utc"] = int(round(cross_day * 86_400)) * 1_000_000_000
    if fit is None:
        parts.append(
            f"{spec.label}: too few recordings ({n}; a drift test needs {min_recordings} spanning "
            f"more than {min_span_days:g} days)"
        )
    elif row["drifting"]:
        text = (f"{spec.label} drifting {fit.slope_per_day * 30 * factor:+.3g} {shown_unit} per 30 days "
                f"(p = {_fmt_p(fit.p_value)})")
        if row["crossing_utc"] is not None:
            verb = "crossed" if row["crossing_utc"] <= start_ns[-1] else "crosses"
            text += f", {verb} tolerance {_date(row['crossing_utc'])}"
        elif math.isfinite(cal):
            text += f", within tolerance beyond {horizon_days:g} days"
        parts.append(text)
    else:
        parts.append(
            f"{spec.label}: no significant drift ({fit.slope_per_day * 30 * factor:+.2g} "
            f"{shown_unit} per 30 days, p = {_fmt_p(fit.p_value)})"
        )
    if row["out_of_tolerance"]:
        parts.append(
            f"out of tolerance: {short(value * factor)} {shown_unit} at {_date(start_ns[-1])} against "
            f"calibration {short(cal * factor)} ± {short(tol * factor)} {shown_unit}"
        )
    row["flagged"] = bool(row["out_of_tolerance"] or (row["drifting"] and row["crossing_utc"] is not None))
    row["reason"] = "; ".join(parts)
    return row


def flagged_units(units: pa.Table) -> list:
    """The units to recalibrate (any parameter flagged), sorted by name."""
    flagged = units.filter(pc.fill_null(units.column("flagged"), False))
    return sorted(set(flagged.column("unit").to_pylist()))
