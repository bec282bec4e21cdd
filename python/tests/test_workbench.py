"""imud.diagnose and imud.ladder against imu-diagnose --json (1e-12) and the simulator's truth
(a hidden gyro g-sensitivity)."""

import json

import numpy as np

import imud
from compare import assert_close
from conftest import SCENARIOS

BASE = SCENARIOS.parent / "models" / "bias-scale-misalignment.toml"
TRUTH_MODEL = SCENARIOS.parent / "models" / "workbench-demo.toml"


def test_diagnose_equals_the_cli(workbench_demo, cli):
    rec, truth = workbench_demo
    res = imud.diagnose(rec, reference=truth, model=BASE)
    doc = cli("imu-diagnose", rec, "--reference", truth, "--model", BASE)
    for k in ("notes", "added", "verdict", "verdict_codes"):
        assert_close(res.to_dict()[k], doc[k])
    assert_close(res.to_dict()["diagnoses"], doc["diagnoses"])
    # The base model misses the g-sensitivity the truth hides: the gyro is not consistent and
    # the candidate claimed is that effect; programs read it from the codes, not the words.
    assert not res.gyro.consistent
    assert [c["effect"] for c in res.gyro.claimed] == ["g-sensitivity"]
    assert res.gyro.verdict_codes[0] == "missing_effect"
    assert res.verdict_codes["gyro"] == res.gyro.verdict_codes
    assert [c["explanation_code"] for c in res.gyro.claimed] == ["fitted"]


def test_diagnose_with_an_added_effect_equals_the_cli(workbench_demo, cli):
    rec, truth = workbench_demo
    res = imud.diagnose(rec, reference=truth, add=["gyro:g-sensitivity"])
    doc = cli("imu-diagnose", rec, "--reference", truth, "--add", "gyro:g-sensitivity")
    assert_close(res.to_dict()["diagnoses"], doc["diagnoses"])
    assert res.added == [["gyro", "g-sensitivity"]]
    # With the effect, the fitted g-sensitivity is the simulated one within 3 standard errors.
    truth_cal = imud.Calibration.load(TRUTH_MODEL)
    names, values = truth_cal.param_names("gyro"), truth_cal.params("gyro")
    fit = res.gyro.extra["fit"]
    checked = 0
    for name, value, se in zip(fit["names"], fit["params"], fit["std_errors"]):
        if name.startswith("g-sensitivity") and se is not None:
            t = values[names.index(name)] if name in names else 0.0
            assert abs(value - t) < 3 * se, (name, value, t, se)
            checked += 1
    assert checked == 9


def test_the_ladder_equals_the_cli_and_adds_the_hidden_effect(workbench_demo, cli, tmp_path):
    rec, truth = workbench_demo
    res = imud.ladder(rec, reference=truth, base=BASE)
    out = tmp_path / "ladder.toml"
    doc = cli("imu-diagnose", "ladder", rec, "--reference", truth, "--base", BASE, "-o", out)
    for k in ("notes", "note_codes", "added", "steps", "verdict", "verdict_codes"):
        assert_close(res.to_dict()[k], doc[k])
    assert ["gyro", "g-sensitivity"] in res.added
    assert res.gyro.consistent
    theirs = json.loads(imud.Calibration.load(out).to_json())
    mine = json.loads(res.calibration.to_json())
    for t in ("accel", "gyro"):
        assert_close(mine[t], theirs[t])
    assert np.isfinite(res.steps[-1].gyro["p_value"])


def test_reference_free_diagnose_equals_the_cli(multi_pose, cli):
    rec, _ = multi_pose
    res = imud.diagnose(rec, reference_free=True, latitude_deg=40.0)
    doc = cli("imu-diagnose", rec, "--reference-free", "--latitude-deg", "40")
    for k in ("notes", "note_codes", "added", "verdict", "verdict_codes", "diagnoses"):
        assert_close(res.to_dict()[k], doc[k])
    # The reference-free conventions are noted, each with its code, in the same order.
    assert res.note_codes == [
        "local_gravity",
        "accel_magnitude",
        "earth_rate_at_poses",
        "gyro_moves",
    ]
    assert len(res.notes) == len(res.note_codes)
