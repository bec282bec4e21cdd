"""imud.health_check against imu-analyze health --json (1e-12) and against the simulator's
truth: a calibration whose biases are off by known vectors is found off by them."""

import subprocess

import numpy as np
import pytest

import imud
from compare import assert_close
from conftest import SCENARIOS

MODEL = SCENARIOS.parent / "models" / "example-3dm-gx1.toml"
G0 = 9.80665


def record_with(bins, tmp, scenario, seed, name, calibration):
    """Records a scenario through imud's offline pipeline with ``calibration`` in force."""
    log = tmp / name
    out = subprocess.run(
        [str(bins / "imud"), "--sim", str(scenario), "--offline", "--seed", str(seed),
         "--name", name, "--log-dir", str(log), "--calibration", str(calibration)],
        capture_output=True, text=True,
    )
    assert out.returncode == 0, out.stderr
    recs = sorted(log.glob(f"{name}-2*.mcap"))
    assert len(recs) == 1, list(log.iterdir())
    return recs[0]


@pytest.fixture(scope="session")
def knock(bins, tmp_path_factory):
    """The shipped health-knock scenario under its truth model as the calibration."""
    return record_with(bins, tmp_path_factory.mktemp("knock"), SCENARIOS / "health-knock.toml",
                       7, "knock", MODEL)


def _doc(cli_doc):
    """The CLI's document without what it says about the input files."""
    return {k: v for k, v in cli_doc.items() if k not in ("input", "input_unfinished")}


def test_health_check_equals_the_cli(knock, cli):
    py = imud.health_check(knock, imud.Calibration.load(MODEL), latitude_deg=40.0,
                           gravity_m_s2=G0)
    doc = cli("imu-analyze", "health", knock, "--calibration", MODEL, "--latitude-deg", "40",
              "--gravity-m-s2", str(G0))
    assert_close(py.to_dict(), _doc(doc))
    assert py.noise_source == "tables"
    assert len(py.windows) == len(doc["windows"]) >= 20
    # The knock at 250 s is flagged: a window before it is ok, one after it is not.
    assert py.windows[3].state == "ok"
    assert any(w.state != "ok" and w.start_s > 250.0 for w in py.windows)
    assert py.rejections >= 1


def test_health_check_of_a_recording_without_calibration_equals_the_cli(knock, cli):
    rec = imud.read(knock)
    py = imud.health_check(rec)
    doc = cli("imu-analyze", "health", knock)
    assert_close(py.to_dict(), _doc(doc))
    assert py.noise_source == "estimated"
    assert np.isnan(py.gyro_offset_std_rad_s).sum() == 0


ORIENTATIONS = [
    (25.0, 13.4, -37.9), (-13.6, -40.0, -48.4), (-40.0, 12.3, -102.7), (-12.4, 40.0, -154.9),
    (90.0, 0.0, 20.0), (0.0, 90.0, 75.0), (-90.0, 0.0, 130.0), (0.0, -90.0, -60.0),
    (180.0, 0.0, 10.0), (40.0, 1.5, -158.7), (2.0, -25.0, 47.0),
]


def _shifted(text, table, by):
    start = text.index(f"[{table}]")
    at = text.index("value = [", start)
    end = text.index("]", at)
    old = [float(v) for v in text[at + len("value = ["):end].split(",")]
    new = "value = [" + ", ".join(repr(float(o + b)) for o, b in zip(old, by)) + "]"
    return text[:at] + new + text[end + 1:]


def test_health_check_recovers_a_known_bias_offset(bins, tmp_path):
    scenario = tmp_path / "offset.toml"
    text = (f'name = "health-offset"\nrate-hz = 100.0\nlatitude-deg = 40.0\n'
            f'truth = "{MODEL}"\n\n[[segment]]\nkind = "static"\nduration-s = 30.0\n')
    for r, p, y in ORIENTATIONS:
        text += (f'\n[[segment]]\nkind = "static"\norientation = {{ roll-deg = {r}, '
                 f'pitch-deg = {p}, yaw-deg = {y} }}\nmove-s = 3.0\nduration-s = 30.0\n')
    scenario.write_text(text)
    d = np.array([0.02, -0.015, 0.01])
    e = np.array([2.0e-3, -1.0e-3, 1.5e-3])
    off = tmp_path / "off.toml"
    off.write_text(_shifted(_shifted(MODEL.read_text(), "accel.bias", d), "gyro.bias", e))
    rec = record_with(bins, tmp_path, scenario, 3, "offset", off)
    res = imud.health_check(rec, imud.Calibration.load(off), latitude_deg=40.0,
                            gravity_m_s2=G0)
    assert res.accel_offset_3d
    # Every rest but the last, which the recording ends before motion closes it (as live).
    assert len(res.windows) == len(ORIENTATIONS)
    # The calibration's bias is the truth's + d: the stream reads d too little, and the true
    # bias is the calibration's plus the offset.
    assert np.all(np.abs(res.accel_offset_m_s2 + d) < 3 * res.accel_offset_std_m_s2), (
        res.accel_offset_m_s2, res.accel_offset_std_m_s2)
    assert np.all(np.abs(res.gyro_offset_rad_s + e) < 3 * res.gyro_offset_std_rad_s), (
        res.gyro_offset_rad_s, res.gyro_offset_std_rad_s)
    assert res.state == "stale"
    # The rests see every axis up and down: the scale is calibrated too, and holds (the
    # calibration's scale is the truth's), with the same bias offset.
    fit = res.accel_scale_fit
    assert isinstance(fit, imud.AccelScaleFit) and fit.windows == len(ORIENTATIONS)
    assert np.all(np.abs(fit.scale_error) < 3 * fit.scale_error_std), fit
    assert np.all(np.abs(fit.offset_m_s2 + d) < 3 * fit.offset_std_m_s2), fit
    assert fit.to_dict() == res.to_dict()["accel_scale_fit"]


def test_normal_gravity_is_wgs84s():
    """imud.normal_gravity_m_s2 is the WGS-84 normal gravity (NIMA TR8350.2: 9.7803253359 m/s^2
    on the equator, 9.8321849378 at the poles, on the ellipsoid) and falls with height by the
    free-air gradient, about 3.086e-6 s^-2."""
    assert imud.normal_gravity_m_s2(0.0) == pytest.approx(9.7803253359, abs=1e-8)
    assert imud.normal_gravity_m_s2(90.0) == pytest.approx(9.8321849378, abs=1e-8)
    assert imud.normal_gravity_m_s2(-90.0) == pytest.approx(9.8321849378, abs=1e-8)
    drop = imud.normal_gravity_m_s2(45.0) - imud.normal_gravity_m_s2(45.0, height_m=1000.0)
    assert drop == pytest.approx(3.086e-3, rel=2e-3)
