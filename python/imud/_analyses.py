"""The analyses: :func:`noise`, :func:`health_check`, :func:`calibrate`, :func:`diagnose`,
:func:`ladder`, each the library call its command-line client makes, with the client's
options."""

from __future__ import annotations

import json
import os
from typing import Any, Optional, Sequence, Union

from . import _imud
from ._recording import PathLike, Recording, as_recordings
from ._results import (
    CalibrationResult,
    Diagnosis,
    HealthCheck,
    LadderResult,
    NoiseResult,
    calibration_result,
    diagnosis,
    health_check_result,
    ladder_result,
    noise_result,
)


def _path(p: Optional[PathLike]) -> Optional[str]:
    return None if p is None else os.fspath(p)


def _one(rec_or_path: Any, source: str, read_kw: dict) -> Recording:
    """One recording: a Recording, or a path or the paths of one session."""
    if isinstance(rec_or_path, Recording):
        return as_recordings(rec_or_path, source, read_kw)[0]
    from ._recording import read

    return read(rec_or_path, source=source, **read_kw)


def noise(
    recording: Any,
    *,
    kind: Union[str, Sequence[str]] = "oadev",
    confidence: float = 0.683,
    edf: str = "greenhall",
    taus: Union[str, Sequence[float]] = "8-per-decade",
    source: str = "corrected",
    **read_kw: Any,
) -> NoiseResult:
    """Allan-family deviations and IEEE Std 952/1293 noise terms of a static recording, per
    sensor axis: ``imu-noise --json``.

    ``recording`` is a :class:`Recording` or a path (or the files of one session; read from
    ``source`` with ``read_kw``, the options of :func:`imud.read`). ``kind``: deviations to
    compute (``adev``, ``oadev``, ``mdev``, ``hdev``, ``ohdev``, ``tdev``, ``totdev``,
    ``theo1``, ``theoh``; a list or comma-separated). ``confidence``: two-sided level of the
    bounds. ``edf``: ``greenhall`` or ``sp1065``. ``taus``: ``octave``, ``decade``, ``all``,
    ``N-per-decade``, or taus in seconds (each rounded to whole sample periods; the noise-term
    fit then uses 8-per-decade). With ``theo1`` or ``theoh`` among the kinds the noise-term fit
    also takes Theo1 points beyond the OADEV's longest tau, up to 75 % of the record
    (``fit["n_theo1_points"]`` of each axis says how many).
    """
    rec = _one(recording, source, read_kw)
    kinds = [k.strip() for k in kind.split(",")] if isinstance(kind, str) else list(kind)
    tau_arg = taus if isinstance(taus, str) else ",".join(repr(float(t)) for t in taus)
    doc = json.loads(_imud.noise_json(rec._series, kinds, tau_arg, edf, float(confidence)))
    return noise_result(doc)


def health_check(
    recording: Any,
    calibration: Any = None,
    *,
    latitude_deg: Optional[float] = None,
    height_m: float = 0.0,
    gravity_m_s2: Optional[float] = None,
    false_alarm_p: float = 1e-4,
    source: str = "corrected",
    **read_kw: Any,
) -> HealthCheck:
    """The daemon's live calibration health checks, offline: ``imu-analyze health --json``.

    ``recording``: a :class:`Recording` or a path (or the files of one session; read from
    ``source`` with ``read_kw``) holding the stream the calibration's health sees (imud's
    corrected stream). ``calibration``: the :class:`imud.Calibration` in force (or its file):
    its noise tables give the expected scatter; None: the scatter is learned from the first
    still windows, as the daemon does without tables. Gravity: ``gravity_m_s2`` if given, else
    normal gravity at ``latitude_deg`` and ``height_m``, else learned from the first still
    windows (then only changes are seen). ``latitude_deg`` also gives Earth's rate's vertical
    part. ``false_alarm_p``: the false-alarm rate per still window and triad. Every still
    window is tested as the daemon would have live (same detector, tests and states), and the
    offset of the calibrated stream from physics is estimated over all of them.
    """
    rec = _one(recording, source, read_kw)
    cal = calibration
    if cal is not None and not isinstance(cal, _imud.Calibration):
        cal = _imud.Calibration.load(os.fspath(cal))
    doc = _imud.health_check_json(
        rec._series,
        cal,
        None if latitude_deg is None else float(latitude_deg),
        float(height_m),
        None if gravity_m_s2 is None else float(gravity_m_s2),
        float(false_alarm_p),
    )
    return health_check_result(json.loads(doc))


def _references(
    n: int,
    plan: Any,
    reference: Any,
    reference_offset_s: Any,
) -> list:
    """One ("plan"|"reference", path, offset) per recording; several recordings take lists."""

    def listed(v: Any) -> list:
        if v is None:
            return []
        if isinstance(v, (str, bytes, os.PathLike)):
            return [v]
        return list(v)

    plans, refs = listed(plan), listed(reference)
    if plans and refs:
        raise ValueError(
            "give plan or reference (one per recording), not both; for a mix pass "
            "references=[('plan', PATH), ('reference', PATH, OFFSET_S), ...]"
        )
    if plans:
        if reference_offset_s is not None:
            raise ValueError("reference_offset_s applies to a reference log, not to a plan")
        return [("plan", os.fspath(p), None) for p in plans]
    offsets = (
        [None] * len(refs)
        if reference_offset_s is None
        else listed(reference_offset_s)
        if isinstance(reference_offset_s, (list, tuple))
        else [reference_offset_s]
    )
    if len(offsets) != len(refs):
        raise ValueError(f"{len(offsets)} offsets for {len(refs)} references")
    return [
        ("reference", os.fspath(r), None if o is None else float(o))
        for r, o in zip(refs, offsets)
    ]


def _specs(references: Optional[Sequence[Sequence[Any]]]) -> Optional[list]:
    if references is None:
        return None
    out = []
    for r in references:
        kind, path, *rest = r
        out.append((str(kind), os.fspath(path), float(rest[0]) if rest and rest[0] is not None else None))
    return out


def _triple(v: Optional[Union[float, Sequence[float]]]) -> Optional[list]:
    if v is None:
        return None
    if isinstance(v, (int, float)):
        return [float(v)]
    return [float(x) for x in v]


def calibrate(
    recordings: Any,
    *,
    plan: Any = None,
    reference: Any = None,
    reference_offset_s: Any = None,
    references: Optional[Sequence[Sequence[Any]]] = None,
    reference_free: bool = False,
    gravity_m_s2: Optional[float] = None,
    latitude_deg: Optional[float] = None,
    accel_turn_on_bias_m_s2: Optional[Union[float, Sequence[float]]] = None,
    gyro_turn_on_bias_rad_s: Optional[Union[float, Sequence[float]]] = None,
    model: Optional[PathLike] = None,
    add: Sequence[str] = (),
    **read_kw: Any,
) -> CalibrationResult:
    """Fits accel and gyro error models: ``imu-calibrate --json``.

    ``recordings``: one :class:`Recording` or path, or a list of them (separate recordings of
    one unit, fitted together, each against its own reference; a path may be a session
    directory). Paths are read from the raw stream with ``read_kw`` (see :func:`imud.read`).
    The true input: ``plan`` (test plan files) or ``reference`` (truth MCAP or reference logs,
    with ``reference_offset_s``), one per recording, or ``references=[("plan", P),
    ("reference", P, OFFSET_S), ...]``, or ``reference_free=True`` (hand-held poses; with
    ``gravity_m_s2``, ``latitude_deg``). ``model``: a calibration file whose effects say what to
    fit (and whose noise tables widen the bias errors); ``add``: effects to add
    (``gyro:g-sensitivity``, ...). ``accel_turn_on_bias_m_s2``, ``gyro_turn_on_bias_rad_s``:
    turn-on bias repeatability (one value or X, Y, Z).
    """
    recs = as_recordings(recordings, "raw", read_kw)
    specs = _specs(references)
    if specs is None:
        specs = [] if reference_free else _references(len(recs), plan, reference, reference_offset_s)
    elif plan is not None or reference is not None:
        raise ValueError("references= replaces plan= and reference=")
    args = {
        "references": specs,
        "reference_free": bool(reference_free),
        "gravity_m_s2": gravity_m_s2,
        "latitude_deg": latitude_deg,
        "accel_turn_on_bias_m_s2": _triple(accel_turn_on_bias_m_s2),
        "gyro_turn_on_bias_rad_s": _triple(gyro_turn_on_bias_rad_s),
        "model": _path(model),
        "add": [str(a) for a in add],
    }
    doc, cal = _imud.calibrate_json([r._series for r in recs], args)
    return calibration_result(json.loads(doc), cal)


def _workbench_args(
    plan: Any,
    reference: Any,
    reference_offset_s: Optional[float],
    reference_free: bool,
    gravity_m_s2: Optional[float],
    latitude_deg: Optional[float],
    model: Optional[PathLike],
    add: Sequence[str],
) -> dict:
    if sum(x is not None for x in (plan, reference)) + bool(reference_free) != 1:
        raise ValueError("give exactly one of plan=, reference= or reference_free=True")
    if reference_offset_s is not None and reference is None:
        raise ValueError("reference_offset_s applies to reference=")
    spec = None
    if plan is not None:
        spec = ("plan", os.fspath(plan), None)
    elif reference is not None:
        off = None if reference_offset_s is None else float(reference_offset_s)
        spec = ("reference", os.fspath(reference), off)
    return {
        "reference": spec,
        "reference_free": bool(reference_free),
        "gravity_m_s2": gravity_m_s2,
        "latitude_deg": latitude_deg,
        "model": _path(model),
        "add": [str(a) for a in add],
    }


def diagnose(
    recording: Any,
    *,
    plan: Optional[PathLike] = None,
    reference: Optional[PathLike] = None,
    reference_offset_s: Optional[float] = None,
    reference_free: bool = False,
    gravity_m_s2: Optional[float] = None,
    latitude_deg: Optional[float] = None,
    model: Optional[PathLike] = None,
    add: Sequence[str] = (),
    **read_kw: Any,
) -> Diagnosis:
    """Holds a calibration model against a recording and ranks the effects that would explain
    what is left: ``imu-diagnose --json``.

    ``recording``: a :class:`Recording` or path (or the files of one session), read from the raw
    stream. Exactly one of ``plan``, ``reference`` (with ``reference_offset_s``) or
    ``reference_free`` (with ``gravity_m_s2``, ``latitude_deg``). ``model``: the model under
    test (default bias + scale + misalignment; its noise tables are the floor); ``add``:
    effects to add to it.
    """
    rec = _one(recording, "raw", read_kw)
    args = _workbench_args(
        plan, reference, reference_offset_s, reference_free, gravity_m_s2, latitude_deg, model, add
    )
    return diagnosis(json.loads(_imud.diagnose_json(rec._series, args)))


def ladder(
    recording: Any,
    *,
    plan: Optional[PathLike] = None,
    reference: Optional[PathLike] = None,
    reference_offset_s: Optional[float] = None,
    reference_free: bool = False,
    gravity_m_s2: Optional[float] = None,
    latitude_deg: Optional[float] = None,
    base: Optional[PathLike] = None,
    **read_kw: Any,
) -> LadderResult:
    """From the base model, adds the best claimed effect one at a time until accel and gyro are
    consistent with their noise floors: ``imu-diagnose ladder --json``. Options as
    :func:`diagnose`, ``base`` in place of ``model``. The result's ``calibration`` is the final
    model (``.save(path)`` writes a file imud loads)."""
    rec = _one(recording, "raw", read_kw)
    args = _workbench_args(
        plan, reference, reference_offset_s, reference_free, gravity_m_s2, latitude_deg, base, ()
    )
    doc, cal = _imud.ladder_json(rec._series, args)
    return ladder_result(json.loads(doc), cal)
