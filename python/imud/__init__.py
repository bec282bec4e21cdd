"""imud from Python: read IMU recordings into numpy arrays and run imud's analyses on them.

The analyses are imud's own Rust libraries, called in-process (no subprocess): every function
takes the same options as the command-line client it mirrors and returns the same numbers as
that client's ``--json``:

- :func:`read` -- any recording the offline tools read (imud MCAP, rosbag2, ROS 1 bag, text);
- :func:`noise` -- ``imu-noise``: Allan-family deviations and IEEE noise terms per axis;
- :func:`health_check` -- ``imu-analyze health``: the daemon's live calibration health checks
  (still windows against gravity and Earth's rate) offline, and the calibration's offset;
- :func:`calibrate` -- ``imu-calibrate``: calibration fits against references or reference-free;
- :func:`diagnose`, :func:`ladder` -- ``imu-diagnose``: the model workbench;
- :class:`Calibration` -- imud's calibration file, and its correction vectorised over arrays.

Errors are raised as :class:`ImudError` with the client's message (file, line, what to do).
"""

from ._imud import ImudError, Calibration, normal_gravity_m_s2, example_model_toml, __version__
from ._recording import Recording, read
from ._analyses import noise, health_check, calibrate, diagnose, ladder
from ._results import (
    NoiseResult,
    NoiseAxis,
    HealthCheck,
    StillWindowCheck,
    AccelScaleFit,
    CalibrationResult,
    TriadFit,
    Diagnosis,
    TriadDiagnosis,
    LadderResult,
    LadderStep,
)

__all__ = [
    "ImudError",
    "Calibration",
    "Recording",
    "read",
    "noise",
    "health_check",
    "normal_gravity_m_s2",
    "example_model_toml",
    "calibrate",
    "diagnose",
    "ladder",
    "NoiseResult",
    "NoiseAxis",
    "HealthCheck",
    "StillWindowCheck",
    "AccelScaleFit",
    "CalibrationResult",
    "TriadFit",
    "Diagnosis",
    "TriadDiagnosis",
    "LadderResult",
    "LadderStep",
    "__version__",
]
