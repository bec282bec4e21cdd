"""imud.read on ROS logs: one of our recordings converted by Python `rosbags` (an independent
writer, tests/python/write_ros_logs.py) into a ROS 1 bag, a rosbag2 sqlite3 bag and a rosbag2
MCAP bag reads back as the same samples, and analyses the same, as the MCAP original."""

import os
import subprocess
import sys

import numpy as np
import pytest

import imud
from compare import assert_close
from conftest import REPO


@pytest.fixture(scope="module")
def converted(index_table, tmp_path_factory):
    rec, _ = index_table
    prefix = tmp_path_factory.mktemp("ros") / "rec"
    script = REPO / "tests" / "python" / "write_ros_logs.py"
    out = subprocess.run([sys.executable, str(script), "convert", str(rec), str(prefix)],
                         capture_output=True, text=True)
    if out.returncode == 77:
        if os.environ.get("IMUD_REQUIRE_PEERS") == "1":
            pytest.fail(f"rosbags missing (IMUD_REQUIRE_PEERS=1): {out.stderr}")
        pytest.skip(f"rosbags missing: {out.stderr}")
    assert out.returncode == 0, out.stderr
    return rec, [prefix.with_suffix(".bag"), prefix.parent / "rec-db3", prefix.parent / "rec-mcap"]


def test_every_ros_log_reads_as_the_recording(converted):
    rec, logs = converted
    ref = imud.read(rec)
    for log in logs:
        r = imud.read(log)
        assert len(r) == len(ref), log
        np.testing.assert_array_equal(r.accel_m_s2, ref.accel_m_s2, err_msg=str(log))
        np.testing.assert_array_equal(r.gyro_rad_s, ref.gyro_rad_s, err_msg=str(log))
        np.testing.assert_allclose(r.time_s, ref.time_s, rtol=0, atol=1e-9, err_msg=str(log))


def test_a_ros1_bag_analyses_as_the_cli_does(converted, cli):
    _, logs = converted
    bag = logs[0]
    py = imud.noise(bag, taus="octave")
    assert_close(py.to_list(), cli("imu-noise", bag, "--taus", "octave"))
