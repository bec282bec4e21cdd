#!/usr/bin/env python3
"""Peer of the imu-stats `noise_vs_allantools` bench (issue 17 item 8).

  allantools_bench_peer.py generate OUT.f64 N SEED
      writes N samples of a rate series (white noise 1e-3/sqrt(Hz) plus a random walk K 1e-5,
      1 Hz, numpy's PCG64 seeded with SEED) as raw little-endian f64.
  allantools_bench_peer.py time DATA.f64 FUNCS FACTORS
      times allantools' FUNCS (comma-separated: oadev, mdev, ...) on the series at the
      averaging factors in FACTORS (a text file, one integer per line; tau = m seconds), each
      call on its own, and prints JSON {"<func>": {"taus": [...], "devs": [...], "compute_s": t},
      "allantools_version": v}. Only the calls are timed, not the load.
"""
import json
import sys
import time

import numpy as np
import allantools


def generate(out, n, seed):
    rng = np.random.default_rng(seed)
    y = 1e-3 * rng.standard_normal(n) + np.cumsum(1e-5 * rng.standard_normal(n))
    y.astype("<f8").tofile(out)


def time_funcs(path, funcs, factors):
    data = np.fromfile(path, dtype="<f8")
    taus = np.loadtxt(factors, dtype=float, ndmin=1)
    out = {"allantools_version": allantools.__version__}
    for name in funcs.split(","):
        fn = getattr(allantools, name)
        t0 = time.perf_counter()
        t, d, _, _ = fn(data, rate=1.0, data_type="freq", taus=taus)
        out[name] = {
            "compute_s": time.perf_counter() - t0,
            "taus": [float(v) for v in t],
            "devs": [float(v) for v in d],
        }
    json.dump(out, sys.stdout)


def main():
    if sys.argv[1] == "generate":
        generate(sys.argv[2], int(sys.argv[3]), int(sys.argv[4]))
    elif sys.argv[1] == "time":
        time_funcs(sys.argv[2], sys.argv[3], sys.argv[4])
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main()
