"""Type stubs of the compiled module ``imud._imud`` (the Rust half of the package)."""

from os import PathLike
from typing import Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

class ImudError(Exception):
    """An imud analysis or reader failed; the message is the command-line client's."""

class Series:
    """A recording as the analyses see it (imud's ``ImudSeries``), never changed."""

    @staticmethod
    def from_arrays(
        time_s: npt.NDArray[np.float64],
        accel_m_s2: npt.NDArray[np.float64],
        gyro_rad_s: npt.NDArray[np.float64],
        temperature_c: Optional[npt.NDArray[np.float64]] = None,
        origin: Optional[str] = None,
    ) -> "Series": ...
    def __len__(self) -> int: ...
    def time_s(self) -> npt.NDArray[np.float64]: ...
    def accel_m_s2(self) -> npt.NDArray[np.float64]: ...
    def gyro_rad_s(self) -> npt.NDArray[np.float64]: ...
    def temperature_c(self) -> npt.NDArray[np.float64]: ...
    def temperature_readings(
        self,
    ) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
    def info_json(self) -> str:
        """JSON object: ``origin``, ``input`` (files, topic, gaps), ``t0_ns``, ``started_utc``
        (ISO 8601 or null), ``sample_rate_hz``, ``missing_samples``, ``stopped_early``,
        ``unfinished``, ``motion_warning``, ``device`` (the ``imud.device`` metadata, ``{}``
        without) and ``calibration_in_force`` (``{"id", "toml", "file"}`` or null)."""

class Calibration:
    """An imud calibration: the file imud loads, its parameters and its correction."""

    def __init__(self) -> None:
        """The identity calibration (no effects)."""
    @staticmethod
    def load(path: Union[str, PathLike[str]]) -> "Calibration":
        """Loads and validates an imud calibration file (errors name file, line and key)."""
    @staticmethod
    def from_toml(text: str, source: str = "<string>") -> "Calibration": ...
    def save(self, path: Union[str, PathLike[str]]) -> None:
        """Writes the calibration file (the format imud loads and hot-reloads)."""
    def to_toml(self) -> str: ...
    def to_json(self) -> str: ...
    def content_id(self) -> str: ...
    def param_names(self, triad_name: str) -> list[str]: ...
    def params(self, triad_name: str) -> list[float]: ...
    def correct(
        self,
        accel_m_s2: npt.NDArray[np.float64],
        gyro_rad_s: npt.NDArray[np.float64],
        temperature_c: Union[None, float, npt.NDArray[np.float64]] = None,
        time_s: Optional[npt.NDArray[np.float64]] = None,
    ) -> Tuple[
        npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.bool_]
    ]:
        """Corrects (N, 3) measurements as the daemon does, read in place; returns (accel,
        gyro, converged)."""

def read_series(paths: Sequence[str], options: dict) -> Series: ...
def noise_json(
    series: Series, kinds: Sequence[str], taus: str, edf: str, confidence: float
) -> str: ...
def normal_gravity_m_s2(latitude_deg: float, height_m: float = 0.0) -> float:
    """WGS-84 normal gravity at a latitude and a height above the ellipsoid, m/s^2."""
def health_check_json(
    series: Series,
    calibration: Optional[Calibration],
    latitude_deg: Optional[float],
    height_m: float,
    gravity_m_s2: Optional[float],
    false_alarm_p: float,
) -> str: ...
def calibrate_json(series: Sequence[Series], args: dict) -> Tuple[str, Calibration]: ...
def diagnose_json(series: Series, args: dict) -> str: ...
def ladder_json(series: Series, args: dict) -> Tuple[str, Calibration]: ...
