"""Polynomial path functions: fibre length as a polynomial of the coordinates a muscle spans.

OpenSim 4.5+ can give a muscle a ``FunctionBasedPath`` whose length is a
``MultivariatePolynomialFunction`` of some coordinates; its moment arm about coordinate c is then
``-dL/dq_c`` of that polynomial. OpenSim's own ``PolynomialPathFitter`` fits such functions to
GeometryPath lengths over sampled poses. This module does the same for fibre lengths, with our
own sampling and least-squares fit (nothing of OpenSim's implementation is used).

Term order (OpenSim's ``MultivariatePolynomialFunction``: "ascending powers starting from the
last independent component"; checked against ``opensim.MultivariatePolynomialFunction.
getTermValues`` in tests/analysis/test_path_fit.py): nested loops, the first coordinate's power
outermost, each inner power running up to the order left over::

    for i in 0..order: for j in 0..order-i: for k in 0..order-i-j: term x^i y^j z^k

so for two coordinates of order 2 the terms are 1, y, y^2, x, x y, x^2.

Fit (`fit_polynomials`): linear least squares on the rows ``[L; -dL/dq]`` of every training pose,
i.e. fibre lengths and fibre moment arms together (a moment-arm row has the same units as a length
row for a rotational coordinate, metres per radian, and is weighted 1). Columns are scaled to unit
norm before ``numpy.linalg.lstsq`` (SVD), which leaves the solution unchanged but keeps high orders
well conditioned. All N fibres of a muscle share the design matrix: one solve with N right-hand
sides.

Gates (ConditionalPathPoints): a path whose ConditionalPathPoint switches inside the sampled range
has a step in its length where the point drops out, which no polynomial follows. With ``gates``
(one ``(column, low, high)`` per conditional point: active when ``low <= q[column] <= high``, the
point's range widened by OpenSim's 1e-5) the fitted function is ``P(q) + sum_g A_g(q) P_g(q)``
with ``A_g`` the 0/1 activity of gate g and ``P_g`` a polynomial of the same order: still linear
least squares (the design's columns are the terms, then the terms times each activity). OpenSim
4.5+ evaluates it exactly as an ``ExpressionBasedFunction`` (``step(q - low) * step(high - q)``;
its derivative, the moment arm, is the active piece's: Lepton's step has zero derivative), see
`expression`.

Sampling (`sample_poses`): like PolynomialPathFitter, random perturbations of the motion's own
frames: each sample takes a frame of the motion and adds to each spanned coordinate an offset
drawn by Latin hypercube sampling (one stratum per sample and coordinate) within
``+-SAMPLING_HALF_WIDTH`` of its motion type (10 degrees, PolynomialPathFitter's default global
bounds; 2 cm for translations). The samples so cover the motion's range with a margin.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

__all__ = ["monomial_exponents", "n_terms", "design_matrix", "design_gradient", "evaluate",
           "fit_polynomials", "sample_poses", "select_orders", "SAMPLING_HALF_WIDTH", "OrderChoice",
           "gate_activity", "expression", "max_order_for"]

#: half width of the sampling box around each motion frame, per motion type (SI)
SAMPLING_HALF_WIDTH = {"rotational": math.radians(10.0), "translational": 0.02, "coupled": math.radians(10.0)}


def n_terms(dim: int, order: int) -> int:
    """Number of terms of a polynomial of ``dim`` variables with total degree <= ``order``."""
    return math.comb(dim + order, order)


def monomial_exponents(dim: int, order: int) -> np.ndarray:
    """(T, dim) int exponents of every term, in OpenSim's MultivariatePolynomialFunction order
    (module docstring)."""
    if dim < 1 or order < 0:
        raise ValueError(f"need dim >= 1 and order >= 0, got {dim}, {order}")
    out = []

    def rec(prefix, left):
        if len(prefix) == dim - 1:
            for k in range(left + 1):
                out.append(prefix + [k])
            return
        for k in range(left + 1):
            rec(prefix + [k], left - k)

    rec([], order)
    exps = np.array(out, dtype=np.int64)
    assert len(exps) == n_terms(dim, order)
    return exps


def max_order_for(dim: int, max_order: int, max_terms: int = 286) -> int:
    """The highest order tried for ``dim`` coordinates: ``max_order``, raised (up to 20) while the
    polynomial has at most ``max_terms`` terms (one or two coordinates: 20; three: 10; four or
    more: ``max_order``), so a fibre whose length bends sharply is followed closer. Measured
    (LHDL gluteus maximus, three coordinates, the fibre whose flexion moment arm turns from -40 to
    -46 mm over the first 2 degrees of the motion): worst motion error 1.5 mm at order 8, 0.64 at
    10 (validation worst 5.2 -> 4.1 mm); fitting took 47 -> 196 s."""
    order = int(max_order)
    while order < 20 and n_terms(dim, order + 1) <= max_terms:
        order += 1
    return order


def gate_activity(q, gates) -> np.ndarray:
    """(S, G) 0/1 activity of every gate ``(column, low, high)`` at poses q (S, D)."""
    q = np.asarray(q, dtype=float)
    if not gates:
        return np.zeros((len(q), 0))
    return np.stack([((q[:, c] >= lo) & (q[:, c] <= hi)).astype(float) for c, lo, hi in gates], axis=1)


def design_matrix(q, exps, gates=()) -> np.ndarray:
    """Term values: q (S, D), exps (T, D) -> (S, T (1 + G)) (gated copies last, module docstring)."""
    q = np.asarray(q, dtype=float)
    t = np.prod(q[:, None, :] ** exps[None, :, :], axis=-1)
    if not gates:
        return t
    a = gate_activity(q, gates)
    return np.concatenate([t] + [a[:, g:g + 1] * t for g in range(a.shape[1])], axis=1)


def design_gradient(q, exps, gates=()) -> np.ndarray:
    """Partial derivatives of every term: q (S, D), exps (T, D) -> (S, D, T (1 + G))."""
    q = np.asarray(q, dtype=float)
    s, d = q.shape
    out = np.empty((s, d, len(exps)))
    for c in range(d):   # loop over coordinates (a handful)
        e = exps.copy()
        coef = e[:, c].astype(float)
        e[:, c] = np.maximum(e[:, c] - 1, 0)
        out[:, c] = coef[None, :] * np.prod(q[:, None, :] ** e[None, :, :], axis=-1)
    if not gates:
        return out
    a = gate_activity(q, gates)
    return np.concatenate([out] + [a[:, None, g:g + 1] * out for g in range(a.shape[1])], axis=2)


def evaluate(coefficients, exps, q, gates=()):
    """Lengths (S, N) and moment arms -dL/dq (S, N, D) of N polynomials (N, T (1 + G)) at poses q (S, D)."""
    coefficients = np.asarray(coefficients, dtype=float)
    lengths = design_matrix(q, exps, gates) @ coefficients.T
    arms = -np.einsum("sdt,nt->snd", design_gradient(q, exps, gates), coefficients)
    return lengths, arms


def expression(coefficients, exps, gates=(), names=None) -> str:
    """The fitted function as an OpenSim ``ExpressionBasedFunction`` expression (Lepton syntax)
    of variables ``names`` (default ``q0, q1, ...``): the polynomial, plus each gate's polynomial
    times ``step(q - low) * step(high - q)`` (module docstring)."""
    exps = np.asarray(exps)
    d = exps.shape[1]
    names = list(names) if names is not None else [f"q{i}" for i in range(d)]
    coefficients = np.asarray(coefficients, dtype=float)
    t = len(exps)

    def poly(c):
        parts = []
        for coef, e in zip(c, exps):
            if coef == 0.0:
                continue
            factors = [repr(float(coef))] + [names[i] if k == 1 else f"{names[i]}^{int(k)}"
                                              for i, k in enumerate(e) if k]
            parts.append("*".join(factors))
        return "(" + (" + ".join(parts) if parts else "0") + ")"

    out = [poly(coefficients[:t])]
    for g, (c, lo, hi) in enumerate(gates):
        out.append(f"step({names[c]} - ({float(lo)!r}))*step(({float(hi)!r}) - {names[c]})*"
                   + poly(coefficients[t * (g + 1):t * (g + 2)]))
    return " + ".join(out).replace("+ -", "- ")


def fit_polynomials(q, lengths, moment_arms, order: int, gates=()) -> np.ndarray:
    """Least-squares coefficients (N, T) of N fibre-length polynomials of total degree ``order``.

    Parameters
    ----------
    q : (S, D) float
        Training poses (the spanned coordinates only).
    lengths : (S, N) float
    moment_arms : (S, N, D) float or None
        -dL/dq at the same poses; rows weighted 1 beside the length rows.
    order : int
    gates : sequence of (column, low, high), optional
        ConditionalPathPoint activities (module docstring).
    """
    q = np.asarray(q, dtype=float)
    exps = monomial_exponents(q.shape[1], order)
    a = [design_matrix(q, exps, gates)]
    b = [np.asarray(lengths, dtype=float)]
    if moment_arms is not None:
        g = design_gradient(q, exps, gates)                            # (S, D, T)
        a.append(-g.reshape(-1, g.shape[-1]))
        b.append(np.moveaxis(np.asarray(moment_arms, dtype=float), 2, 1).reshape(-1, b[0].shape[1]))
    a = np.vstack(a)
    b = np.vstack(b)
    scale = np.linalg.norm(a, axis=0)
    scale[scale == 0] = 1.0
    sol, *_ = np.linalg.lstsq(a / scale, b, rcond=None)
    return (sol / scale[:, None]).T


def sample_poses(q_frames, coord_idx, motion_types, n: int, rng) -> np.ndarray:
    """``n`` poses (n, C_all): motion frames with Latin-hypercube offsets on the spanned coordinates.

    Parameters
    ----------
    q_frames : (F, C_all) float
        The motion's poses (all model coordinates).
    coord_idx : (D,) int
        Columns to perturb.
    motion_types : sequence of str, (D,)
    n : int
    rng : numpy.random.Generator
    """
    q_frames = np.asarray(q_frames, dtype=float)
    base = rng.permutation(np.resize(np.arange(len(q_frames)), n))   # frames used evenly
    q = q_frames[base].copy()
    for c, kind in zip(coord_idx, motion_types):
        u = (rng.permutation(n) + rng.random(n)) / n                   # one stratum per sample
        q[:, c] += (2.0 * u - 1.0) * SAMPLING_HALF_WIDTH.get(kind, SAMPLING_HALF_WIDTH["rotational"])
    return q


@dataclasses.dataclass(frozen=True)
class OrderChoice:
    """The chosen polynomial per fibre and its measured errors on the validation poses.

    Attributes
    ----------
    orders : (N,) int
    coefficients : list of (T_k,) float arrays, one per fibre (OpenSim term order)
    length_max, length_rms : (N,) float
        Validation error of the length (m).
    moment_arm_max : (N,) float
        Largest validation error of -dL/dq over the coordinates (m per rad).
    ok : (N,) bool
        Both errors within the tolerances.
    """

    orders: np.ndarray
    coefficients: list
    length_max: np.ndarray
    length_rms: np.ndarray
    moment_arm_max: np.ndarray
    ok: np.ndarray


def select_orders(train, validation, *, max_order: int, length_tol: float,
                  moment_arm_tol: float, gates=()) -> OrderChoice:
    """Per fibre, the lowest order whose worst validation errors meet both tolerances (else the
    order with the smallest tolerance-scaled RMS error).

    ``train`` and ``validation`` are (q (S, D), lengths (S, N), moment_arms (S, N, D)) triples.
    The orders tried are 1..max_order, each fitted only while it has fewer terms than the
    training rows. ``gates``: as in `fit_polynomials` (every order gets the gated terms).
    """
    q_t, l_t, r_t = train
    q_v, l_v, r_v = validation
    n = l_t.shape[1]
    d = q_t.shape[1]
    rows = len(q_t) * (1 + d)
    best = None
    for order in range(1, max_order + 1):
        if n_terms(d, order) * (1 + len(gates)) >= rows:
            break
        coef = fit_polynomials(q_t, l_t, r_t, order, gates)
        lv, rv = evaluate(coef, monomial_exponents(d, order), q_v, gates)
        el = np.abs(lv - l_v)
        e_max, e_rms = el.max(axis=0), np.sqrt((el ** 2).mean(axis=0))
        em = np.abs(rv - r_v)
        m_max = em.max(axis=(0, 2))
        m_rms = np.sqrt((em ** 2).mean(axis=(0, 2)))
        ok = (e_max <= length_tol) & (m_max <= moment_arm_tol)
        # between orders that miss the tolerances, the smaller RMS error wins (the worst error of
        # a path with a step, e.g. a ConditionalPathPoint, is the step's, whatever the order)
        score = np.where(ok, 0.0, np.maximum(e_rms / length_tol, m_rms / moment_arm_tol))
        if best is None:
            best = dict(orders=np.full(n, order), coefficients=list(coef), length_max=e_max,
                        length_rms=e_rms, moment_arm_max=m_max, ok=ok, score=score)
            continue
        # a fibre takes this order if it was not yet within tolerance and this one is better
        take = ~best["ok"] & (score < best["score"])
        for k in np.flatnonzero(take):
            best["coefficients"][k] = coef[k]
        best["orders"] = np.where(take, order, best["orders"])
        for key, val in (("length_max", e_max), ("length_rms", e_rms), ("moment_arm_max", m_max),
                         ("ok", ok), ("score", score)):
            best[key] = np.where(take, val, best[key])
        if best["ok"].all():
            break
    if best is None:
        raise ValueError(f"{len(q_t)} training poses are too few for a polynomial of {d} coordinates")
    best.pop("score")
    return OrderChoice(**best)
