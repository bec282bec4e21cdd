"""imud.Calibration: loading imud's files (errors with file and line), and the vectorised
correction against the simulator's truth and the one-sample path."""

import numpy as np
import pytest

import imud
from conftest import SCENARIOS

TRUTH_MODEL = SCENARIOS.parent / "models" / "example-3dm-gx1.toml"


def test_a_bad_file_names_its_line(tmp_path):
    p = tmp_path / "cal.toml"
    p.write_text('format = "imud-calibration/1"\n\n[accel.bias]\nvalue = [1, 2]\n')
    with pytest.raises(imud.ImudError, match=r"cal\.toml.*line 4|cal\.toml:4"):
        imud.Calibration.load(p)


def test_correcting_the_raw_stream_gives_gravity(index_table, tmp_path):
    # Still poses on an index table: corrected with the calibration fitted to them (bias,
    # scale, misalignment, cubic nonlinearity), the specific force is gravity (the simulator's
    # standard gravity, as the plan says), which the raw stream misses by its scale and bias
    # errors.
    from test_calibrate import INDEX_MODEL, PLAN

    rec, _ = index_table
    model = tmp_path / "model.toml"
    model.write_text(INDEX_MODEL)
    raw = imud.read(rec, source="raw")
    cal = imud.calibrate(raw, plan=PLAN, model=model).calibration
    a, g, ok = cal.correct(raw.accel_m_s2, raw.gyro_rad_s, raw.temperature_c, raw.time_s)
    assert ok.all() and a.shape == raw.accel_m_s2.shape and g.shape == raw.gyro_rad_s.shape
    still = np.linalg.norm(raw.gyro_rad_s - np.median(raw.gyro_rad_s, axis=0), axis=1) < 0.02
    # Averaged over the still samples (per-sample white noise is 0.015 m/s^2 per axis).
    err_raw = abs(np.linalg.norm(raw.accel_m_s2[still], axis=1).mean() - 9.80665)
    err = abs(np.linalg.norm(a[still], axis=1).mean() - 9.80665)
    assert err < 0.001 and err_raw > 0.01, (err, err_raw)


def test_arrays_are_read_in_place_and_checked():
    cal = imud.Calibration.load(TRUTH_MODEL)
    n = 100
    a = np.tile([0.1, -0.2, 9.8], (n, 1))
    g = np.tile([0.01, 0.0, -0.01], (n, 1))
    a.flags.writeable = False  # a read-only view is enough: nothing is written to it
    full, _, _ = cal.correct(a, g, 25.0)
    # One temperature for all equals the same value per sample; rows are independent.
    per, _, _ = cal.correct(a, g, np.full(n, 25.0))
    np.testing.assert_array_equal(full, per)
    one, _, _ = cal.correct(a[:1].copy(), g[:1].copy())
    np.testing.assert_array_equal(one[0], full[0])
    with pytest.raises(imud.ImudError, match="C-contiguous"):
        cal.correct(np.asfortranarray(a), g)
    with pytest.raises(imud.ImudError, match="values for"):
        cal.correct(a, g, np.zeros(3))
    ident = imud.Calibration()
    same, _, _ = ident.correct(a, g)
    np.testing.assert_array_equal(same, a)


def test_the_built_in_example_model_is_the_shipped_file():
    # imud.example_model_toml() (imud --sim's truth, the simulated fleet's default units) is the
    # file in config/models/, compiled in, and loads as a calibration with the file's values.
    import tomllib

    text = imud.example_model_toml()
    assert text == TRUTH_MODEL.read_text()
    cal = imud.Calibration.from_toml(text, "built-in")
    names, values = cal.param_names("accel"), cal.params("accel")
    bias = [v for n, v in zip(names, values) if n.startswith("bias")]
    assert bias == tomllib.loads(text)["accel"]["bias"]["value"], (names, values)
