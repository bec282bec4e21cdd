"""A simulated fleet: ``python -m imud.fleet.simulate OUTDIR --units 8 --recordings 5 --months 6
--drifting 2 --imud PATH_TO_imud``.

Each unit is a 3DM-GX1-class MEMS IMU (the built-in example model,
:func:`imud.example_model_toml`, ``config/models/example-3dm-gx1.toml``: its error model and noise
tables) with biases of its own and a serial number. Its calibration in force is its
truth at day 0, written once (``calibrations/UNIT.toml``) and given to every recording
(``imud --calibration``). Each recording is a few minutes at 100 Hz made by imud's offline
pipeline (``imud --sim SCEN --offline``), dated by the scenario's UTC of time 0 (``[device]
gnss-epoch-utc-s``): a rest, rests in random orientations with moves between them, and in every
other recording one long rest (noise terms); the second and fourth lose replies on the link
(``[[dropout]]``: samples missing, counted by the reader). Its truth model is the unit's with biases =
base + a turn-on jitter (seeded, each power-up) + drift x days for the drifting units: one
with an accelerometer bias drift, one with a gyro bias drift, alternately.

Magnitudes are a real MEMS fleet's: drift 3 mg per month (accel) and 0.05 deg/s per month
(gyro), the high end of what MEMS units show over months; turn-on repeatability 0.3 mg and
0.005 deg/s (a tenth of a month's drift). Messy on purpose: one recording is cut mid-file (a
unit switched off while writing), one is all motion (no still moment).

Layout: ``OUTDIR/recordings/`` (the fleet's recordings, the input of ``python -m imud.fleet``),
``OUTDIR/calibrations/``, ``OUTDIR/truth/`` (scenarios, truth models, the simulator's truth
files) and ``OUTDIR/truth.json``: per unit its serial, the drifting parameter (column stem as in
:mod:`imud.fleet.schema`, e.g. ``accel_bias_x``), its rate per day and base biases, and per
recording its date and true biases.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from datetime import datetime, timezone
from pathlib import Path
from typing import Dict, List, Optional

import numpy as np

from .._imud import example_model_toml, normal_gravity_m_s2

#: 1 mg, m/s^2; 1 deg/s, rad/s; the mean month, days.
MG_M_S2 = 9.80665e-3
DEG_S_RAD_S = np.pi / 180.0
MONTH_DAYS = 30.4375

ACCEL_DRIFT_M_S2_PER_DAY = 3.0 * MG_M_S2 / MONTH_DAYS
GYRO_DRIFT_RAD_S_PER_DAY = 0.05 * DEG_S_RAD_S / MONTH_DAYS
ACCEL_TURN_ON_M_S2 = 0.3 * MG_M_S2
GYRO_TURN_ON_RAD_S = 0.005 * DEG_S_RAD_S
#: Spread of the units' base biases around the model's (units differ by tens of mg, tenths of
#: a deg/s).
ACCEL_UNIT_SPREAD_M_S2 = 20.0 * MG_M_S2
GYRO_UNIT_SPREAD_RAD_S = 0.2 * DEG_S_RAD_S

#: The first recording's date: 2026-01-05T00:00:00Z.
EPOCH_UTC_S = 1_767_571_200.0
FIRST_SERIAL = 3001
RATE_HZ = 100.0
LATITUDE_DEG = 40.0
#: The scenarios' gravity: WGS-84 normal gravity at LATITUDE_DEG on the ellipsoid (what imud's
#: health check and imu-calibrate take at that latitude; the simulator's default is standard
#: gravity, 4.97e-3 m/s^2 more, which would read as a 0.5 mg bias error in every rest).
GRAVITY_M_S2 = normal_gravity_m_s2(LATITUDE_DEG)


def _with_biases(text: str, ident: str, accel: np.ndarray, gyro: np.ndarray) -> str:
    """The model text with its id and accel/gyro bias values replaced."""

    def vec(v: np.ndarray) -> str:
        return "[" + ", ".join(repr(float(x)) for x in v) + "]"

    out, n = re.subn(r'(?m)^id = ".*"$', f'id = "{ident}"', text)
    assert n == 1, "the model has one id line"
    for triad, v in (("accel", accel), ("gyro", gyro)):
        out, n = re.subn(
            rf"(?ms)(^\[{triad}\.bias\]\n(?:#.*\n)*value = )\[[^\]]*\]", rf"\g<1>{vec(v)}", out
        )
        assert n == 1, f"the model has one [{triad}.bias] value"
    return out


def _base(text: str, triad: str) -> np.ndarray:
    m = re.search(rf"(?ms)^\[{triad}\.bias\]\n(?:#.*\n)*value = \[([^\]]*)\]", text)
    assert m is not None
    return np.array([float(x) for x in m[1].split(",")])


#: The scenario of an ordinary recording: a rest, rests in random orientations with moves
#: between them (s), and in every other recording one long rest for the noise terms.
FIRST_REST_S, POSES, DWELL_S, MOVE_S, LONG_REST_S = 10.0, 6, 15.0, 2.0, 70.0


def _duration_s(long_rest: bool) -> float:
    return FIRST_REST_S + POSES * (DWELL_S + MOVE_S) + (LONG_REST_S if long_rest else 0.0)


def _scenario(
    name: str,
    truth: Path,
    serial: int,
    epoch_utc_s: float,
    long_rest: bool,
    motion_only: bool,
    dropouts: List[tuple],
) -> str:
    head = (
        f'name = "{name}"\nrate-hz = {RATE_HZ}\nlatitude-deg = {LATITUDE_DEG}\n'
        f"gravity-m-s2 = {GRAVITY_M_S2}\n"
        f'truth = "{truth}"\n\n[device]\nserial-number = {serial}\n'
        f"gnss-epoch-utc-s = {epoch_utc_s:.1f}\n"
    )
    for at_s, dur_s in dropouts:
        head += f"\n[[dropout]]\nat-s = {at_s}\nduration-s = {dur_s}\n"
    if motion_only:
        # Turns about alternating axes with no rest between them: nothing is still.
        turns = "".join(
            f'\n[[segment]]\nkind = "rotate"\naxis = "{ax}"\nangle-deg = {ang}\n'
            f"duration-s = 4.0\nwobble-deg = 20.0\n"
            for ax, ang in [("x", 90), ("y", 120), ("z", -90), ("x", -150), ("y", 60)] * 3
        )
        return head + turns
    segs = (
        f'\n[[segment]]\nkind = "static"\nduration-s = {FIRST_REST_S}\n'
        f'\n[[segment]]\nkind = "random-poses"\ncount = {POSES}\ndwell-s = {DWELL_S}\n'
        f"move-s = {MOVE_S}\n"
    )
    if long_rest:
        segs += f'\n[[segment]]\nkind = "static"\nduration-s = {LONG_REST_S}\n'
    return head + segs


#: Dropouts (replies lost on the link: at s, for s) of the second and fourth recording of
#: each unit: 50 samples, then 30 and 100.
DROPOUTS = {1: [(30.0, 0.5)], 3: [(40.0, 0.3), (80.0, 1.0)]}


def _run_imud(imud: str, scen: Path, cal: Path, seed: int, name: str, log: Path) -> Path:
    out = subprocess.run(
        [imud, "--sim", str(scen), "--offline", "--calibration", str(cal), "--seed", str(seed),
         "--name", name, "--log-dir", str(log)],
        capture_output=True, text=True,
    )
    if out.returncode != 0:
        raise RuntimeError(f"imud --sim {scen} --offline failed: {out.stderr.strip()}")
    recs = sorted(log.glob(f"{name}-2*.mcap"))
    if len(recs) != 1:
        raise RuntimeError(f"imud wrote {[p.name for p in log.iterdir()]} for {name}")
    return recs[0]


def simulate(
    outdir: os.PathLike,
    *,
    units: int = 8,
    recordings: int = 5,
    months: float = 6.0,
    drifting: int = 2,
    imud: str = "imud",
    seed: int = 1,
    jobs: Optional[int] = None,
    model: Optional[os.PathLike] = None,
    dropouts: bool = True,
) -> dict:
    """Writes the fleet (see the module's doc) and returns ``truth.json``'s document."""
    if units < 1 or recordings < 2 or drifting > units or months <= 0:
        raise ValueError(
            "need units >= 1, recordings >= 2 per unit, drifting <= units, months > 0"
        )
    out = Path(outdir)
    rec_dir, cal_dir, truth_dir = out / "recordings", out / "calibrations", out / "truth"
    for d in (rec_dir, cal_dir, truth_dir):
        d.mkdir(parents=True, exist_ok=True)
    model_text = Path(model).read_text() if model else example_model_toml()
    base_accel, base_gyro = _base(model_text, "accel"), _base(model_text, "gyro")
    rng = np.random.default_rng(seed)
    span_days = months * MONTH_DAYS
    drifting_units = sorted(rng.choice(units, size=drifting, replace=False).tolist())
    jobs_list: List[dict] = []
    doc: Dict[str, dict] = {"units": {}, "epoch_utc_s": EPOCH_UTC_S, "span_days": span_days}
    for u in range(units):
        serial = FIRST_SERIAL + u
        accel0 = base_accel + rng.normal(0.0, ACCEL_UNIT_SPREAD_M_S2, 3)
        gyro0 = base_gyro + rng.normal(0.0, GYRO_UNIT_SPREAD_RAD_S, 3)
        cal_path = cal_dir / f"unit-{serial}.toml"
        cal_path.write_text(_with_biases(model_text, f"unit-{serial}-day0", accel0, gyro0))
        drift = None
        if u in drifting_units:
            k = drifting_units.index(u)
            triad = "accel" if k % 2 == 0 else "gyro"
            axis = int(rng.integers(3))
            rate = ACCEL_DRIFT_M_S2_PER_DAY if triad == "accel" else GYRO_DRIFT_RAD_S_PER_DAY
            drift = (triad, axis, rate * (1 if rng.random() < 0.5 else -1))
        unit = {
            "serial": str(serial),
            "calibration": str(cal_path),
            "drifting": None if drift is None else f"{drift[0]}_bias_{'xyz'[drift[1]]}",
            "rate_per_day": 0.0 if drift is None else drift[2],
            "base": {"accel_bias_m_s2": accel0.tolist(), "gyro_bias_rad_s": gyro0.tolist()},
            "recordings": [],
        }
        for j in range(recordings):
            # Evenly over the span with a few days' jitter, at a working hour.
            day = float(np.clip(span_days * j / (recordings - 1) + rng.uniform(-4, 4), 0, span_days))
            day = np.floor(day) + rng.uniform(8, 18) / 24.0
            accel = accel0 + rng.normal(0.0, ACCEL_TURN_ON_M_S2, 3)
            gyro = gyro0 + rng.normal(0.0, GYRO_TURN_ON_RAD_S, 3)
            if drift is not None:
                (accel if drift[0] == "accel" else gyro)[drift[1]] += drift[2] * day
            jobs_list.append(
                dict(unit=unit, serial=serial, j=j, day=day, accel=accel, gyro=gyro,
                     cal=cal_path, long_rest=j % 2 == 0, motion_only=False,
                     dropouts=DROPOUTS.get(j, []) if dropouts else [])
            )
        doc["units"][str(serial)] = unit
    # The messy ones: an all-motion recording of the first unit that does not drift, mid-span;
    # the middle recording of another steady unit is cut mid-file after it is written.
    steady = [u for u in range(units) if u not in drifting_units]
    motion_unit = steady[0] if steady else 0
    mu = doc["units"][str(FIRST_SERIAL + motion_unit)]
    jobs_list.append(
        dict(unit=mu, serial=FIRST_SERIAL + motion_unit, j=recordings, day=span_days / 2,
             accel=np.array(mu["base"]["accel_bias_m_s2"]),
             gyro=np.array(mu["base"]["gyro_bias_rad_s"]),
             cal=Path(mu["calibration"]), long_rest=False, motion_only=True, dropouts=[])
    )
    cut_unit = steady[1] if len(steady) > 1 else motion_unit
    for k, job in enumerate(jobs_list):
        job["seed"] = seed * 100_000 + k
        job["name"] = f"unit{job['serial']}-r{job['j']:02d}"

    def one(job: dict) -> dict:
        name = job["name"]
        truth = truth_dir / f"{name}-model.toml"
        truth.write_text(_with_biases(model_text, f"{name}-truth", job["accel"], job["gyro"]))
        scen = truth_dir / f"{name}.toml"
        epoch = EPOCH_UTC_S + job["day"] * 86_400.0
        scen.write_text(
            _scenario(name, truth, job["serial"], epoch, job["long_rest"], job["motion_only"],
                      job["dropouts"])
        )
        log = truth_dir / name
        path = _run_imud(imud, scen, job["cal"], job["seed"], name, log)
        dst = rec_dir / path.name
        shutil.move(str(path), dst)
        # The simulator's truth file (the true motion, ~3 MB) is not needed: the truth that
        # matters here (biases per recording) is in truth.json.
        shutil.rmtree(log)
        return {
            "name": name,
            "path": str(dst),
            "day": job["day"],
            "start_utc": datetime.fromtimestamp(epoch, timezone.utc).isoformat(),
            "seed": job["seed"],
            "accel_bias_m_s2": job["accel"].tolist(),
            "gyro_bias_rad_s": job["gyro"].tolist(),
            "motion_only": job["motion_only"],
            "dropouts": [list(d) for d in job["dropouts"]],
            # Samples the simulated unit made (the truth's): a recording without losses has
            # all of them.
            "nominal_samples": None
            if job["motion_only"]
            else int(round(_duration_s(job["long_rest"]) * RATE_HZ)),
            "truncated": False,
        }

    with ThreadPoolExecutor(max_workers=jobs or os.cpu_count() or 1) as pool:
        made = list(pool.map(one, jobs_list))
    for job, rec in zip(jobs_list, made):
        job["unit"]["recordings"].append(rec)
        if rec["motion_only"]:
            doc["motion_only"] = rec["path"]
    cut = doc["units"][str(FIRST_SERIAL + cut_unit)]["recordings"][recordings // 2]
    p = Path(cut["path"])
    with open(p, "r+b") as f:
        f.truncate(int(p.stat().st_size * 0.6))
    cut["truncated"] = True
    doc["truncated"] = cut["path"]
    (out / "truth.json").write_text(json.dumps(doc, indent=1))
    return doc


def main(argv: Optional[List[str]] = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m imud.fleet.simulate",
        description="Simulates a fleet of MEMS IMUs recorded over months (two drifting).",
    )
    p.add_argument("outdir")
    p.add_argument("--units", type=int, default=8)
    p.add_argument("--recordings", type=int, default=5, help="recordings per unit")
    p.add_argument("--months", type=float, default=6.0, help="span of the recordings' dates")
    p.add_argument("--drifting", type=int, default=2, help="units with a drifting bias")
    p.add_argument("--imud", default=shutil.which("imud") or "imud", help="the imud binary")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--jobs", type=int, help="imud processes at once (default: CPUs)")
    p.add_argument("--no-dropouts", action="store_true", help="no lost replies")
    p.add_argument("--model", help="the units' error model (default: the built-in example, "
                   "config/models/example-3dm-gx1.toml)")
    a = p.parse_args(argv)
    doc = simulate(
        a.outdir, units=a.units, recordings=a.recordings, months=a.months, drifting=a.drifting,
        imud=a.imud, seed=a.seed, jobs=a.jobs,
        model=a.model, dropouts=not a.no_dropouts,
    )
    n = sum(len(u["recordings"]) for u in doc["units"].values())
    print(f"{n} recordings of {len(doc['units'])} units in {Path(a.outdir) / 'recordings'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
