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
  allantools_bench_peer.py time_ci DATA.f64 D FACTORS
      times what allantools needs for Greenhall bounds on top of a deviation of phase-difference
      order D (2: the Allan kinds, 3: the Hadamard ones) at FACTORS: `ci.autocorr_noise_id`
      on the phase (its default use; factors it cannot identify, under 30 decimated points,
      raise and are skipped) and `ci.edf_greenhall`, every factor; prints JSON
      {"compute_s": t, "identified": n}. The same work for every kind of that order.
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


def time_ci(path, d, factors):
    import contextlib
    from allantools import ci
    y = np.fromfile(path, dtype="<f8")
    x = np.concatenate(([0.0], np.cumsum(y)))
    ms = np.loadtxt(factors, dtype=int, ndmin=1)
    identified = 0
    t0 = time.perf_counter()
    for m in ms:
        try:
            with contextlib.redirect_stdout(sys.stderr):
                alpha = ci.autocorr_noise_id(x, int(m), data_type="phase", dmin=0, dmax=d)[0]
        except NotImplementedError:
            continue
        identified += 1
        ci.edf_greenhall(alpha=alpha, d=d, m=int(m), N=len(x), overlapping=True, modified=False)
    json.dump({"compute_s": time.perf_counter() - t0, "identified": identified}, sys.stdout)


def main():
    if sys.argv[1] == "generate":
        generate(sys.argv[2], int(sys.argv[3]), int(sys.argv[4]))
    elif sys.argv[1] == "time":
        time_funcs(sys.argv[2], sys.argv[3], sys.argv[4])
    elif sys.argv[1] == "time_ci":
        time_ci(sys.argv[2], int(sys.argv[3]), sys.argv[4])
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main()
