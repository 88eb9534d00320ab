"""Sobol sampling of the template parameter square (r, s) in [0, 1]^2.

Kohout et al. (GRAPP 2012) §3.1, after Ng-Thow-Hing (2001): a Sobol low-discrepancy sequence
spreads a few hundred fibres over the muscle more evenly than random or grid sampling. We use
``scipy.stats.qmc.Sobol``, whose direction numbers are those of Joe & Kuo (2008), "Constructing
Sobol sequences with better two-dimensional projections", SIAM J. Sci. Comput. 30(5):2635-2654,
scrambled (Owen-type linear matrix scrambling plus digital shift) with the given seed so that no
fibre sits exactly on the face of the template cube.

Determinism: the points are the first ``n`` of one fixed sequence per seed, so fibre ``k`` is
the same fibre whatever ``n`` is (as long as ``n > k``), in every frame and every run.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

__all__ = ["sobol_rs"]


def sobol_rs(n: int, *, seed: int = 0) -> np.ndarray:
    """The first ``n`` points of the scrambled 2D Sobol sequence for ``seed``.

    Parameters
    ----------
    n : int
        Number of fibres N (>= 1); need not be a power of two.
    seed : int, keyword-only
        Scrambling seed (>= 0). The same seed always gives the same sequence.

    Returns
    -------
    rs : (N, 2) float64, read-only
        Template parameters (r, s) in the open square (0, 1)^2.
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    m = max(int(np.ceil(np.log2(int(n)))), 0)
    return _sobol_block(m, int(seed))[: int(n)]


@lru_cache(maxsize=16)
def _sobol_block(m: int, seed: int) -> np.ndarray:
    """The first 2^m points for ``seed``, read-only (computed once: every frame of a motion
    asks for the same fibres)."""
    from scipy.stats import qmc

    engine = qmc.Sobol(d=2, scramble=True, rng=np.random.default_rng(seed))
    rs = engine.random_base2(m)
    rs.flags.writeable = False
    return rs
