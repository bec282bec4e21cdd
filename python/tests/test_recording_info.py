"""What a recording says about itself (``Recording.info``, ``.device``,
``.calibration_in_force``): the simulated unit's serial number, the calibration imud applied,
the scenario's date of time 0 and the samples its dropouts lost, each against the scenario
that made the recording."""

import json
import subprocess
from datetime import datetime, timezone

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
    assert rec.device["serial-number"] == "4711" and rec.device["model"] == "3DM-GX1"
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


def test_offline_recordings_are_dated_by_their_scenarios(bins, tmp_path):
    # Two recordings of one unit 90 days apart: stamps, started_utc, the recorder's
    # started-utc metadata and the file names all follow the scenarios' gnss-epoch-utc-s.
    from mcap.reader import make_reader

    day_s = 86_400
    epochs = [DEFAULT_EPOCH_S + 17 * day_s + 3_600, DEFAULT_EPOCH_S + 107 * day_s + 3_600]
    got = []
    for i, epoch in enumerate(epochs):
        path = record(bins, tmp_path, f"d{i}", scenario(7, device_extra=f"gnss-epoch-utc-s = {epoch}"))
        rec = imud.read(path)
        start = datetime.fromtimestamp(epoch, timezone.utc)
        assert rec.info["t0_ns"] == epoch * 10**9
        assert datetime.fromisoformat(rec.info["started_utc"]) == start
        stamp = start.strftime("%Y%m%dT%H%M%SZ")
        assert path.name == f"d{i}-{stamp}-0000.mcap"
        with open(path, "rb") as f:
            meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
        assert meta["imud.recording"]["started-utc"] == stamp
        got.append(rec)
    assert got[1].info["t0_ns"] - got[0].info["t0_ns"] == 90 * day_s * 10**9
    a, b = (datetime.fromisoformat(r.info["started_utc"]) for r in got)
    assert (b - a).total_seconds() == 90 * day_s


def test_dropouts_lose_exactly_their_samples_and_the_reader_counts_them(bins, tmp_path):
    # Two dropouts: every sample of the truth inside them is missing from the recording and
    # the reader's missing_samples counts exactly those (the daemon's own loss counter:
    # daemon/tests/offline_dropouts.rs).
    from collections import Counter

    from mcap.reader import make_reader

    windows = [(12.0, 0.5), (40.005, 1.0)]
    extra = "".join(f"[[dropout]]\nat-s = {a}\nduration-s = {d}\n" for a, d in windows)
    path = record(bins, tmp_path, "lossy", scenario(31, extra=extra))
    truth = path.parent / "lossy-truth.mcap"
    with open(truth, "rb") as f:
        samples = [json.loads(m.data) for _, _, m in make_reader(f).iter_messages(
            topics=["/truth/sample"])]
    # The data command's truth (a GX1 also answers temperature polls, with truth of their own).
    data_cmd, _ = Counter(s["command"] for s in samples).most_common(1)[0]
    t_truth = [s["t_s"] for s in samples if s["command"] == data_cmd]
    assert len(t_truth) == 6000
    dropped = sum(any(a <= t < a + d for a, d in windows) for t in t_truth)
    assert dropped == 150
    rec = imud.read(path)
    assert len(rec) == len(t_truth) - dropped
    assert rec.info["missing_samples"] == dropped
    raw = imud.read(path, source="raw")
    assert len(raw) == len(rec) and raw.info["missing_samples"] == dropped
