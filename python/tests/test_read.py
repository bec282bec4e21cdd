"""imud.read and Recording: every format's arrays, the text options, errors with the file and
line, and the numpy/Arrow views."""

import os
import subprocess

import numpy as np
import pytest

import imud


def test_an_imud_recording_reads_as_arrays(index_table):
    rec, _ = index_table
    r = imud.read(rec)
    n = len(r)
    assert n > 10_000
    assert r.time_s.shape == (n,) and r.accel_m_s2.shape == (n, 3) and r.gyro_rad_s.shape == (n, 3)
    assert r.temperature_c.shape == (n,)
    assert r.accel_m_s2.dtype == np.float64
    assert r.time_s[0] == 0.0 and np.all(np.diff(r.time_s) > 0)
    assert r.sample_rate_hz == pytest.approx(100.0, rel=1e-3)
    # Still on an index table: the specific force is gravity, whatever the position.
    g = np.linalg.norm(r.accel_m_s2, axis=1)
    assert abs(np.median(g) - 9.80) < 0.1
    assert r.info["input"]["files"] == [str(rec)]
    # The raw stream is another reading of the same samples.
    raw = imud.read(rec, source="raw")
    assert len(raw) == n and raw.source == "raw"
    # (stamped from the device's ticks in both; within a microsecond of each other)
    np.testing.assert_allclose(raw.time_s, r.time_s, rtol=0, atol=1e-6)


def test_text_reads_back_exactly_with_the_cli_options(tmp_path):
    rng = np.random.default_rng(1)
    n = 500
    t = np.arange(n) / 200.0
    a = rng.normal(0, 1, (n, 3)) + [0, 0, 9.81]
    g = rng.normal(0, 0.01, (n, 3))
    path = tmp_path / "imu.csv"
    with open(path, "w") as f:
        f.write("t_ns,gx,gy,gz,ax,ay,az\n")
        for i in range(n):
            values = [format(float(v), ".17g") for v in (*g[i], *a[i])]
            f.write(",".join([str(int(round(t[i] * 1e9)))] + values) + "\n")
    r = imud.read(path, time_scale_s=1e-9, columns="t_ns,ax,ay,az,gx,gy,gz")
    np.testing.assert_array_equal(r.accel_m_s2, a)
    np.testing.assert_array_equal(r.gyro_rad_s, g)
    np.testing.assert_allclose(r.time_s, t - t[0], rtol=0, atol=1e-12)
    # deg/s and g, as --csv-gyro deg/s --csv-accel g
    r2 = imud.read(path, time_scale_s=1e-9, columns=[0, 4, 5, 6, 1, 2, 3],
                   accel_unit="g", gyro_unit="deg/s")
    np.testing.assert_allclose(r2.gyro_rad_s, np.radians(g), rtol=1e-15)
    np.testing.assert_allclose(r2.accel_m_s2, a * 9.80665, rtol=1e-15)


def test_a_bad_text_row_is_an_imud_error_naming_file_and_line(tmp_path, bins):
    path = tmp_path / "bad.csv"
    path.write_text("0.00,0,0,9.8,0,0,0\n0.01,0,0,9.8,0,0,0\n0.02,0,zero,9.8,0,0,0\n")
    with pytest.raises(imud.ImudError) as e:
        imud.read(path)
    msg = str(e.value)
    assert f"{path}:3" in msg, msg
    # The same words as the command-line client's.
    out = subprocess.run([str(bins / "imu-noise"), str(path)], capture_output=True, text=True)
    assert out.returncode != 0
    assert msg in out.stderr, (msg, out.stderr)
    assert issubclass(imud.ImudError, Exception)


def test_a_missing_file_and_bad_options_are_imud_errors(tmp_path):
    with pytest.raises(imud.ImudError, match="nothing.mcap"):
        imud.read(tmp_path / "nothing.mcap")
    with pytest.raises(imud.ImudError, match="accel_unit"):
        imud.read(tmp_path / "x.csv", accel_unit="furlongs")
    with pytest.raises(imud.ImudError, match="source"):
        imud.read(tmp_path / "x.csv", source="cooked")


def test_from_arrays_round_trips_and_refuses_wrong_shapes():
    n = 1000
    t = np.arange(n) / 100.0
    a = np.tile([0.0, 0.0, 9.81], (n, 1))
    g = np.zeros((n, 3))
    temp = np.full(n, 30.0)
    r = imud.Recording.from_arrays(t, a, g, temp)
    np.testing.assert_array_equal(r.accel_m_s2, a)
    np.testing.assert_array_equal(r.temperature_c, temp)
    assert r.sample_rate_hz == pytest.approx(100.0)
    with pytest.raises(imud.ImudError, match="shape"):
        imud.Recording.from_arrays(t, a[:-1], g)


def test_to_arrow_has_every_column():
    if os.environ.get("IMUD_REQUIRE_PEERS") == "1":
        import pyarrow  # noqa: F401  (a missing peer fails the run)
    pa = pytest.importorskip("pyarrow")
    n = 50
    t = np.arange(n) / 100.0
    a = np.arange(3 * n, dtype=float).reshape(n, 3)
    g = -a
    r = imud.Recording.from_arrays(t, a, g)
    table = r.to_arrow()
    assert isinstance(table, pa.Table) and table.num_rows == n
    np.testing.assert_array_equal(table.column("accel_y_m_s2").to_numpy(), a[:, 1])
    np.testing.assert_array_equal(table.column("gyro_z_rad_s").to_numpy(), g[:, 2])
    np.testing.assert_array_equal(table.column("time_s").to_numpy(), t)
