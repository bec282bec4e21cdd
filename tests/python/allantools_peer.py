#!/usr/bin/env python3
"""Peer computation for imu-analysis's Allan deviations: runs allantools on a raw little-endian
f64 rate ("freq") series and prints JSON {"<func>": {"taus": [...], "devs": [...]}, "compute_s": t}.

Usage: allantools_peer.py DATA.f64 RATE_HZ FUNCS TAUS
  FUNCS: comma-separated allantools function names (oadev, mdev, hdev, tdev, ...)
  TAUS:  "octave" or comma-separated taus in seconds
Only the allantools calls are timed (not the load).
"""
import json
import sys
import time

import numpy as np
import allantools


def main():
    path, rate, funcs, taus = sys.argv[1], float(sys.argv[2]), sys.argv[3], sys.argv[4]
    data = np.fromfile(path, dtype="<f8")
    if taus != "octave":
        taus = np.array([float(t) for t in taus.split(",")])
    out = {}
    t0 = time.perf_counter()
    for name in funcs.split(","):
        fn = getattr(allantools, name)
        t, d, _, _ = fn(data, rate=rate, data_type="freq", taus=taus)
        out[name] = {"taus": [float(v) for v in t], "devs": [float(v) for v in d]}
    out["compute_s"] = time.perf_counter() - t0
    out["allantools_version"] = allantools.__version__
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main()
