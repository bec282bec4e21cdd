"""Recordings: :func:`read` and :class:`Recording` (numpy arrays over imud's own series)."""

from __future__ import annotations

import json
import os
from functools import cached_property
from typing import Any, Optional, Sequence, Union

import numpy as np

from . import _imud

PathLike = Union[str, "os.PathLike[str]"]
#: One recording, the files of one session, or their directory.
Paths = Union[PathLike, Sequence[PathLike]]


def _paths(path: Paths) -> list:
    if isinstance(path, (str, bytes, os.PathLike)):
        return [os.fspath(path)]
    return [os.fspath(p) for p in path]


def _columns(v: Optional[Union[str, Sequence[Union[str, int]]]]) -> Optional[list]:
    if v is None:
        return None
    if isinstance(v, str):
        return [c.strip() for c in v.split(",")]
    return [str(c) for c in v]


def read_options(
    source: str = "corrected",
    topic: Optional[str] = None,
    time_scale_s: float = 1.0,
    rate_hz: Optional[float] = None,
    start_s: float = 0.0,
    accel_unit: str = "m/s2",
    gyro_unit: str = "rad/s",
    gyro_file: Optional[PathLike] = None,
    columns: Optional[Union[str, Sequence[Union[str, int]]]] = None,
    gyro_columns: Optional[Union[str, Sequence[Union[str, int]]]] = None,
    label_column: Optional[Union[str, int]] = None,
) -> dict:
    """The reading options of the offline clients' flags, as the compiled module takes them."""
    return {
        "source": source,
        "topic": topic,
        "time_scale_s": float(time_scale_s),
        "rate_hz": None if rate_hz is None else float(rate_hz),
        "start_s": float(start_s),
        "accel_unit": accel_unit,
        "gyro_unit": gyro_unit,
        "gyro_file": None if gyro_file is None else os.fspath(gyro_file),
        "columns": _columns(columns),
        "gyro_columns": _columns(gyro_columns),
        "label_column": None if label_column is None else str(label_column),
    }


class Recording:
    """One recording: samples as numpy arrays, and where they came from.

    The samples stay in imud's own layout (the analyses read them there without a copy); each
    array is made on first access and cached. ``len(rec)`` is the number of samples.

    Attributes (arrays are float64):
        time_s: (N,) sample times, seconds from the first sample.
        accel_m_s2: (N, 3) specific force, sensor frame, m/s^2.
        gyro_rad_s: (N, 3) angular rate, sensor frame, rad/s.
        temperature_c: (N,) temperature at each sample, degC (the latest reading at or before
            it; NaN before the first or without any).
        info: origin, files, topic, gaps between files, sample rate, unfinished file, and
            what the recording says about itself: ``started_utc`` (ISO 8601 UTC of the first
            sample, None when unknown), ``missing_samples`` (samples lost, judged by the time
            gaps against the sample interval, gaps between a session's files included; the
            ``input["non_finite_samples"]`` skipped for a NaN or infinite value among them),
            ``device`` (an imud recording's ``imud.device`` metadata: ``model``,
            ``serial-number``, firmware, gains...; ``{}`` without) and
            ``calibration_in_force`` (``{"id", "toml", "file"}`` of the ``imud.calibration``
            metadata, the one put in force last; None without).
        source: ``"corrected"`` or ``"raw"``: which stream of an imud recording was read.
    """

    def __init__(self, series: "_imud.Series", source: str) -> None:
        self._series = series
        self.source = source

    @classmethod
    def from_arrays(
        cls,
        time_s: np.ndarray,
        accel_m_s2: np.ndarray,
        gyro_rad_s: np.ndarray,
        temperature_c: Optional[np.ndarray] = None,
        source: str = "raw",
    ) -> "Recording":
        """A recording from arrays: ``time_s`` (N,), ``accel_m_s2`` and ``gyro_rad_s`` (N, 3),
        ``temperature_c`` (N,) or None (NaN: no reading). Arrays that are already C-contiguous
        float64 are read in place; others are converted first."""
        f = lambda a: np.ascontiguousarray(a, dtype=np.float64)  # noqa: E731
        t = None if temperature_c is None else f(temperature_c)
        return cls(_imud.Series.from_arrays(f(time_s), f(accel_m_s2), f(gyro_rad_s), t), source)

    def __len__(self) -> int:
        return len(self._series)

    def __repr__(self) -> str:
        return f"Recording({self.info['origin']!r}, {len(self)} samples, {self.source})"

    @cached_property
    def time_s(self) -> np.ndarray:
        return self._series.time_s()

    @cached_property
    def accel_m_s2(self) -> np.ndarray:
        return self._series.accel_m_s2()

    @cached_property
    def gyro_rad_s(self) -> np.ndarray:
        return self._series.gyro_rad_s()

    @cached_property
    def temperature_c(self) -> np.ndarray:
        return self._series.temperature_c()

    @cached_property
    def temperature_readings(self) -> "tuple[np.ndarray, np.ndarray]":
        """The temperature readings as recorded: (times s, degC)."""
        return self._series.temperature_readings()

    @cached_property
    def info(self) -> dict:
        return json.loads(self._series.info_json())

    @property
    def sample_rate_hz(self) -> float:
        return self.info["sample_rate_hz"]

    @property
    def device(self) -> dict:
        """The device an imud recording says it recorded (its ``imud.device`` metadata, as
        the daemon writes it: ``model``, ``serial-number``...); ``{}`` for other inputs."""
        return dict(self.info["device"])

    @cached_property
    def calibration_in_force(self) -> "Optional[_imud.Calibration]":
        """The :class:`imud.Calibration` the recording says was in force (its
        ``imud.calibration`` metadata; the one put in force last), or None. Raises
        :class:`ImudError` naming the recording file if that text is not a valid calibration."""
        cal = self.info["calibration_in_force"]
        if cal is None:
            return None
        return _imud.Calibration.from_toml(cal["toml"], source=f"{cal['file']} (imud.calibration)")

    def to_arrow(self) -> Any:
        """The samples as a ``pyarrow.Table`` (columns time_s, accel_x/y/z_m_s2,
        gyro_x/y/z_rad_s, temperature_c); needs pyarrow."""
        try:
            import pyarrow as pa
        except ImportError as e:  # pragma: no cover - depends on the environment
            raise ImportError("Recording.to_arrow needs pyarrow: pip install pyarrow") from e
        a, g = self.accel_m_s2, self.gyro_rad_s
        cols = {"time_s": self.time_s}
        for i, x in enumerate("xyz"):
            cols[f"accel_{x}_m_s2"] = a[:, i]
        for i, x in enumerate("xyz"):
            cols[f"gyro_{x}_rad_s"] = g[:, i]
        cols["temperature_c"] = self.temperature_c
        meta = {"imud.origin": str(self.info["origin"]), "imud.source": self.source}
        return pa.table(cols, metadata=meta)


def read(
    path: Paths,
    topic: Optional[str] = None,
    *,
    source: str = "corrected",
    time_scale_s: float = 1.0,
    rate_hz: Optional[float] = None,
    start_s: float = 0.0,
    accel_unit: str = "m/s2",
    gyro_unit: str = "rad/s",
    gyro_file: Optional[PathLike] = None,
    columns: Optional[Union[str, Sequence[Union[str, int]]]] = None,
    gyro_columns: Optional[Union[str, Sequence[Union[str, int]]]] = None,
    label_column: Optional[Union[str, int]] = None,
) -> Recording:
    """Reads a recording as the offline clients do.

    ``path`` is an imud MCAP log, a rosbag2 MCAP file or directory, a ROS 1 bag, a text file in
    any layout, or several files of one imud session (or their directory), read in time order.
    ``topic`` picks the ``sensor_msgs/msg/Imu`` topic when there are several. ``source`` is the
    stream of an imud recording (``"corrected"``, or ``"raw"``: what calibration fits need).
    The text options are the clients' flags: ``time_scale_s`` (``--csv-time-scale-s``),
    ``rate_hz`` and ``start_s`` (no time column), ``accel_unit`` (``m/s2``, ``g``,
    ``counts:SCALE[@OFFSET]``), ``gyro_unit`` (``rad/s``, ``deg/s``, counts), ``gyro_file`` (the
    gyro's own text file), ``columns``, ``gyro_columns``, ``label_column`` (0-based indices or
    header names).

    Raises :class:`ImudError` with the client's message (file and line of a bad text row).
    """
    opts = read_options(
        source, topic, time_scale_s, rate_hz, start_s, accel_unit, gyro_unit, gyro_file,
        columns, gyro_columns, label_column,
    )
    return Recording(_imud.read_series(_paths(path), opts), source)


def as_recordings(rec_or_paths: Any, source: str, read_kw: dict) -> "list[Recording]":
    """A Recording as it is, or a path (or list of paths: separate recordings) read from
    ``source``."""
    items = rec_or_paths if isinstance(rec_or_paths, (list, tuple)) else [rec_or_paths]
    out = []
    for item in items:
        if isinstance(item, Recording):
            if read_kw:
                raise TypeError(
                    f"reading options {sorted(read_kw)} apply to paths, not to a Recording"
                )
            out.append(item)
        else:
            out.append(read(item, source=source, **read_kw))
    return out
