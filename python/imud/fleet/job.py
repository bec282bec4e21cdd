"""One recording -> one row of the recordings table (:data:`imud.fleet.schema.RECORDINGS`).

The same function runs in a Ray task and in-process (``engine="local"``): it reads the
recording (a remote one copied to a temporary directory first, deleted after), tells its unit,
takes the calibration in force (the recording's own, else the one the job was given), runs
imud's health checks of that calibration on every still window (:func:`imud.health_check`:
offsets from gravity and Earth rate), and the noise terms (:func:`imud.noise`) on the longest
still span when it is long enough. A recording that gives no evidence is a row with ``error``
saying why; the job goes on.

Accel scale columns are filled where the recording's rests calibrate the scale: the health
check's joint fit of the bias offset and a scale error per axis to every still window's
``|f| - g`` (:class:`imud.AccelScaleFit`: 7 or more rests, each axis seen up and down), so the
column is the scale error against the calibration in force, 0 while it holds. Elsewhere they
are null, as the gyro scale columns always are: Earth's rate is too small to calibrate a gyro
scale from rests; that needs a turntable or a reference. The bias columns stay the bias-only
offset (what the daemon's live check estimates, and what every recording with a rest gives),
so a unit's biases are compared on one footing across all its recordings.
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
import time
import traceback
from dataclasses import dataclass
from typing import Any, Dict, List, Optional

import numpy as np

from . import schema
from .inputs import RecordingSpec

#: Shortest still span the noise terms are computed on, s: the Allan curve of a shorter one
#: reaches too few taus to separate white noise from bias instability.
DEFAULT_MIN_NOISE_SPAN_S = 60.0


@dataclass
class JobOptions:
    """What every recording's job is given (plain data: sent to each Ray task)."""

    #: TOML of the calibration used where a recording carries none.
    calibration_toml: Optional[str] = None
    calibration_source: str = "<calibration>"
    unit_column: Optional[str] = None
    unit_pattern: Optional[str] = None
    min_noise_span_s: float = DEFAULT_MIN_NOISE_SPAN_S
    latitude_deg: Optional[float] = None
    #: Local gravity, m/s^2 (None: normal gravity at the latitude, else learned, as
    #: :func:`imud.health_check` does).
    gravity_m_s2: Optional[float] = None


def analyze_recording(spec: RecordingSpec, options: JobOptions) -> Dict[str, Any]:
    """The recordings-table row of one recording (a dict keyed by column; absent keys null).
    Never raises for a bad recording: the row's ``error`` says what went wrong."""
    row: Dict[str, Any] = {"path": spec.path}
    tmp = None
    try:
        t0 = time.perf_counter()
        try:
            files = spec.files
            if spec.filesystem is not None:
                tmp = tempfile.mkdtemp(prefix="imud-fleet-")
                files = _fetch(spec, tmp)
            rec = _read(spec, files)
        finally:
            row["read_s"] = time.perf_counter() - t0
        _describe(rec, spec, options, row)
        cal = _calibration(rec, options)
        row["calibration_id"] = None if cal is None else cal.content_id()
        for t, _ in schema.TRIADS:
            names = [] if cal is None else cal.param_names(t)
            params = [] if cal is None else cal.params(t)
            for i, a in enumerate(schema.AXES):
                name = f"bias.{a}"
                row[schema.cal_bias(t, a)] = (
                    float(params[names.index(name)]) if name in names else 0.0
                )
        if len(rec) == 0:
            row["error"] = "no samples"
            return row
        t1 = time.perf_counter()
        try:
            check = _health(rec, cal, options)
        finally:
            row["check_s"] = time.perf_counter() - t1
        _check_columns(check, row)
        if not check.windows:
            row["error"] = (
                "no still window: the unit never rested long enough for a check against "
                "gravity and Earth rate"
            )
            return row
        t2 = time.perf_counter()
        try:
            _noise(rec, check, options, row)
        finally:
            row["noise_s"] = time.perf_counter() - t2
    except Exception as e:  # noqa: BLE001 - any failure of one recording is its row's error
        row["error"] = _message(e)
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    return row


def _message(e: BaseException) -> str:
    msg = str(e).strip() or type(e).__name__
    from .. import ImudError

    if isinstance(e, (ImudError, OSError, ValueError)):
        return msg
    # An unexpected failure: keep where it happened, for the bug report.
    tb = traceback.extract_tb(e.__traceback__)[-1:]
    where = f" ({tb[0].filename}:{tb[0].lineno})" if tb else ""
    return f"{type(e).__name__}: {msg}{where}"


def _fetch(spec: RecordingSpec, tmp: str) -> List[str]:
    """Copies a remote recording's files into ``tmp`` (a rosbag2 directory keeps its layout)."""
    out = []
    for f in spec.files:
        rel = (
            os.path.relpath(f, spec.directory)
            if spec.directory is not None
            else os.path.basename(f)
        )
        dst = os.path.join(tmp, rel)
        os.makedirs(os.path.dirname(dst), exist_ok=True)
        with spec.filesystem.open_input_stream(f) as src, open(dst, "wb") as out_f:
            shutil.copyfileobj(src, out_f, length=1 << 20)
        out.append(dst)
    if spec.directory is not None:
        return [tmp]
    return out


def _read(spec: RecordingSpec, files: List[str]) -> Any:
    import imud

    if spec.directory is not None and spec.filesystem is None:
        files = [spec.directory]
    return imud.read(files)


def _describe(rec: Any, spec: RecordingSpec, options: JobOptions, row: Dict[str, Any]) -> None:
    """Identity, time span, samples and losses of the recording."""
    info = rec.info
    device = info.get("device") or {}
    # A 3DM-GX1 reports no model name: its protocol names the device family then.
    model = str(device.get("model") or device.get("protocol") or "") or None
    serial = str(device.get("serial-number", "")) or None
    row["model"], row["serial"] = model, serial
    row["unit"] = _unit(spec.path, device, model, serial, options)
    t0_ns = int(info.get("t0_ns") or 0)
    row["start_utc"] = t0_ns if t0_ns > 0 else None
    t = rec.time_s
    row["samples"] = len(rec)
    row["duration_s"] = float(t[-1] - t[0]) if len(t) else 0.0
    missing = info.get("missing_samples")
    row["missing_samples"] = None if missing is None else int(missing)
    row["stopped_early"] = info.get("stopped_early")
    if row["unit"] is None:
        row["error"] = (
            "no unit identity: the recording has no device model and serial "
            "(give --unit-pattern or --unit-column)"
        )


def _unit(
    path: str, device: dict, model: Optional[str], serial: Optional[str], options: JobOptions
) -> Optional[str]:
    if options.unit_pattern is not None:
        m = re.search(options.unit_pattern, path)
        if m is None:
            return None
        if "unit" in m.re.groupindex:
            return m["unit"]
        return m[1] if m.re.groups else m[0]
    if options.unit_column is not None:
        v = device.get(options.unit_column)
        return None if v in (None, "") else str(v)
    if model is None and serial is None:
        return None
    return " ".join(x for x in (model, serial) if x)


def _calibration(rec: Any, options: JobOptions) -> Any:
    """The recording's calibration in force, else the job's, else None (health learns its
    noise from the first still windows then, as the daemon does)."""
    import imud

    own = getattr(rec, "calibration_in_force", None)
    if own is not None:
        return own
    if options.calibration_toml is not None:
        return imud.Calibration.from_toml(options.calibration_toml, options.calibration_source)
    return None


def _health(rec: Any, cal: Any, options: JobOptions) -> Any:
    import imud

    return imud.health_check(
        rec, cal, latitude_deg=options.latitude_deg, gravity_m_s2=options.gravity_m_s2
    )


def _f(v: Any) -> Optional[float]:
    """A float column's value: NaN (an axis no window observes) is null."""
    if v is None:
        return None
    v = float(v)
    return None if np.isnan(v) else v


def _check_columns(check: Any, row: Dict[str, Any]) -> None:
    row["still_windows"] = len(check.windows)
    row["still_s"] = _f(check.still_s)
    row["rejections"] = int(check.rejections)
    row["health_state"] = check.state
    row["noise_source"] = check.noise_source
    row["gravity_m_s2"] = _f(check.gravity_m_s2)
    row["accel_offset_3d"] = bool(check.accel_offset_3d)
    offsets = {
        "accel": (check.accel_offset_m_s2, check.accel_offset_std_m_s2),
        "gyro": (check.gyro_offset_rad_s, check.gyro_offset_std_rad_s),
    }
    for t, (off, std) in offsets.items():
        for i, a in enumerate(schema.AXES):
            o, s = _f(off[i]), _f(std[i])
            row[schema.offset(t, a)] = o
            row[schema.offset_std(t, a)] = s
            # For a linear model the true bias is the calibration's plus the offset, with the
            # offset's uncertainty (the calibration's bias is a given number here).
            cal = row[schema.cal_bias(t, a)]
            row[schema.bias(t, a)] = None if o is None else cal + o
            row[schema.bias_std(t, a)] = s
    # Where the rests calibrate the accelerometer's scale: its error against the calibration
    # in force (schema 1's scale column; 0 while the calibration holds).
    fit = check.accel_scale_fit
    if fit is not None:
        for i, a in enumerate(schema.AXES):
            row[schema.scale("accel", a)] = _f(fit.scale_error[i])
            row[schema.scale_std("accel", a)] = _f(fit.scale_error_std[i])


def _noise(rec: Any, check: Any, options: JobOptions, row: Dict[str, Any]) -> None:
    """Noise terms of the longest still span, when it is at least ``min_noise_span_s``."""
    import imud

    if check.longest_still_s is None or check.longest_still_s < options.min_noise_span_s:
        return
    start_s, end_s = check.longest_still_span_s
    t = rec.time_s
    sel = (t >= start_s) & (t <= end_s)
    if np.count_nonzero(sel) < 2:
        return
    span = imud.Recording.from_arrays(
        t[sel] - t[sel][0], rec.accel_m_s2[sel], rec.gyro_rad_s[sel], rec.temperature_c[sel]
    )
    res = imud.noise(span)
    row["noise_span_s"] = float(end_s - start_s)
    for t_name, _ in schema.TRIADS:
        for a in schema.AXES:
            fit = res.axis(t_name, a).fit
            for stem, key, _ in schema.NOISE_TERMS:
                term = fit.get(key) or {}
                row[schema.noise(t_name, stem, a)] = _f(term.get("value"))
                row[schema.noise_std(t_name, stem, a)] = _f(term.get("sigma"))
