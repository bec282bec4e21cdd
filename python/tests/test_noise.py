"""imud.noise against imu-noise --json (1e-12) and against the simulator's noise model."""

import tomllib

import numpy as np

import imud
from compare import assert_close
from conftest import SCENARIOS


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
