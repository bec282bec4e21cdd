"""The fleet job (imud.fleet) over a simulated fleet: 8 units of a 3DM-GX1-class MEMS IMU, 7
recordings each over 6 months of simulated dates, two of them with a drifting bias (one accel,
one gyro), plus an all-motion recording and one cut mid-file, and lost replies in some.

The fleet is made once (``python -m imud.fleet.simulate`` with the built ``imud``); the job runs
on a local Ray cluster (``ray.init(num_cpus=2)``) in a network namespace of its own with only
loopback (fleet_on_ray.py: as a library call and as ``python -m imud.fleet``), and in-process
(``engine="local"``). Checked against the simulator's truth: exactly the drifting units
flagged, their drift rates within 3 reported sigmas, the offsets of every recording, the
samples lost; the Ray result equal to the local one.
"""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import REPO, _missing

if os.environ.get("IMUD_REQUIRE_PEERS") != "1":
    # pyarrow is the fleet job's table format (pip install 'imud[fleet]'); under
    # IMUD_REQUIRE_PEERS the imports below fail instead of skipping.
    pytest.importorskip("pyarrow")
import pyarrow as pa  # noqa: E402
import pyarrow.dataset as pads  # noqa: E402

import imud  # noqa: E402
import imud.fleet  # noqa: E402
from imud.fleet import schema  # noqa: E402
from imud.fleet.inputs import find_recordings  # noqa: E402

UNITS, PER_UNIT, MONTHS = 8, 7, 6
LATITUDE_DEG = 40.0


@pytest.fixture(scope="session")
def imud_bin():
    """The built imud (the simulator is only needed here, not the analysis clients)."""
    p = Path(os.environ.get("IMUD_BIN_DIR", REPO / "target" / "debug")) / "imud"
    if not p.is_file():
        _missing(f"imud is not built at {p} (cargo build -p imud --bins)")
    return p


@pytest.fixture(scope="session")
def fleet(imud_bin, tmp_path_factory):
    """The simulated fleet: (directory, truth.json's document)."""
    from imud.fleet.simulate import simulate

    d = tmp_path_factory.mktemp("fleet")
    truth = simulate(
        d, units=UNITS, recordings=PER_UNIT, months=MONTHS, drifting=2,
        imud=str(imud_bin), seed=1,
    )
    return d, truth


@pytest.fixture(scope="session")
def on_ray(fleet, tmp_path_factory):
    """The job on a local Ray cluster in a network namespace with only loopback: the output
    directory (library/, cli/ datasets, fleet.html, cli.stdout)."""
    try:
        import ray  # noqa: F401
    except ImportError:
        _missing("Ray is not installed (pip install -r requirements-dev.txt)")
    for tool in ("unshare", "ip"):
        if shutil.which(tool) is None:
            _missing(f"`{tool}` is not installed (util-linux, iproute2): the Ray cluster runs in "
                     "a network namespace of its own")
    d, _ = fleet
    out = tmp_path_factory.mktemp("ray")
    script = Path(__file__).with_name("fleet_on_ray.py")
    run = subprocess.run(
        ["unshare", "-rn", "sh", "-c", 'ip link set lo up && exec "$0" "$@"',
         sys.executable, str(script), str(d / "recordings"), str(out)],
        capture_output=True, text=True, timeout=600,
    )
    if run.returncode != 0 and "unshare" in run.stderr and "Operation not permitted" in run.stderr:
        _missing(f"cannot make a network namespace here: {run.stderr.strip()}")
    assert run.returncode == 0, run.stderr[-4000:]
    return out


@pytest.fixture(scope="session")
def ray_result(on_ray):
    """(recordings, units) tables of the Ray run, read back from its Parquet dataset."""
    return tuple(
        pads.dataset(on_ray / "library" / name).to_table() for name in ("recordings", "units")
    )


@pytest.fixture(scope="session")
def local_result(fleet):
    d, _ = fleet
    return imud.fleet.analyze(d / "recordings", engine="local", latitude_deg=LATITUDE_DEG)


def _rows(table):
    """The table's rows as dicts, timestamps as int ns (datetime has only microseconds)."""
    cols = [c.cast(pa.int64()) if pa.types.is_timestamp(c.type) else c for c in table.columns]
    return pa.table(cols, names=table.column_names).to_pylist()


def _truth_recordings(truth):
    return {r["path"]: (u, r) for u in truth["units"].values() for r in u["recordings"]}


def _row(table, path):
    rows = [r for r in _rows(table) if r["path"] == path]
    assert len(rows) == 1, path
    return rows[0]


def test_every_recording_is_a_row_in_input_order(fleet, ray_result):
    d, truth = fleet
    rec, _ = ray_result
    n = sum(len(u["recordings"]) for u in truth["units"].values())
    assert n >= 40
    assert rec.num_rows == n
    assert rec.column("path").to_pylist() == sorted(str(p) for p in (d / "recordings").iterdir())
    assert len(set(rec.column("unit").to_pylist())) == UNITS
    starts = rec.column("start_utc").cast(pa.int64()).to_pylist()
    assert (max(starts) - min(starts)) / 86_400e9 >= MONTHS * 30 - 10


def test_exactly_the_drifting_units_are_flagged(fleet, ray_result):
    _, truth = fleet
    rec, units = ray_result
    serial_of = dict(zip(rec.column("unit").to_pylist(), rec.column("serial").to_pylist()))
    flagged = sorted(
        {serial_of[u] for u, f in zip(units.column("unit").to_pylist(),
                                      units.column("flagged").to_pylist()) if f}
    )
    drifting = sorted(s for s, u in truth["units"].items() if u["drifting"])
    assert len(drifting) == 2
    assert flagged == drifting


def test_drift_rate_is_the_true_one_within_its_uncertainty(fleet, ray_result):
    _, truth = fleet
    rec, units = ray_result
    unit_of = dict(zip(rec.column("serial").to_pylist(), rec.column("unit").to_pylist()))
    rows = _rows(units)
    for serial, u in truth["units"].items():
        if not u["drifting"]:
            continue
        (row,) = [r for r in rows if r["unit"] == unit_of[serial] and r["parameter"] == u["drifting"]]
        r_true = u["rate_per_day"]
        assert row["drifting"] and row["flagged"], row
        sigma = row["slope_std_per_day"]
        # Small enough to mean something, and the truth inside 3 of it.
        assert sigma < abs(r_true) / 4, (row, r_true)
        assert abs(row["slope_per_day"] - r_true) <= 3 * sigma, (row, r_true)


def test_each_recording_sees_its_true_bias_error(fleet, ray_result):
    """The offset of the calibrated stream is the true bias minus the calibration's (the unit's
    day-0 truth): within 4 reported sigmas plus the in-run bias instability (the true bias of
    a recording is its turn-on value; flicker wanders around it by about B)."""
    _, truth = fleet
    rec, _ = ray_result
    by_path = _truth_recordings(truth)
    model = {"accel": 1.27e-3, "gyro": 2.4e-4}  # bias instability of the model, largest axis
    checked = 0
    for row in _rows(rec):
        if row["error"] is not None:
            continue
        u, r = by_path[row["path"]]
        for t, unit in schema.TRIADS:
            for i, a in enumerate(schema.AXES):
                off = row[schema.offset(t, a)]
                if off is None:
                    continue
                want = r[f"{t}_bias_{unit}"][i] - u["base"][f"{t}_bias_{unit}"][i]
                assert abs(off - want) <= 4 * row[schema.offset_std(t, a)] + 2 * model[t], (
                    row["path"], t, a, off, want)
                assert row[schema.cal_bias(t, a)] == pytest.approx(u["base"][f"{t}_bias_{unit}"][i])
                checked += 1
    assert checked >= 40 * 6


def test_accel_scale_where_the_rests_calibrate_it(ray_result):
    """The units' calibrations in force hold their true scales (the truth at day 0; scales do
    not drift here): where a recording's rests calibrate the accel scale (7 or more, each axis
    up and down), its scale error is 0 within 4 reported sigmas, and no unit's scale is called
    drifting. The gyro scale is never calibrated by rests."""
    rec, units = ray_result
    rows = [r for r in _rows(rec) if r["error"] is None]
    with_scale = [r for r in rows if r[schema.scale("accel", "x")] is not None]
    # Random poses seldom see every axis both ways (8 of the 56 recordings of this seeded
    # fleet); each such recording has the 7 rests the fit needs.
    assert len(with_scale) >= 5, (len(with_scale), len(rows))
    for r in with_scale:
        assert r["still_windows"] >= 7, r
        for a in schema.AXES:
            v, s = r[schema.scale("accel", a)], r[schema.scale_std("accel", a)]
            assert s is not None and 0 < s < float("inf"), (r["path"], a, s)
            assert abs(v) <= 4 * s, (r["path"], a, v, s)
    assert all(r[schema.scale("gyro", a)] is None for r in rows for a in schema.AXES)
    scale_rows = [u for u in _rows(units) if "_scale_" in u["parameter"]]
    assert scale_rows, "the drift test sees the scale columns"
    assert not any(u["drifting"] or u["flagged"] for u in scale_rows), scale_rows


def test_ray_result_equals_local(ray_result, local_result):
    rec, units = ray_result
    a = schema.without_timings(rec)
    b = schema.without_timings(local_result.recordings)
    assert a.equals(b), [c for c in a.column_names if not a[c].equals(b[c])]
    assert units.equals(local_result.units), [
        c for c in units.column_names if not units[c].equals(local_result.units[c])]


def test_cli_writes_the_dataset_and_the_report(on_ray, ray_result):
    rec, units = ray_result
    for name, table in (("recordings", rec), ("units", units)):
        ds = pads.dataset(on_ray / "cli" / name, format="parquet")
        assert [p.name for p in (on_ray / "cli" / name).iterdir()] == ["part-0.parquet"]
        meta = ds.schema.metadata
        assert meta[schema.META_SCHEMA_VERSION.encode()] == schema.SCHEMA_VERSION.encode()
        assert meta[schema.META_IMUD_VERSION.encode()] == imud.__version__.encode()
        got = ds.to_table()
        assert schema.without_timings(got).equals(schema.without_timings(table))
    html = (on_ray / "fleet.html").read_text()
    assert html.lstrip().lower().startswith("<!doctype html")
    flagged = sorted({u for u, f in zip(units.column("unit").to_pylist(),
                                        units.column("flagged").to_pylist()) if f})
    for u in flagged:
        assert u in html
    assert f"to recalibrate: {', '.join(flagged)}" in (on_ray / "cli.stdout").read_text()


def test_the_truncated_recording_stopped_early_and_still_counts(fleet, ray_result):
    _, truth = fleet
    rec, _ = ray_result
    row = _row(rec, truth["truncated"])
    assert row["stopped_early"], row
    assert row["error"] is None and row["still_windows"] > 0


def test_the_motion_only_recording_is_an_error_row_not_a_failure(fleet, ray_result):
    _, truth = fleet
    rec, _ = ray_result
    row = _row(rec, truth["motion_only"])
    assert row["still_windows"] == 0
    assert "no still window" in row["error"]
    assert row["samples"] > 0


def test_lost_samples_are_counted_exactly(fleet, ray_result):
    _, truth = fleet
    rec, _ = ray_result
    by_path = _truth_recordings(truth)
    lossy = 0
    for row in _rows(rec):
        _, r = by_path[row["path"]]
        if r["truncated"] or r["motion_only"]:
            continue
        assert row["missing_samples"] == r["nominal_samples"] - row["samples"], row["path"]
        assert (row["missing_samples"] > 0) == bool(r["dropouts"]), row["path"]
        lossy += bool(r["dropouts"])
    assert lossy >= UNITS


def test_noise_terms_of_the_long_rests_are_the_model_s(ray_result):
    """White-noise density of the longest rest (70 s) against the model's (accel 1.5e-3,
    1.5e-3, 1.8e-3 m/s^2/sqrt(Hz), gyro 1e-3 rad/s/sqrt(Hz)): within 4 of the fit's sigmas
    (the fleet has ~100 such axes), and the sigmas small enough to mean something."""
    rec, _ = ray_result
    density = {"accel": [1.5e-3, 1.5e-3, 1.8e-3], "gyro": [1.0e-3] * 3}
    rows = [r for r in _rows(rec) if r["noise_span_s"] is not None]
    assert len(rows) >= UNITS * 3
    for row in rows:
        assert row["noise_span_s"] >= 60.0
        for t, _ in schema.TRIADS:
            for i, a in enumerate(schema.AXES):
                n = row[schema.noise(t, "white", a)]
                sigma = row[schema.noise_std(t, "white", a)]
                assert sigma < 0.2 * density[t][i], (row["path"], t, a, n, sigma)
                assert abs(n - density[t][i]) < 4 * sigma, (row["path"], t, a, n, sigma)
    short = [r for r in _rows(rec) if r["noise_span_s"] is None and r["error"] is None]
    assert short and all(r[schema.noise("gyro", "white", "x")] is None for r in short)


def test_a_remote_filesystem_recording_is_copied_in_the_task(fleet, local_result):
    """Recordings on a pyarrow filesystem that is not the local one (here a SubTreeFileSystem
    over the fleet's directory) are copied to a temporary file in the task: same rows."""
    from pyarrow import fs as pafs

    d, _ = fleet
    names = sorted(p.name for p in (d / "recordings").iterdir())[:2]
    sub = pafs.SubTreeFileSystem(str(d / "recordings"), pafs.LocalFileSystem())
    got = imud.fleet.analyze(names, engine="local", filesystem=sub, latitude_deg=LATITUDE_DEG)
    local = {r["path"]: r for r in _rows(schema.without_timings(local_result.recordings))}
    for row in _rows(schema.without_timings(got.recordings)):
        want = local[str(d / "recordings" / row["path"])]
        assert {k: v for k, v in row.items() if k != "path"} == {
            k: v for k, v in want.items() if k != "path"}


def test_sessions_are_grouped_and_bad_paths_named(tmp_path):
    for n in ["a-20260101T000000Z-0000.mcap", "a-20260101T010000Z-0001.mcap",
              "a-20260102T000000Z-0000.mcap", "b-20260101T000000Z-0000.mcap", "c.mcap",
              "notes.txt"]:
        (tmp_path / n).write_bytes(b"")
    specs = find_recordings([tmp_path])
    assert [[Path(f).name for f in s.files] for s in specs] == [
        ["a-20260101T000000Z-0000.mcap", "a-20260101T010000Z-0001.mcap"],
        ["a-20260102T000000Z-0000.mcap"],
        ["b-20260101T000000Z-0000.mcap"],
        ["c.mcap"],
    ]
    with pytest.raises(FileNotFoundError, match="nowhere.mcap"):
        find_recordings([tmp_path / "nowhere.mcap"])
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="without recordings"):
        find_recordings([tmp_path / "empty"])
    out = subprocess.run(
        [sys.executable, "-m", "imud.fleet", str(tmp_path / "nowhere.mcap"), "--out",
         str(tmp_path / "r.parquet"), "--engine", "local"],
        capture_output=True, text=True,
    )
    assert out.returncode == 2 and "nowhere.mcap" in out.stderr, out.stderr


def test_an_unreadable_recording_is_an_error_row(tmp_path):
    bad = tmp_path / "junk.mcap"
    bad.write_bytes(b"not an mcap file at all")
    res = imud.fleet.analyze([bad], engine="local")
    (row,) = _rows(res.recordings)
    assert row["path"] == str(bad) and "junk.mcap" in row["error"]
    assert row["samples"] is None


def test_the_drift_test_reads_and_writes_the_schema_s_columns():
    """The drift module names its columns itself; they are schema version 1's."""
    from imud.fleet import drift

    assert drift.UNITS_SCHEMA is schema.UNITS
    names = set(schema.RECORDINGS.names)
    for spec in drift.PARAMETERS:
        assert {spec.value_column, spec.std_column} <= names, spec
        if spec.kind != "scale":
            assert spec.cal_column in names, spec
