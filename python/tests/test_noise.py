"""imud.noise against imu-noise --json (1e-12) and against the simulator's noise model."""

import tomllib

import numpy as np

import imud
from compare import assert_close
from conftest import SCENARIOS, record


def test_noise_equals_the_cli(static_run, cli):
    rec, _ = static_run
    py = imud.noise(rec, kind=["oadev", "mdev", "tdev"], edf="sp1065")
    doc = cli("imu-noise", rec, "--kind", "oadev,mdev,tdev", "--edf", "sp1065")
    assert_close(py.to_list(), doc)
    assert [(a.sensor, a.axis) for a in py.axes][:2] == [("accel", "x"), ("accel", "y")]


def test_noise_with_taus_in_seconds_equals_the_cli(static_run, cli):
    rec, _ = static_run
    r = imud.read(rec)
    py = imud.noise(r, taus=[0.1, 1.0, 10.0, 100.0], confidence=0.9)
    doc = cli("imu-noise", rec, "--taus", "0.1,1,10,100", "--confidence", "0.9")
    assert_close(py.to_list(), doc)
    np.testing.assert_allclose(py.axis("gyro", "z").taus_s(), [0.1, 1.0, 10.0, 100.0])


def test_white_noise_is_the_simulated_one(static_run):
    rec, _ = static_run
    with open(SCENARIOS.parent / "models" / "example-3dm-gx1.toml", "rb") as f:
        model = tomllib.load(f)
    res = imud.noise(rec)
    for sensor in ("accel", "gyro"):
        density = model[sensor]["noise"]["white-density"]
        for i, axis in enumerate("xyz"):
            n = res.axis(sensor, axis).fit["n_u_per_sqrt_hz"]
            # Within 3 reported sigmas, plus the unit's uncorrected scale error (up to 1 %):
            # the corrected stream of an uncalibrated recording carries it.
            assert abs(n["value"] - density[i]) < 3 * n["sigma"] + 0.01 * density[i], (
                sensor, axis, n, density[i])


def test_theo1_extends_the_noise_term_fit_as_in_the_cli(bins, cli, tmp_path):
    """With theo1 among the kinds the fit takes Theo1 points beyond the OADEV's longest tau, in
    Python as in imu-noise (a 60 s record: Theo1 costs O(N m) per tau)."""
    text = (SCENARIOS / "static-6h.toml").read_text()
    text = text.replace("duration-s = 21600.0", "duration-s = 60.0").replace(
        '"../models/', f'"{SCENARIOS.parent / "models"}/'
    )
    scenario = tmp_path / "static-1min.toml"
    scenario.write_text(text)
    rec, _ = record(bins, tmp_path, scenario, 11, name="static1min")
    py = imud.noise(rec, kind=["oadev", "theo1"], taus="octave")
    doc = cli("imu-noise", rec, "--kind", "oadev,theo1", "--taus", "octave")
    assert_close(py.to_list(), doc)
    plain = imud.noise(rec, kind="oadev", taus="octave")
    for a, b in zip(py.axes, plain.axes):
        assert a.fit["n_theo1_points"] >= 1, a.fit
        assert b.fit["n_theo1_points"] == 0, b.fit
        assert a.fit["n_points"] == b.fit["n_points"] + a.fit["n_theo1_points"]
