#!/usr/bin/env python3
"""Peer computation of the Allan-family confidence intervals: runs allantools on a raw
little-endian f64 PHASE series (tau0 = 1 / RATE_HZ) and prints JSON
{"<kind>": [{"m": m, "dev": d, "alpha": a, "edf": e, "lo": l, "hi": h}, ...], ...}.

The noise type per averaging factor m follows Stable32's rule (imu-stats `allan/noise_id.rs`),
built from allantools' `ci` functions:
- the phase decimated by m has at least 30 points: `ci.autocorr_noise_id` on the frequency
  (`data_type="freq"`: m-averages, linear drift removed, at most d - 1 differences); with exactly
  29 averages (allantools refuses fewer than 30) the same steps from `ci.detrend` and
  `ci.lag1_acf`;
- fewer, for the non-overlapping adev and hdev, with at least 10 averages: the B1 ratio
  `ci.b1` against `ci.b1_theory` (boundaries at the geometric means), and for phase noise R(n)
  `ci.rn` against `ci.rn_boundary`;
- otherwise the type of the nearest identified factor (the shorter one on a tie).
EDF: `edf_greenhall` (`edf_totdev` for totdev); bounds: `confidence_interval` at CONFIDENCE.

Usage: allantools_ci_peer.py PHASE.f64 RATE_HZ KINDS FACTORS CONFIDENCE
  KINDS:   comma-separated (adev, oadev, mdev, hdev, ohdev, tdev, totdev)
  FACTORS: comma-separated averaging factors m
"""
import contextlib
import json
import sys

import numpy as np
import allantools
from allantools import ci

SHAPE = {  # kind: (d, overlapping, modified)
    "adev": (2, False, False),
    "oadev": (2, True, False),
    "mdev": (2, True, True),
    "tdev": (2, True, True),
    "hdev": (3, False, False),
    "ohdev": (3, True, False),
    "totdev": (2, None, None),
}
B1_MIN_POINTS = 10


def lag1_id(x, y, m, d):
    n = (len(x) - 1) // m
    if n + 1 < 30:
        return None
    if n >= 30:
        with contextlib.redirect_stdout(sys.stderr):
            return int(ci.autocorr_noise_id(y, m, data_type="freq", dmin=0, dmax=d - 1)[0])
    z = ci.detrend(y[: n * m].reshape(n, m).mean(axis=1), deg=1)
    k = 0
    while True:
        r1 = ci.lag1_acf(z)
        rho = r1 / (1.0 + r1)
        if rho < 0.25 or k >= d - 1:
            return int(-np.round(2 * rho) - 2 * k)
        z = np.diff(z)
        k += 1


def b1_id(x, m, d):
    n = (len(x) - 1) // m
    if n < B1_MIN_POINTS:
        return None
    ratio = ci.b1(x, m, 1.0)
    mu = -2
    while mu < d and ratio > np.sqrt(ci.b1_theory(n, mu) * ci.b1_theory(n, mu + 1)):
        mu += 1
    if mu > -2:
        return -mu - 1
    return 1 if ci.rn(x, m, 1.0) > ci.rn_boundary(m, 0) else 2


def noise_ids(x, y, ms, kind, cache):
    d = SHAPE[kind][0]
    ids = []
    for m in ms:
        key = ("lag1", m, d)
        if key not in cache:
            cache[key] = lag1_id(x, y, m, d)
        a = cache[key]
        if a is None and kind in ("adev", "hdev"):
            key = ("b1", m, d)
            if key not in cache:
                cache[key] = b1_id(x, m, d)
            a = cache[key]
        ids.append(a)
    lowest = 2 - 2 * d
    out = []
    for i in range(len(ms)):
        known = [(abs(i - j), j > i, a) for j, a in enumerate(ids) if a is not None]
        a = min(known)[2] if known else 0
        out.append(int(min(max(a, lowest), 2)))
    return out


def main():
    path, rate, kinds, factors, conf = sys.argv[1:6]
    rate, conf = float(rate), float(conf)
    x = np.fromfile(path, dtype="<f8")
    y = np.diff(x)
    ms = [int(m) for m in factors.split(",")]
    out = {"allantools_version": allantools.__version__}
    cache = {}
    for kind in kinds.split(","):
        d, overlapping, modified = SHAPE[kind]
        taus = [m / rate for m in ms]
        t, devs, _, _ = getattr(allantools, kind)(x, rate=rate, data_type="phase", taus=taus)
        got = [int(round(v * rate)) for v in t]
        rows = []
        for m, dev, alpha in zip(got, devs, noise_ids(x, y, got, kind, cache)):
            if kind == "totdev":
                edf = ci.edf_totdev(len(x), m, alpha)
            else:
                edf = ci.edf_greenhall(alpha, d, m, len(x), overlapping, modified)
            lo, hi = ci.confidence_interval(dev, edf, conf)
            rows.append({"m": m, "dev": float(dev), "alpha": alpha, "edf": float(edf),
                         "lo": float(lo), "hi": float(hi)})
        out[kind] = rows
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main()
