"""Fingerprints of a problem: proof that two planners solved the identical problem.

Every number is hashed through ``float.hex`` (exact, no rounding), so two fingerprints are
equal only if every coefficient is bit-for-bit the same.
"""

from __future__ import annotations

import hashlib
import json

from iamp.core.problem import Problem


def _hex(x: float) -> str:
    return float(x).hex()


def x_poly_fingerprint(problem: Problem) -> str:
    """SHA-256 of the exact ``x_poly`` coefficients (``float.hex``) of every vehicle."""
    text = json.dumps([[_hex(c) for c in v.x_poly] for v in problem.vehicles])
    return hashlib.sha256(text.encode()).hexdigest()


def problem_fingerprint(problem: Problem) -> str:
    """SHA-256 of every number of the problem (ego, geometry, corners, ``x_poly``, and the
    physical limits when the problem has any)."""
    e = problem.ego
    data = {
        "ego": [_hex(getattr(e, k)) for k in ("tf", "x0", "y0", "vx0", "vy0", "xf", "yf", "vxf", "vyf")],
        "vehicles": [{"corner": v.corner, "x_poly": [_hex(c) for c in v.x_poly],
                      "geom": [_hex(getattr(v, k)) for k in ("y", "length", "width", "safety_x", "safety_y")]}
                     for v in problem.vehicles],
    }
    if problem.limits is not None and not problem.limits.empty:  # SPEC §14 (absent: the unbounded hash unchanged)
        data["limits"] = {k: [_hex(x) for x in v] if isinstance(v, tuple) else _hex(v)
                          for k, v in problem.limits.given().items()}
    return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()
