"""Comparing documents: every number equal to a relative 1e-12 (and NaN/None alike), every
other value equal, keys compared on what both sides have unless told otherwise."""

import math

RTOL = 1e-12


def assert_close(a, b, path="$", rtol=RTOL):
    """``a`` (from Python) matches ``b`` (the CLI's JSON) everywhere."""
    if isinstance(a, bool) or isinstance(b, bool):
        assert a == b, f"{path}: {a!r} != {b!r}"
    elif isinstance(a, (int, float)) and isinstance(b, (int, float)):
        if math.isnan(a) and math.isnan(b):
            return
        assert abs(a - b) <= rtol * max(abs(a), abs(b), 1e-300), f"{path}: {a!r} != {b!r}"
    elif isinstance(a, dict) and isinstance(b, dict):
        assert set(a) == set(b), f"{path}: keys {sorted(set(a) ^ set(b))} differ"
        for k in a:
            assert_close(a[k], b[k], f"{path}.{k}", rtol)
    elif isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        assert len(a) == len(b), f"{path}: {len(a)} != {len(b)} items"
        for i, (x, y) in enumerate(zip(a, b)):
            assert_close(x, y, f"{path}[{i}]", rtol)
    else:
        assert a == b, f"{path}: {a!r} != {b!r}"
