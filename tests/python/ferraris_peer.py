#!/usr/bin/env python3
"""An independent implementation of the Ferraris et al. (1995) calibration, numpy only.

F. Ferraris, U. Grimaldi, M. Parvis, "Procedure for effortless in-field calibration of
three-axial rate gyro and accelerometers", Sensors and Materials 7(5), 1995. The sensor output
is modelled as u = S x + b (S: sensitivity and misalignment, b: bias). The unit rests on its
six faces and is turned once through 360 degrees about each of its axes:

  accelerometer: with gravity g up along +j and then -j (faces +j and -j),
      u(+j) = S g e_j + b,  u(-j) = -S g e_j + b
      =>  column j of S_a = (u(+j) - u(-j)) / (2 g),  b_a = mean of the six face outputs;
  gyro bias: the mean of the six faces' rest outputs (Earth's rate, which Ferraris neglects,
      cancels between opposite faces along the vertical and is left in the horizontal);
  gyro: over a full turn about axis j, integral of (u - b_g) dt = S_g (2 pi s e_j), s = +-1
      the turn's sense  =>  column j of S_g = integral / (2 pi s).

The procedure is exactly determined: it fits the faces and the turns perfectly, so it must be
judged on other data (held-out poses, other turns).

Usage: ferraris_peer.py DATA.txt WINDOWS.json
  DATA.txt: whitespace-separated rows `t ax ay az gx gy gz` (s, m/s^2, rad/s), no header.
  WINDOWS.json: {"gravity_m_s2": g, "faces": [[t0, t1], ...], "turns": [[t0, t1], ...]}: the
  times of each rest (any number per face; those with the same face are pooled) and of each
  turn (rest to rest), as the operator of the procedure knows them.
Prints JSON: {"accel": {"s": 3x3, "b": 3}, "gyro": {"s": 3x3, "b": 3}, "faces": ["+x", ...],
"turns": ["+z", ...]}. Exit 77 when numpy is missing (the caller skips or fails).
"""
import json
import sys

try:
    import numpy as np
except ImportError:
    sys.exit(77)


def in_window(t, w):
    return (t >= w[0]) & (t <= w[1])


def face_name(axis, sign):
    return ("+" if sign > 0 else "-") + "xyz"[axis]


def main():
    data = np.loadtxt(sys.argv[1], ndmin=2)
    with open(sys.argv[2]) as f:
        windows = json.load(f)
    g = float(windows["gravity_m_s2"])
    t, acc, gyr = data[:, 0], data[:, 1:4], data[:, 4:7]

    # Faces: pool the rests by the axis gravity is along (the face the unit lies on).
    pooled = {}
    for w in windows["faces"]:
        sel = in_window(t, w)
        a_mean = acc[sel].mean(axis=0)
        axis = int(np.argmax(np.abs(a_mean)))
        key = (axis, 1 if a_mean[axis] > 0 else -1)
        pooled.setdefault(key, [[], []])
        pooled[key][0].append(acc[sel])
        pooled[key][1].append(gyr[sel])
    faces = {k: (np.concatenate(v[0]).mean(axis=0), np.concatenate(v[1]).mean(axis=0))
             for k, v in pooled.items()}
    missing = [face_name(a, s) for a in range(3) for s in (1, -1) if (a, s) not in faces]
    if missing:
        sys.exit("faces missing: " + ", ".join(missing))

    s_a = np.zeros((3, 3))
    for j in range(3):
        s_a[:, j] = (faces[(j, 1)][0] - faces[(j, -1)][0]) / (2.0 * g)
    b_a = np.mean([f[0] for f in faces.values()], axis=0)
    b_g = np.mean([f[1] for f in faces.values()], axis=0)

    s_g = np.zeros((3, 3))
    seen = {}
    for w in windows["turns"]:
        sel = in_window(t, w)
        tt, u = t[sel], gyr[sel] - b_g
        # Trapezoidal integral of the bias-free rate over the turn.
        angle = ((u[1:] + u[:-1]) * 0.5 * np.diff(tt)[:, None]).sum(axis=0)
        axis = int(np.argmax(np.abs(angle)))
        sense = 1.0 if angle[axis] > 0 else -1.0
        if axis in seen:
            sys.exit(f"two turns about {'xyz'[axis]}")
        seen[axis] = face_name(axis, sense)
        s_g[:, axis] = angle / (2.0 * np.pi * sense)
    if len(seen) != 3:
        sys.exit("need one turn about each axis, got " + ", ".join(seen.values()))

    json.dump({
        "accel": {"s": s_a.tolist(), "b": b_a.tolist()},
        "gyro": {"s": s_g.tolist(), "b": b_g.tolist()},
        "faces": sorted(face_name(a, s) for a, s in faces),
        "turns": [seen[a] for a in sorted(seen)],
    }, sys.stdout)


if __name__ == "__main__":
    main()
