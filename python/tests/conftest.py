"""Fixtures of the imud Python tests: the built command-line tools (the peers every function is
compared with) and recordings of the shipped scenarios made with them in a temporary directory.

The tools come from ``$IMUD_BIN_DIR`` (default: the workspace's ``target/debug``). Without them
the comparisons are skipped with the reason shown; with ``IMUD_REQUIRE_PEERS=1`` (CI,
``scripts/test``) that is a failure instead.
"""

import json
import os
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SCENARIOS = REPO / "config" / "scenarios"
TOOLS = ("imud", "imu-noise", "imu-calibrate", "imu-diagnose", "imu-analyze")


def _missing(reason):
    if os.environ.get("IMUD_REQUIRE_PEERS") == "1":
        pytest.fail(f"{reason} (IMUD_REQUIRE_PEERS=1)")
    pytest.skip(reason)


@pytest.fixture(scope="session")
def bins():
    """Directory of the built tools."""
    d = Path(os.environ.get("IMUD_BIN_DIR", REPO / "target" / "debug"))
    absent = [t for t in TOOLS if not (d / t).is_file()]
    if absent:
        _missing(f"the command-line tools {absent} are not built in {d} (cargo build --bins)")
    return d


@pytest.fixture(scope="session")
def cli(bins):
    """Runs a tool with ``--json`` and returns the parsed document."""

    def run(tool, *args):
        out = subprocess.run(
            [str(bins / tool), *map(str, args), "--json"], capture_output=True, text=True
        )
        assert out.returncode == 0, f"{tool} {args}: {out.stderr}"
        return json.loads(out.stdout)

    return run


def record(bins, tmp, scenario, seed, name=None):
    """Records a scenario through imud's offline pipeline: (recording, truth MCAP)."""
    name = name or Path(scenario).stem
    log = tmp / name
    out = subprocess.run(
        [str(bins / "imud"), "--sim", str(scenario), "--offline", "--seed", str(seed),
         "--name", name, "--log-dir", str(log)],
        capture_output=True, text=True,
    )
    assert out.returncode == 0, out.stderr
    recs = sorted(p for p in log.glob(f"{name}-2*.mcap"))
    assert len(recs) == 1, list(log.iterdir())
    truth = log / f"{name}-truth.mcap"
    assert truth.is_file(), list(log.iterdir())
    return recs[0], truth


@pytest.fixture(scope="session")
def index_table(bins, tmp_path_factory):
    """The shipped 12-position index-table scenario: (recording, truth)."""
    return record(bins, tmp_path_factory.mktemp("index"), SCENARIOS / "index-table-12pos.toml", 11)


@pytest.fixture(scope="session")
def workbench_demo(bins, tmp_path_factory):
    """The shipped workbench scenario (a hidden gyro g-sensitivity): (recording, truth)."""
    return record(bins, tmp_path_factory.mktemp("wb"), SCENARIOS / "workbench-demo.toml", 5)


@pytest.fixture(scope="session")
def multi_pose(bins, tmp_path_factory):
    """The shipped reference-free scenario (36 hand-held poses): (recording, truth)."""
    return record(bins, tmp_path_factory.mktemp("poses"), SCENARIOS / "multi-pose.toml", 3)


@pytest.fixture(scope="session")
def static_run(bins, tmp_path_factory):
    """The shipped static scenario (static-6h), shortened to 15 min so the suite stays quick:
    the same sensor, orientation and noise model. (recording, truth)."""
    tmp = tmp_path_factory.mktemp("static")
    text = (SCENARIOS / "static-6h.toml").read_text()
    assert "duration-s = 21600.0" in text
    text = text.replace("duration-s = 21600.0", "duration-s = 900.0").replace(
        '"../models/', f'"{SCENARIOS.parent / "models"}/'
    )
    scenario = tmp / "static-15min.toml"
    scenario.write_text(text)
    return record(bins, tmp, scenario, 7, name="static")
