"""imud.calibrate against imu-calibrate --json (1e-12) and against the simulator's truth."""

import numpy as np
import pytest

import imud
from compare import assert_close
from conftest import SCENARIOS

PLAN = SCENARIOS.parent / "plans" / "index-table-12pos.toml"
TRUTH_MODEL = SCENARIOS.parent / "models" / "example-3dm-gx1.toml"

# What the index table observes: accel bias, scale, misalignment and cubic nonlinearity, gyro
# bias (as clients/imu-calibrate/tests/cli.rs), with the unit's noise tables.
INDEX_MODEL = """
format = "imud-calibration/1"
[accel.bias]
value = [0.0, 0.0, 0.0]
[accel.scale]
value = [0.0, 0.0, 0.0]
[accel.misalignment]
[accel.scale-nonlinearity]
quadratic = [0.0, 0.0, 0.0]
cubic = [0.0, 0.0, 0.0]
[gyro.bias]
value = [0.0, 0.0, 0.0]
[accel.noise]
white-density = [1.5e-3, 1.5e-3, 1.8e-3]
bias-instability = [1.27e-3, 9.8e-4, 4.2e-4]
bias-instability-tau-max-s = 1000.0
random-walk = [2.0e-5, 2.0e-5, 2.0e-5]
quantization-lsb = [2.1e-3, 2.1e-3, 2.1e-3]
[gyro.noise]
white-density = [1.0e-3, 1.0e-3, 1.0e-3]
bias-instability = [2.4e-4, 2.4e-4, 2.4e-4]
bias-instability-tau-max-s = 1000.0
random-walk = [1.0e-5, 1.0e-5, 1.0e-5]
quantization-lsb = [2.6e-4, 2.6e-4, 2.6e-4]
"""


@pytest.fixture(scope="module")
def index_model(tmp_path_factory):
    p = tmp_path_factory.mktemp("model") / "model.toml"
    p.write_text(INDEX_MODEL)
    return p


def test_a_plan_fit_equals_the_cli_and_recovers_the_truth(index_table, index_model, cli, tmp_path):
    rec, _ = index_table
    res = imud.calibrate(rec, plan=PLAN, model=index_model)
    out = tmp_path / "cli.toml"
    doc = cli("imu-calibrate", rec, "--plan", PLAN, "--model", index_model, "-o", out)
    assert res.procedure == "reference"
    assert_close(res.fit, doc["fit"])
    # A note per code, the plan's gravity first (the codes are for programs, the notes for people).
    assert res.note_codes == doc["fit"]["note_codes"]
    assert res.note_codes[0] == "plan_gravity" and len(res.notes) == len(res.note_codes)
    # The calibration: the same model as the CLI's file (provenance apart).
    mine = imud.Calibration.from_toml(res.calibration.to_toml())
    theirs = imud.Calibration.load(out)
    for t in ("accel", "gyro"):
        assert mine.param_names(t) == theirs.param_names(t)
        assert_close(mine.params(t), theirs.params(t))
    # Truth: every parameter with a standard error within 3 of them of the simulated unit's.
    truth = imud.Calibration.load(TRUTH_MODEL)
    fitted = 0
    for fit in (res.accel, res.gyro):
        names, values = truth.param_names(fit.triad), truth.params(fit.triad)
        for name, value, se in zip(fit.names, fit.params, fit.std_errors):
            if np.isnan(se):
                continue
            t = values[names.index(name)] if name in names else 0.0
            assert abs(value - t) < 3 * se, (fit.triad, name, value, t, se)
            fitted += 1
    assert fitted == 18 + 3


def test_a_fit_against_the_truth_file_equals_the_cli(index_table, cli):
    rec, truth = index_table
    r = imud.read(rec, source="raw")
    res = imud.calibrate(r, reference=truth, add=["accel:scale-nonlinearity"])
    doc = cli("imu-calibrate", rec, "--reference", truth, "--add", "accel:scale-nonlinearity")
    assert_close(res.fit, doc["fit"])
    assert res.accel.value("bias.x")[1] > 0


def test_reference_free_equals_the_cli(multi_pose, cli):
    rec, _ = multi_pose
    res = imud.calibrate(rec, reference_free=True, latitude_deg=40.0)
    doc = cli("imu-calibrate", rec, "--reference-free", "--latitude-deg", "40")
    assert res.procedure == "reference-free"
    assert_close(res.fit, doc["fit"])
    assert "local_gravity" in res.note_codes and "gyro_gains_method" in res.note_codes


def test_calibration_files_round_trip(index_table, index_model, tmp_path):
    rec, _ = index_table
    cal = imud.calibrate(rec, plan=PLAN, model=index_model).calibration
    p = tmp_path / "cal.toml"
    cal.save(p)
    back = imud.Calibration.load(p)
    assert back.to_toml() == cal.to_toml()
    assert back.content_id() == cal.content_id()


def test_bad_arguments_are_errors(index_table, tmp_path):
    rec, truth = index_table
    with pytest.raises(ValueError, match="not both"):
        imud.calibrate(rec, plan=PLAN, reference=truth)
    with pytest.raises(imud.ImudError, match="references for"):
        imud.calibrate([rec, rec], plan=PLAN)
    with pytest.raises(imud.ImudError, match="reference_free only"):
        imud.calibrate(rec, plan=PLAN, latitude_deg=40.0)
    bad = tmp_path / "bad.toml"
    bad.write_text('format = "imud-calibration/1"\n[accel.bias]\nvalu = [0, 0, 0]\n')
    with pytest.raises(imud.ImudError, match="bad.toml"):
        imud.calibrate(rec, plan=PLAN, model=bad)
