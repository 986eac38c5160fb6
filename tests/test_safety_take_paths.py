"""Issue 32: the safety report's helpers with fewer numpy calls, the same numbers bit for bit.

* :class:`~iamp.core.hold_trajectory.HoldTrajectory`'s ``states`` and ``inputs`` (one ``take`` of
  per-piece rows instead of indexing three arrays) are the former implementation's, byte for byte
  (signed zeros too), FOH and ZOH, scalar and array times, times outside the grid;
* :func:`~iamp.core.trajectory_pieces.taylor_pieces` (column slices for lists of columns) and
  :func:`~iamp.core.trajectory_pieces.breakpoints` (one sort for ``numpy.unique``) are the former
  ones, byte for byte;
* ``_CutPolynomials``'s rows (one concatenation for ``numpy.stack``, ``take`` for lists of indices) and
  :func:`~iamp.core.polyroots.roots_in_unit_interval` (``nonzero`` for ``numpy.flatnonzero``, one
  ``take`` of the rows, the companion matrices' ones set below the diagonal) are the former ones.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as hst

from iamp.core import intrusion
from iamp.core import polyroots as pr
from iamp.core.hold_trajectory import HoldTrajectory
from iamp.core.polyroots import pad_coeffs, poly_deriv, poly_mul
from iamp.core.problem import SurroundingVehicle
from iamp.core.trajectory_pieces import MERGE_S, breakpoints, shifted_poly, taylor_pieces


class _FormerHold:
    """``HoldTrajectory.states``/``inputs`` as they were (indexing ``X``, ``G1``, ``G2`` with ``k``)."""

    def __init__(self, tr: HoldTrajectory) -> None:
        self.t_nodes, self.X, self.U, self.hold = tr.t_nodes, tr.X, tr.U, tr.hold

    def _locate(self, t: Any) -> tuple[np.ndarray, np.ndarray]:
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        nodes = np.asarray(self.t_nodes, dtype=float)
        k = np.searchsorted(nodes[1:-1], tt, side="right").astype(np.int64, copy=False)
        return k, tt - nodes[k]

    def inputs(self, t: Any) -> np.ndarray:
        k, dt = self._locate(t)
        if self.hold == "zoh":
            return np.asarray(self.U[k], dtype=float)
        nodes = np.asarray(self.t_nodes, dtype=float)
        h = nodes[k + 1] - nodes[k]
        u0 = self.U[k]
        return np.asarray(u0 + (self.U[k + 1] - u0) * (dt / h)[:, None], dtype=float)

    def states(self, t: Any) -> np.ndarray:
        k, dt = self._locate(t)
        nodes = np.asarray(self.t_nodes, dtype=float)
        n = nodes.size - 1
        U = self.U
        G1 = np.empty((n, 4), dtype=np.result_type(self.X, U))
        G1[:, 0::2] = self.X[:n, 1::2]
        G1[:, 1::2] = U[:n]
        if self.hold == "zoh":
            G2 = np.asarray(U[:n])
        else:
            G2 = np.empty((n, 4), dtype=G1.dtype)
            G2[:, 0::2] = U[:n]
            G2[:, 1::2] = (U[1:n + 1] - U[:n]) / (nodes[1:] - nodes[:-1])[:, None]
        d = dt[:, None]
        d2 = d**2
        out = self.X[k] + G1[k] * d
        if self.hold == "zoh":
            out[:, 0::2] += G2[k] * d2 / 2
        else:
            g2 = G2[k]
            out += g2 * d2 / 2
            out[:, 0::2] += g2[:, 1::2] * d**3 / 6
        return out


def _former_taylor_pieces(traj: Any, breaks: np.ndarray) -> tuple[np.ndarray, float]:
    a, b = breaks[:-1], breaks[1:]
    h = b - a
    P = a.size
    Xab = traj.states(np.concatenate((a, b)))
    Xa, Xb = Xab[:P], Xab[P:]
    Uam = traj.inputs(np.concatenate((a, 0.5 * (a + b))))
    Ua, Um = Uam[:P], Uam[P:]
    jerk = (Um - Ua) / (0.5 * h)[:, None]
    C = np.empty((a.size, 2, 4))
    hh = h[:, None]
    C[:, :, 0] = Xa[:, [0, 2]]
    C[:, :, 1] = Xa[:, [1, 3]] * hh
    C[:, :, 2] = Ua * hh**2 / 2
    C[:, :, 3] = jerk * hh**3 / 6
    s_end = C.sum(axis=2)
    v_end = (C[:, :, 1] + 2 * C[:, :, 2] + 3 * C[:, :, 3]) / hh
    scale = max(1.0, float(np.max(np.abs(Xb))))
    mismatch = max(float(np.max(np.abs(s_end - Xb[:, [0, 2]]))), float(np.max(np.abs(v_end - Xb[:, [1, 3]]))))
    return C, mismatch / scale


def _former_breakpoints(nodes: np.ndarray, tf: float) -> np.ndarray:
    b = np.unique(np.concatenate(([0.0], np.asarray(nodes, dtype=float).ravel(), [float(tf)])))
    b = b[(b >= 0) & (b <= tf)]
    keep = np.concatenate(([True], np.diff(b) > MERGE_S))
    b = b[keep]
    b[-1] = tf
    return b


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def _hold(seed: int, hold: str, n: int, zeros: bool) -> HoldTrajectory:
    rng = np.random.default_rng(seed)
    nodes = np.r_[0.0, np.cumsum(rng.uniform(1e-3, 1.0, size=n))]
    X = rng.normal(size=(n + 1, 4)) * 10.0
    U = rng.normal(size=(n + 1 if hold == "foh" else n, 2))
    if zeros:  # signed zeros in the nodal states and inputs
        X[rng.random(X.shape) < 0.3] = -0.0
        U[rng.random(U.shape) < 0.3] = -0.0
    return HoldTrajectory(nodes, X, U, hold)


@settings(max_examples=120, deadline=None)
@given(seed=hst.integers(0, 2**31 - 1), hold=hst.sampled_from(["foh", "zoh"]), n=hst.integers(1, 30),
       zeros=hst.booleans())
def test_states_and_inputs_are_the_former_ones(seed: int, hold: str, n: int, zeros: bool) -> None:
    tr = _hold(seed, hold, n, zeros)
    old = _FormerHold(tr)
    rng = np.random.default_rng(seed + 1)
    nodes = tr.t_nodes
    t = np.r_[rng.uniform(-0.5, nodes[-1] + 0.5, size=40), nodes, -0.0, 0.5 * (nodes[:-1] + nodes[1:])]
    for times in (t, float(t[0]), t[:0], list(t[:3])):
        assert _same(tr.states(times), old.states(times))
        assert _same(tr.inputs(times), old.inputs(times))
    assert _same(tr.states(t), old.states(t))  # the kept rows again


@settings(max_examples=80, deadline=None)
@given(seed=hst.integers(0, 2**31 - 1), hold=hst.sampled_from(["foh", "zoh"]), n=hst.integers(1, 30),
       zeros=hst.booleans(), dup=hst.booleans())
def test_taylor_pieces_and_breakpoints_are_the_former_ones(seed: int, hold: str, n: int, zeros: bool,
                                                           dup: bool) -> None:
    tr = _hold(seed, hold, n, zeros)
    tf = float(tr.t_nodes[-1])
    nodes = tr.t_nodes
    if dup:  # duplicates, near-duplicates, signed zeros, times outside [0, tf], a NaN
        rng = np.random.default_rng(seed)
        extra = rng.choice(nodes, size=5) + rng.choice([0.0, 1e-10, -1e-10, 2e-9], size=5)
        nodes = np.r_[nodes, extra, -0.0, -1.0, tf + 1.0, np.nan]
        np.random.default_rng(seed).shuffle(nodes)

    class _Nodes:
        t_nodes = nodes

    got, want = breakpoints(_Nodes(), tf), _former_breakpoints(nodes, tf)
    assert got is not None and _same(got, want)
    C, m = taylor_pieces(tr, got)
    C0, m0 = _former_taylor_pieces(_FormerHold(tr), want)
    assert _same(C, C0) and _same(np.float64(m), np.float64(m0))


class _FormerCutPolynomials:
    """Vehicle ``v``'s polynomials whose roots are cut points: groups of ``P`` rows (one per piece)."""

    def __init__(self, v: Any, breaks: np.ndarray, C: np.ndarray, Le: float, We: float) -> None:
        a, h = breaks[:-1], np.diff(breaks)
        degree = max(3, len(v.x_poly) - 1)
        xs = shifted_poly(v.x_poly, a, h, degree)
        dX = pad_coeffs(C[:, 0, :], degree + 1) - xs
        dY = pad_coeffs(C[:, 1, :], degree + 1)
        dY[:, 0] -= v.y
        Ax, Ay = v.length / 2 + v.safety_x, v.width / 2 + v.safety_y
        Bx, By = (Le + v.length) / 2, (We + v.width) / 2
        d = intrusion.INTRUSION_TOL_M
        self.v, self.Ax, self.Ay, self.Bx, self.By = v, Ax, Ay, Bx, By
        self.n2 = n2 = 2 * degree + 1

        ddX, ddY = poly_deriv(dX), poly_deriv(dY)
        # per group of P rows, in order: its polynomial (dX, dY, dX', dY' or one of the eight
        # below) and the constant subtracted from its σ⁰ coefficient
        base: list[int] = []
        const: list[float] = []
        self.with_intrusion = Ax > d and Ay > d
        if self.with_intrusion:  # intrusion: |dx| < Ax − δ and |dy| < Ay − δ
            base += [0, 0, 1, 1]
            const += [Ax - d, -(Ax - d), Ay - d, -(Ay - d)]
        self.first_overlap = len(base)  # overlap of the bodies: |dx| < Bx and |dy| < By
        base += [0, 0, 1, 1]
        const += [Bx, -Bx, By, -By]
        self.first_extreme = len(base)  # extremes: candidates where depth / distance can attain a max / min
        base += [0, 1, 2, 3, 0, 0, 1, 1]
        const += [0.0, 0.0, 0.0, 0.0, Ax, -Ax, Ay, -Ay]
        # the products (dx − sx Ax) dx' and (dy − sy Ay) dy', each computed once (one row-wise
        # product of the four stacked: each row's numbers are those of its own product)
        P, D = dX.shape
        # dx − Ax, dx + Ax, dy − Ay, dy + Ay stacked: each copy's σ⁰ coefficient less its constant
        # (one subtraction per number, as one copy at a time)
        shifted = np.stack((dX, dX, dY, dY))
        shifted[:, :, 0] -= np.array([[Ax], [-Ax], [Ay], [-Ay]])
        prods = poly_mul(shifted.reshape(4 * P, D), np.stack((ddX, ddX, ddY, ddY)).reshape(4 * P, D - 1))
        prods = prods.reshape(4, P, -1)
        # per sign pair (sx, sy) = (1, 1), (1, −1), (−1, 1), (−1, −1): the depth crossing
        # Ax − sx dx = Ay − sy dy and the stationary points of (dx − sx Ax)² + (dy − sy Ay)²
        cross = intrusion._SY * dY - intrusion._SX * dX
        stationary = prods[[0, 0, 1, 1]] + prods[[2, 3, 2, 3]]
        # the polynomials, zero-padded to n2 columns: dX, dY, dX', dY', then per sign pair its
        # crossing and its stationary points
        padded = np.zeros((12, P, n2))
        padded[0, :, :D], padded[1, :, :D] = dX, dY
        padded[2, :, :D - 1], padded[3, :, :D - 1] = ddX, ddY
        padded[4::2, :, :D] = cross
        padded[5::2, :, :stationary.shape[2]] = stationary
        base += [4, 5, 6, 7, 8, 9, 10, 11]
        const += [Ay - Ax, 0.0] * 4
        self.n_groups = len(base)
        # every group's polynomial written into its rows, then its constant subtracted
        # (subtracting 0.0 changes no bit)
        rows = padded[base]
        rows[:, :, 0] -= np.asarray(const)[:, None]
        self.rows = rows.reshape(self.n_groups * P, n2)


def _former_roots(C: np.ndarray, imag_tol: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """``roots_in_unit_interval`` as it was (``numpy.flatnonzero``, ``C[idx, d]``, ``numpy.eye``)."""
    C = np.ascontiguousarray(C, dtype=float)
    K, D1 = C.shape
    if K == 0 or D1 < 2:
        return np.zeros(0, dtype=np.intp), np.zeros(0)
    deg = pr._degrees(C, imag_tol, pr._SKIP_FAR)
    sent = np.flatnonzero(deg)
    if sent.size == 0:
        return np.zeros(0, dtype=np.intp), np.zeros(0)
    rows_in: list[np.ndarray] = []
    eig: list[np.ndarray] = []
    dsent = deg[sent]
    for d in np.flatnonzero(np.bincount(dsent)).tolist():  # the degrees present, ascending (numpy.unique's)
        idx = sent[dsent == d]
        lead = C[idx, d]
        if d == 1:
            r = (-C[idx, 0] / lead)[:, None].astype(complex)
        else:
            comp = np.zeros((idx.size, d, d))
            comp[:, 1:, :-1] = np.eye(d - 1)
            comp[:, :, -1] = -C[idx, :d] / lead[:, None]
            r = pr._eigvals(comp)
        rows_in.append(np.repeat(idx, d))
        eig.append(r.ravel())
    rr = np.concatenate(rows_in).astype(np.int64)
    z = np.concatenate(eig)
    with np.errstate(invalid="ignore"):  # NaN coefficients (kept, as numpy's eigenvalues give them)
        rows, x = pr.kernel("polish_roots")(C, rr, np.ascontiguousarray(z.real), np.ascontiguousarray(z.imag),
                                         float(imag_tol))
    return rows.astype(np.intp), x


@settings(max_examples=60, deadline=None)
@given(seed=hst.integers(0, 2**31 - 1), n=hst.integers(1, 20), ncoef=hst.integers(1, 6), zeros=hst.booleans())
def test_cut_polynomials_and_their_roots_are_the_former_ones(seed: int, n: int, ncoef: int, zeros: bool) -> None:
    """The rows of ``_CutPolynomials`` (one concatenation for ``numpy.stack``, ``take`` for lists of
    indices) and ``roots_in_unit_interval`` (``nonzero``, ``take``, the ones set below the diagonal) give
    the former arrays byte for byte."""
    rng = np.random.default_rng(seed)
    breaks = np.r_[0.0, np.cumsum(rng.uniform(1e-3, 1.0, size=n))]
    C = rng.normal(size=(n, 2, 4)) * 10.0 ** rng.uniform(-3, 2, size=(n, 2, 4))
    if zeros:
        C[rng.random(C.shape) < 0.3] = -0.0
    x_poly = tuple(rng.normal(size=ncoef) * 10.0 ** rng.uniform(-3, 1, size=ncoef))
    v = SurroundingVehicle(x_poly=x_poly, y=float(rng.normal()), length=float(rng.uniform(3, 6)),
                           width=float(rng.uniform(1.5, 2.5)), safety_x=float(rng.uniform(0, 10)),
                           safety_y=float(rng.uniform(0, 1)), corner="front-lower")
    got = intrusion._CutPolynomials(v, breaks, C, 4.8, 1.8).rows
    want = _FormerCutPolynomials(v, breaks, C, 4.8, 1.8).rows
    assert _same(got, want)
    for M in (got, rng.normal(size=(30, int(rng.integers(2, 8)))) * 10.0 ** rng.uniform(-3, 3, size=(30, 1))):
        r, x = pr.roots_in_unit_interval(M)
        r0, x0 = _former_roots(M)
        assert _same(r, r0) and _same(x, x0)
