"""Result types: thin dataclasses over the JSON the Rust result structs serialize to (the same
documents the command-line clients print with ``--json``).

Each class names the fields most code reads; every other field of the document is kept in
``extra``, and :meth:`to_dict` gives the whole document back, so fields the libraries add later
reach Python without a change here.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field, fields
from typing import Any, Dict, List, Optional

import numpy as np


def _build(cls, d: dict, **over):
    """``cls`` from document ``d``: named fields taken, the rest in ``extra``."""
    names = {f.name for f in fields(cls) if f.init and not f.name.startswith("_")} - {"extra"}
    kw = {k: d.get(k) for k in names if k in d}
    kw.update(over)
    extra = {k: v for k, v in d.items() if k not in names}
    obj = cls(**kw, extra=extra)
    obj._doc = d
    return obj


class _Doc:
    _doc: dict

    def to_dict(self) -> dict:
        """The whole result as the JSON document it came from (a deep copy)."""
        return copy.deepcopy(self._doc)


def _se(std_errors: List[Optional[float]]) -> np.ndarray:
    return np.array([np.nan if s is None else s for s in std_errors], dtype=float)


@dataclass(repr=False)
class NoiseAxis(_Doc):
    """``imu-noise --json``'s report of one sensor axis: the fitted noise terms (``fit``: N, B,
    K with uncertainties), the OADEV curve they were fitted to, every deviation kind asked for."""

    sensor: str = ""
    axis: str = ""
    unit: str = ""
    sample_rate_hz: float = float("nan")
    fit: Dict[str, Any] = field(default_factory=dict)
    curve: Dict[str, Any] = field(default_factory=dict)
    deviations: List[Dict[str, Any]] = field(default_factory=list)
    extra: Dict[str, Any] = field(default_factory=dict)

    def __repr__(self) -> str:
        return f"NoiseAxis({self.sensor} {self.axis}, {len(self.curve.get('points', []))} taus)"

    def deviation(self, kind: str) -> Dict[str, Any]:
        """The curve of one ``kind`` (``oadev``, ``mdev``, ...) as computed."""
        for d in self.deviations:
            if d["kind"] == kind:
                return d
        raise KeyError(f"{kind} was not computed; pass kind=[..., {kind!r}]")

    def taus_s(self, kind: str = "oadev") -> np.ndarray:
        """Averaging times of ``kind``'s points, s."""
        return np.array([p["tau_s"] for p in self.deviation(kind)["points"]], dtype=float)

    def dev(self, kind: str = "oadev") -> np.ndarray:
        """Deviation values of ``kind``'s points, in ``unit``."""
        return np.array([p["dev"] for p in self.deviation(kind)["points"]], dtype=float)


@dataclass(repr=False)
class NoiseResult(_Doc):
    """The noise analysis of a recording: one :class:`NoiseAxis` per sensor axis (accel x, y, z,
    then gyro x, y, z), as ``imu-noise --json``'s array."""

    axes: List[NoiseAxis] = field(default_factory=list)
    extra: Dict[str, Any] = field(default_factory=dict)

    def __repr__(self) -> str:
        return f"NoiseResult({len(self.axes)} axes)"

    def axis(self, sensor: str, axis: str) -> NoiseAxis:
        for a in self.axes:
            if a.sensor == sensor and a.axis == axis:
                return a
        raise KeyError(f"no {sensor} {axis}")

    def to_list(self) -> List[dict]:
        """The array ``imu-noise --json`` prints."""
        return [a.to_dict() for a in self.axes]


@dataclass(repr=False)
class TriadFit(_Doc):
    """One triad's fitted parameters: ``names``, ``units``, ``params`` and ``std_errors``
    (NaN where the parameter was held), the parameters that were not observable and why."""

    triad: str = ""
    names: List[str] = field(default_factory=list)
    units: List[str] = field(default_factory=list)
    params: np.ndarray = field(default_factory=lambda: np.zeros(0))
    std_errors: np.ndarray = field(default_factory=lambda: np.zeros(0))
    unobservable: List[Dict[str, Any]] = field(default_factory=list)
    extra: Dict[str, Any] = field(default_factory=dict)

    def __repr__(self) -> str:
        return f"TriadFit({self.triad}, {len(self.names)} parameters)"

    @classmethod
    def _from(cls, d: dict) -> "TriadFit":
        return _build(
            cls,
            d,
            params=np.array(d.get("params", []), dtype=float),
            std_errors=_se(d.get("std_errors", [])),
        )

    def value(self, name: str) -> "tuple[float, float]":
        """(value, standard error) of parameter ``name`` (e.g. ``bias.x``)."""
        i = self.names.index(name)
        return float(self.params[i]), float(self.std_errors[i])


@dataclass(repr=False)
class CalibrationResult(_Doc):
    """A calibration fit (``imu-calibrate --json``'s ``fit``): the accel and gyro parameter fits,
    notes (``notes``: sentences for people; ``note_codes``: one stable code per note, in the
    same order, for programs), and the fitted :class:`imud.Calibration` (``calibration.save(path)`` writes the file
    imud loads)."""

    procedure: str = ""
    accel: Optional[TriadFit] = None
    gyro: Optional[TriadFit] = None
    notes: List[str] = field(default_factory=list)
    note_codes: List[str] = field(default_factory=list)
    calibration: Any = None
    fit: Dict[str, Any] = field(default_factory=dict)
    extra: Dict[str, Any] = field(default_factory=dict)

    def __repr__(self) -> str:
        return f"CalibrationResult({self.procedure})"


@dataclass(repr=False)
class TriadDiagnosis(_Doc):
    """The workbench's verdict on one triad's model: chi-square against the noise floor, its
    p-value, whether the residual is consistent, and the ranked candidate effects.

    ``verdict`` is the sentence for people; ``verdict_codes`` the stable codes of its parts for
    programs (``consistent``, ``bias_wander``, ``missing_effect``, ``not_confirmed``,
    ``ambiguous`` or ``unexplained``, then ``periodic_component`` per spectral line, then the
    moves' ``gains_consistent``/``gains_inconsistent`` and ``missing_gain_effect`` or
    ``gain_not_confirmed``). Each candidate has ``explanation`` and ``explanation_code``,
    ``not_observable`` and ``not_observable_codes``."""

    triad: str = ""
    effects: List[str] = field(default_factory=list)
    chi2: float = float("nan")
    dof: int = 0
    p_value: Optional[float] = None
    consistent: bool = False
    verdict: str = ""
    verdict_codes: List[str] = field(default_factory=list)
    candidates: List[Dict[str, Any]] = field(default_factory=list)
    extra: Dict[str, Any] = field(default_factory=dict)

    def __repr__(self) -> str:
        return f"TriadDiagnosis({self.triad}, consistent={self.consistent})"

    @property
    def claimed(self) -> List[Dict[str, Any]]:
        """The candidates the workbench claims (significant, confirmed, not ambiguous)."""
        return [c for c in self.candidates if c.get("claimed")]


@dataclass(repr=False)
class Diagnosis(_Doc):
    """``imu-diagnose``'s result: the notes (sentences, and ``note_codes`` for programs), the
    effects added, and one
    :class:`TriadDiagnosis` for accel and one for gyro."""

    notes: List[str] = field(default_factory=list)
    note_codes: List[str] = field(default_factory=list)
    added: List[Any] = field(default_factory=list)
    verdict: Dict[str, str] = field(default_factory=dict)
    verdict_codes: Dict[str, List[str]] = field(default_factory=dict)
    accel: Optional[TriadDiagnosis] = None
    gyro: Optional[TriadDiagnosis] = None
    extra: Dict[str, Any] = field(default_factory=dict)

    def __repr__(self) -> str:
        return f"Diagnosis(accel consistent={self.accel.consistent}, gyro consistent={self.gyro.consistent})"


@dataclass(repr=False)
class LadderStep(_Doc):
    """One rung of the ladder: the effect added (None for the base model) and each triad's
    summary (effects, residual RMS, noise floor, chi-square, p-value, consistent)."""

    added: Optional[List[str]] = None
    accel: Dict[str, Any] = field(default_factory=dict)
    gyro: Dict[str, Any] = field(default_factory=dict)
    extra: Dict[str, Any] = field(default_factory=dict)

    def __repr__(self) -> str:
        return f"LadderStep(added={self.added})"


@dataclass(repr=False)
class LadderResult(_Doc):
    """``imu-diagnose ladder``'s result: the steps, the final diagnoses and the final
    :class:`imud.Calibration`."""

    notes: List[str] = field(default_factory=list)
    note_codes: List[str] = field(default_factory=list)
    added: List[Any] = field(default_factory=list)
    steps: List[LadderStep] = field(default_factory=list)
    verdict: Dict[str, str] = field(default_factory=dict)
    verdict_codes: Dict[str, List[str]] = field(default_factory=dict)
    accel: Optional[TriadDiagnosis] = None
    gyro: Optional[TriadDiagnosis] = None
    calibration: Any = None
    extra: Dict[str, Any] = field(default_factory=dict)

    def __repr__(self) -> str:
        return f"LadderResult({len(self.steps)} steps, added {self.added})"


def _floats(v: Optional[List[Optional[float]]]) -> np.ndarray:
    """A JSON number array (null: NaN, as serde writes a NaN) as float64."""
    return np.array([np.nan if x is None else x for x in (v or [])], dtype=float)


def _float(v: Optional[float]) -> float:
    return float("nan") if v is None else float(v)


@dataclass(repr=False)
class StillWindowCheck(_Doc):
    """One still window held against gravity and Earth's rate, as the daemon's live health
    reports it: ``start_s`` (from the recording's first sample), ``duration_s``, ``up`` (3,)
    in the sensor frame, ``|f| - g`` (``accel_residual_m_s2``) with its expected scatter
    (``accel_std_m_s2``), the rate minus Earth's rate as far as it is known
    (``gyro_residual_rad_s`` (3,)) with its scatter per axis (``gyro_std_rad_s``), ``p_value``
    (the smaller of the accel and gyro tests' in ``extra``; NaN while the noise or gravity was
    being learned) and ``state`` after the window (the worse of the two triads': ``ok``,
    ``degraded``, ``stale``, or ``unknown`` before the first test)."""

    start_s: float = float("nan")
    duration_s: float = float("nan")
    up: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    accel_residual_m_s2: float = float("nan")
    accel_std_m_s2: float = float("nan")
    gyro_residual_rad_s: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    gyro_std_rad_s: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    p_value: float = float("nan")
    state: str = ""
    extra: Dict[str, Any] = field(default_factory=dict)

    def __repr__(self) -> str:
        return f"StillWindowCheck({self.start_s:.1f} s + {self.duration_s:.1f} s, {self.state})"

    @classmethod
    def _from(cls, d: dict) -> "StillWindowCheck":
        return _build(
            cls,
            d,
            start_s=_float(d.get("start_s")),
            duration_s=_float(d.get("duration_s")),
            up=_floats(d.get("up")),
            accel_residual_m_s2=_float(d.get("accel_residual_m_s2")),
            accel_std_m_s2=_float(d.get("accel_std_m_s2")),
            gyro_residual_rad_s=_floats(d.get("gyro_residual_rad_s")),
            gyro_std_rad_s=_floats(d.get("gyro_std_rad_s")),
            p_value=_float(d.get("p_value")),
        )


@dataclass(repr=False)
class AccelScaleFit(_Doc):
    """The accelerometer's scale error fitted jointly with the bias offset to every still
    window's ``|f| - g`` (``HealthCheck.accel_scale_fit``, present where the rests calibrate the
    scale: 7 or more, each axis seen up and down): ``scale_error`` (3,) with
    ``scale_error_std`` (dimensionless; the calibrated stream reads ``1 + scale_error`` times
    physics), ``offset_m_s2`` with ``offset_std_m_s2``, the ``windows`` fitted and the fit's
    ``reduced_chi2``."""

    scale_error: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    scale_error_std: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    offset_m_s2: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    offset_std_m_s2: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    windows: int = 0
    reduced_chi2: float = float("nan")
    extra: Dict[str, Any] = field(default_factory=dict)

    def __repr__(self) -> str:
        return f"AccelScaleFit({self.windows} rests, scale error {self.scale_error})"

    @classmethod
    def _from(cls, d: Optional[dict]) -> "Optional[AccelScaleFit]":
        if d is None:
            return None
        return _build(
            cls,
            d,
            scale_error=_floats(d.get("scale_error")),
            scale_error_std=_floats(d.get("scale_error_std")),
            offset_m_s2=_floats(d.get("offset_m_s2")),
            offset_std_m_s2=_floats(d.get("offset_std_m_s2")),
            reduced_chi2=_float(d.get("reduced_chi2")),
        )


@dataclass(repr=False)
class HealthCheck(_Doc):
    """A recording's calibration health (``imu-analyze health --json``): every still window
    (:class:`StillWindowCheck`), the final ``state``, ``rejections`` (windows where a triad
    rejected the calibration), ``noise_source`` (``tables`` or ``estimated``), the gravity
    held against, and the offset of the calibrated stream from physics over ALL still
    windows (weighted least squares): ``accel_offset_m_s2`` (3,) with ``accel_offset_std_m_s2``
    (NaN for an axis no window observes; ``accel_offset_3d`` when several orientations were
    seen, else along gravity only), ``gyro_offset_rad_s`` with ``gyro_offset_std_rad_s``. For
    a linear model the true bias is the calibration's bias plus the offset;
    ``accel_scale_fit`` (:class:`AccelScaleFit` or None) the scale error where the rests
    calibrate it. ``still_s`` is the
    total still time; ``longest_still_s`` and ``longest_still_span_s`` (start, end) the longest
    continuous rest (for noise terms)."""

    windows: List[StillWindowCheck] = field(default_factory=list)
    accel_offset_m_s2: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    accel_offset_std_m_s2: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    accel_offset_3d: bool = False
    accel_scale_fit: Optional[AccelScaleFit] = None
    gyro_offset_rad_s: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    gyro_offset_std_rad_s: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    state: str = ""
    rejections: int = 0
    noise_source: str = ""
    gravity_m_s2: float = float("nan")
    latitude_deg: Optional[float] = None
    still_s: float = 0.0
    longest_still_s: float = 0.0
    longest_still_span_s: "tuple[float, float]" = (float("nan"), float("nan"))
    extra: Dict[str, Any] = field(default_factory=dict)

    def __repr__(self) -> str:
        return f"HealthCheck({len(self.windows)} still windows, {self.state})"


def health_check_result(doc: dict) -> HealthCheck:
    span = _floats(doc.get("longest_still_span_s"))
    return _build(
        HealthCheck,
        doc,
        windows=[StillWindowCheck._from(w) for w in doc.get("windows", [])],
        accel_offset_m_s2=_floats(doc.get("accel_offset_m_s2")),
        accel_offset_std_m_s2=_floats(doc.get("accel_offset_std_m_s2")),
        accel_scale_fit=AccelScaleFit._from(doc.get("accel_scale_fit")),
        gyro_offset_rad_s=_floats(doc.get("gyro_offset_rad_s")),
        gyro_offset_std_rad_s=_floats(doc.get("gyro_offset_std_rad_s")),
        gravity_m_s2=_float(doc.get("gravity_m_s2")),
        longest_still_span_s=(float(span[0]), float(span[1])),
    )


def noise_result(doc: list) -> NoiseResult:
    r = NoiseResult(axes=[_build(NoiseAxis, a) for a in doc])
    r._doc = {"axes": doc}
    return r


def calibration_result(doc: dict, calibration: Any) -> CalibrationResult:
    fit = doc["fit"]
    return _build(
        CalibrationResult,
        doc,
        accel=TriadFit._from(fit["accel"]),
        gyro=TriadFit._from(fit["gyro"]),
        notes=list(fit.get("notes", [])),
        note_codes=list(fit.get("note_codes", [])),
        calibration=calibration,
    )


def _diagnoses(ds: list) -> dict:
    accel, gyro = (_build(TriadDiagnosis, d) for d in ds)
    return {"accel": accel, "gyro": gyro}


def diagnosis(doc: dict) -> Diagnosis:
    return _build(Diagnosis, doc, **_diagnoses(doc["diagnoses"]))


def ladder_result(doc: dict, calibration: Any) -> LadderResult:
    return _build(
        LadderResult,
        doc,
        steps=[_build(LadderStep, s) for s in doc["steps"]],
        calibration=calibration,
        **_diagnoses(doc["final_diagnoses"]),
    )
