#!/usr/bin/env python3
"""Peer computation of the Allan-family confidence intervals: runs allantools on a raw
little-endian f64 PHASE series (tau0 = 1 / RATE_HZ) and prints JSON
{"<kind>": [{"m": m, "dev": d, "alpha": a, "edf": e, "lo": l, "hi": h}, ...], ...}.
The noise type is allantools' `autocorr_noise_id` (lag-1 autocorrelation of the decimated
phase); where it cannot identify (fewer than 30 decimated points) the nearest identified
averaging factor's type is used. EDF: `edf_greenhall` (`edf_totdev` for totdev); bounds:
`confidence_interval` at CONFIDENCE.

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


def noise_ids(x, ms, dmax):
    ids = []
    for m in ms:
        try:
            # allantools prints its "cannot identify" note on stdout, which carries the JSON.
            with contextlib.redirect_stdout(sys.stderr):
                ids.append(ci.autocorr_noise_id(x, m, data_type="phase", dmin=0, dmax=dmax)[0])
        except NotImplementedError:
            ids.append(None)
    out = []
    for i in range(len(ms)):
        known = [(abs(i - j), a) for j, a in enumerate(ids) if a is not None]
        a = min(known)[1] if known else 0
        out.append(int(min(max(a, 2 - 2 * dmax), 2)))
    return out


def main():
    path, rate, kinds, factors, conf = sys.argv[1:6]
    rate, conf = float(rate), float(conf)
    x = np.fromfile(path, dtype="<f8")
    ms = [int(m) for m in factors.split(",")]
    out = {"allantools_version": allantools.__version__}
    for kind in kinds.split(","):
        d, overlapping, modified = SHAPE[kind]
        taus = [m / rate for m in ms]
        t, devs, _, _ = getattr(allantools, kind)(x, rate=rate, data_type="phase", taus=taus)
        got = [int(round(v * rate)) for v in t]
        rows = []
        for m, dev, alpha in zip(got, devs, noise_ids(x, got, d)):
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
