"""Fibre smoothing: iterated weighted averaging of the inner points (Kohout et al. 2012, §3.4).

At each step every inner point of every poly-line is replaced, simultaneously, by
``P'_i = (P_{i-1} + k P_i + P_{i+1}) / (k + 2)`` with the smoothing constant k = 4 of the
paper; the two end points (on the attachment areas) never move. The iteration is a damped
Jacobi step for the discrete Laplace equation with fixed ends, so repeating it forever yields
equally spaced points on the chord; each error mode j decays by
``1 - 2 (1 - cos(pi j / (P - 1))) / (k + 2)`` per step.
"""
from __future__ import annotations

import numpy as np

__all__ = ["smooth", "DEFAULT_ITERATIONS"]

#: smoothing steps used by `fibres.decompose` unless told otherwise (light: removes slice
#: noise, keeps the shape; the paper leaves the count to the user)
DEFAULT_ITERATIONS = 5


def smooth(points, *, k: float = 4.0, iterations: int = DEFAULT_ITERATIONS) -> np.ndarray:
    """Smooth poly-lines with fixed end points (Kohout 2012 §3.4).

    Parameters
    ----------
    points : (N, P, 3) float (or (P, 3) for one poly-line)
        Fibre poly-lines.
    k : float, keyword-only
        Smoothing constant (> 0; 4 in the paper). Larger k smooths less per step.
    iterations : int, keyword-only
        Number of steps (>= 0).

    Returns
    -------
    (N, P, 3) float64
        A new array (the input is not modified); ends identical to the input's.
    """
    k = float(k)
    if not np.isfinite(k) or k <= 0:
        raise ValueError(f"k must be a positive number, got {k!r}")
    if isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)) \
            or iterations < 0:
        raise ValueError(f"iterations must be a non-negative integer, got {iterations!r}")
    out = np.array(points, dtype=np.float64, copy=True)
    if out.ndim < 2 or out.shape[-2] < 3:
        return out
    inv = 1.0 / (k + 2.0)
    for _ in range(int(iterations)):  # loop over smoothing steps only, not over points
        out[..., 1:-1, :] = (out[..., :-2, :] + k * out[..., 1:-1, :] + out[..., 2:, :]) * inv
    return out
