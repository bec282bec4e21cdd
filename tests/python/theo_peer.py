#!/usr/bin/env python3
"""Peer computation of Theo1, TheoBR and TheoH with their confidence intervals, for imu-stats'
`allan/theo.rs`. Reads a raw little-endian f64 PHASE series (tau0 = 1 / RATE_HZ) and prints JSON
{"ratio": r, "theo1": [pt...], "theoh": [pt...]}, pt = {"m", "tau", "dev", "edf", "lo", "hi"}.

- Theo1: allantools.theo1 at each even m (its direct double loop).
- TheoBR (NIST SP 1065 eq. 31), written here from the publication with numpy: the bias ratio is
  the mean over i = 0..n, n = floor(0.1 N / 3 - 3), of AVAR(9 + 3i) (allantools.oadev) over
  Theo1(12 + 4i); Theo1 here is built from the u-lag phase differences D_u(j) = x[j+u] - x[j]:
  sum over u = 1..m/2 of (1/u) sum_i (D_u(i + m - u) - D_u(i))^2 (SP 1065 eq. 30 with
  u = m/2 - delta), a different arrangement of the sum than both allantools and the Rust code.
- TheoH (SP 1065 section 5.2.15): for averaging times F tau0 from the FACTORS list, k = the
  largest F <= (N - 1) / 10; OADEV at F < k, TheoBR at the even m nearest 4F/3 for F >= k
  (10 <= m <= N - 1).
- EDF for noise exponent ALPHA: Theo1/TheoBR points by SP 1065 section 5.5.6 (Table 12, r = 0.75 m,
  at least 1), OADEV points by allantools' ci.edf_greenhall; bounds by allantools'
  ci.confidence_interval at CONFIDENCE.

Usage: theo_peer.py PHASE.f64 RATE_HZ THEO1_MS FACTORS ALPHA CONFIDENCE
  THEO1_MS: comma-separated even Theo1 factors m; FACTORS: comma-separated averaging factors F.
"""
import contextlib
import json
import math
import sys

import numpy as np
import allantools
from allantools import ci


def theo1_var_lags(x, m):
    """Theo1 variance (tau0 = 1) from lag differences, as described above."""
    n = len(x)
    length = n - m
    total = 0.0
    for u in range(1, m // 2 + 1):
        d = x[u:] - x[:-u]
        e = d[m - u : m - u + length] - d[:length]
        total += float(np.dot(e, e)) / u
    return total / (0.75 * length * m * m)


def oavar(x, m):
    with contextlib.redirect_stdout(sys.stderr):
        _, dev, _, _ = allantools.oadev(x, rate=1.0, data_type="phase", taus=[float(m)])
    return float(dev[0]) ** 2


def br_ratio(x):
    n_br = math.floor(0.1 * len(x) / 3.0 - 3.0)
    vals = [oavar(x, 9 + 3 * i) / theo1_var_lags(x, 12 + 4 * i) for i in range(n_br + 1)]
    return sum(vals) / len(vals)


def edf_theo1(alpha, m, n):
    r = 0.75 * m
    if alpha >= 2:
        e = (0.86 * (n + 1) * (n - 4 * r / 3) / (n - r)) * (r / (r + 1.14))
    elif alpha == 1:
        e = (4.798 * n**2 - 6.374 * n * r + 12.387 * r) / (math.sqrt(r + 36.6) * (n - r))
        e *= r / (r + 0.3)
    elif alpha == 0:
        e = ((4.1 * n + 0.8) / r - (3.1 * n + 6.5) / n) * (r**1.5 / (r**1.5 + 5.2))
    elif alpha == -1:
        e = ((2 * n**2 - 1.3 * n * r - 3.5 * r) / (n * r)) * (r**3 / (r**3 + 2.3))
    else:
        e = ((4.4 * n - 2) / (2.9 * r)) * (
            ((4.4 * n - 1) ** 2 - 8.6 * r * (4.4 * n - 1) + 11.4 * r**2) / (4.4 * n - 3) ** 2
        )
    return max(e, 1.0)


def point(m, tau, var, edf, conf):
    dev = math.sqrt(max(var, 0.0))
    lo, hi = ci.confidence_interval(dev, edf, ci=conf)
    return {"m": m, "tau": tau, "dev": dev, "edf": edf, "lo": float(lo), "hi": float(hi)}


def main():
    path, rate, theo1_ms, factors, alpha, conf = sys.argv[1:7]
    x = np.fromfile(path, dtype="<f8")
    tau0 = 1.0 / float(rate)
    alpha, conf = int(alpha), float(conf)
    n = len(x)
    out = {"theo1": [], "theoh": []}
    for m in [int(v) for v in theo1_ms.split(",") if v]:
        with contextlib.redirect_stdout(sys.stderr):
            _, dev, _, _ = allantools.theo1(x, rate=float(rate), data_type="phase", taus=[m * tau0])
        var = float(dev[0]) ** 2
        out["theo1"].append(point(m, 0.75 * m * tau0, var, edf_theo1(alpha, m, n), conf))
    ratio = br_ratio(x)
    out["ratio"] = ratio
    fs = [int(v) for v in factors.split(",") if v]
    k = max([f for f in fs if f <= (n - 1) / 10], default=1)
    seen = set()
    for f in fs:
        if f < k:
            var = oavar(x, f) / tau0**2
            edf = ci.edf_greenhall(alpha=alpha, d=2, m=f, N=n, overlapping=True, modified=False)
            out["theoh"].append(point(f, f * tau0, var, float(edf), conf))
            continue
        m = 2 * round(2 * f / 3)
        if m < 10 or m > n - 1 or m in seen:
            continue
        seen.add(m)
        var = ratio * theo1_var_lags(x, m) / tau0**2
        out["theoh"].append(point(m, 0.75 * m * tau0, var, edf_theo1(alpha, m, n), conf))
    print(json.dumps(out))


if __name__ == "__main__":
    main()
