"""What a recording says about itself (``Recording.info``, ``.device``,
``.calibration_in_force``): the simulated unit's serial number, the calibration imud applied,
the scenario's date of time 0 and the samples its dropouts lost, each against the scenario
that made the recording."""

import subprocess
from datetime import datetime, timezone

import pytest

import imud
from conftest import SCENARIOS

TRUTH_MODEL = SCENARIOS.parent / "models" / "example-3dm-gx1.toml"

#: 2026-01-01T00:00:00Z, the scenarios' default `[device] gnss-epoch-utc-s`.
DEFAULT_EPOCH_S = 1_767_225_600


def scenario(serial, extra="", device_extra=""):
    """A still minute at 100 Hz of unit `serial`."""
    return (
        f'name = "unit-{serial}"\nrate-hz = 100.0\n{extra}\n'
        f"[device]\nserial-number = {serial}\n{device_extra}\n"
        '[[segment]]\nkind = "static"\nduration-s = 60.0\n'
    )


def record(bins, tmp, name, text, *extra):
    """Records scenario `text` offline (seed 3) with imud's flags `extra`: the recording."""
    path = tmp / f"{name}.toml"
    path.write_text(text)
    log = tmp / name
    out = subprocess.run(
        [str(bins / "imud"), "--sim", str(path), "--offline", "--seed", "3", "--name", name,
         "--log-dir", str(log), *map(str, extra)],
        capture_output=True, text=True,
    )
    assert out.returncode == 0, out.stderr
    recs = sorted(log.glob(f"{name}-*.mcap"))
    recs = [r for r in recs if not r.name.endswith("-truth.mcap")]
    assert len(recs) == 1, list(log.iterdir())
    return recs[0]


def test_a_recording_names_its_unit_calibration_and_start(bins, tmp_path):
    rec = imud.read(record(bins, tmp_path, "u", scenario(4711), "--calibration", TRUTH_MODEL))
    assert rec.device["serial-number"] == "4711"
    assert rec.info["device"] == rec.device and rec.device["path"] == "offline simulation"
    cal = rec.calibration_in_force
    assert isinstance(cal, imud.Calibration)
    assert cal.content_id() == imud.Calibration.load(TRUTH_MODEL).content_id()
    assert rec.info["calibration_in_force"]["id"] == cal.content_id()
    start = datetime.fromisoformat(rec.info["started_utc"])
    assert start == datetime.fromtimestamp(DEFAULT_EPOCH_S, timezone.utc)
    assert rec.info["t0_ns"] == DEFAULT_EPOCH_S * 10**9
    assert rec.info["missing_samples"] == 0 and len(rec) == 6000


def test_without_a_calibration_or_metadata_nothing_is_said(bins, tmp_path):
    rec = imud.read(record(bins, tmp_path, "plain", scenario(12)))
    assert rec.calibration_in_force is None and rec.info["calibration_in_force"] is None
    assert rec.device["serial-number"] == "12"
    # 200 samples at 100 Hz, samples 50..54 missing.
    t = [i * 0.01 for i in range(200) if not 50 <= i < 55]
    n = len(t)
    arrays = imud.Recording.from_arrays(t, [[0, 0, 9.8]] * n, [[0, 0, 0]] * n)
    assert arrays.device == {} and arrays.calibration_in_force is None
    assert arrays.info["started_utc"] is None
    assert arrays.info["missing_samples"] == 5
