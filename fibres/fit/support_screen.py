"""Support screen of the box search (`fibres.fit.fitting`, Kohout et al., GRAPP 2012, §3.2).

The box of every rotation about the principal axis needs the minimum and maximum of the
projections ``cos(t) a + sin(t) b`` of the vertices' cross-section coordinates (a, b). Only
points that can attain such a minimum or maximum for some angle t matter: a superset of
the vertices of the points' convex hull. The screen drops the others, exactly: what it
drops lies deeper inside a convex polygon spanned by some of the points than a margin
``delta`` (1e-9 of the spread, ~1e7 times the rounding of a projection), so a polygon
vertex (kept) exceeds its projection in every direction and no minimum or maximum changes,
bit for bit.

Polygon screen (Akl & Toussaint 1978, "A fast convex hull algorithm", Inf. Process. Lett.
7(5):219-222): the points extreme along n evenly spread directions span a convex polygon
inside the hull; a point farther than delta inside every edge is dropped. Passes of
`_SCREEN_DIRECTIONS` (8, 32, 128) directions; the first, coarse polygon is spanned by the
extremes of every `_SCREEN_STRIDE`-th point only (any points of the set span a polygon inside
the hull; this one costs an eighth of the projections).
"""
from __future__ import annotations

import numpy as np

__all__ = []

#: directions of the polygons that screen the support candidates (three passes; the
#: third cuts ~1200 candidates of a twisted 15K-vertex spindle to ~350)
_SCREEN_DIRECTIONS = (8, 32, 128)
#: the first screening pass takes its polygon from every 8th point
_SCREEN_STRIDE = 8


def polygon_screen(a, b, spread):
    """The polygon screen (module docstring) with arrays: indices (V',) int64, increasing,
    of the points a, b (V,) kept; ``spread`` = max(ptp a, ptp b)."""
    idx = np.arange(a.size)
    for n_dir in _SCREEN_DIRECTIONS:
        if idx.size <= 4 * n_dir:
            break
        phi = 2.0 * np.pi * np.arange(n_dir) / n_dir
        pa, pb = a[idx], b[idx]
        step = _SCREEN_STRIDE if n_dir == _SCREEN_DIRECTIONS[0] else 1
        proj = np.cos(phi)[:, None] * pa[::step] + np.sin(phi)[:, None] * pb[::step]
        ext = np.argmax(proj, axis=1) * step        # counter-clockwise around the hull
        ext = ext[np.append(ext[1:] != ext[:-1], ext[-1] != ext[0])]     # distinct corners
        if np.unique(ext).size < 3:
            break
        qa, qb = pa[ext], pb[ext]
        ea, eb = np.roll(qa, -1) - qa, np.roll(qb, -1) - qb               # polygon edges
        margin = 1e-9 * spread * np.hypot(ea, eb)                          # distance * |edge|
        inside = np.ones(idx.size, dtype=bool)
        for k in range(ext.size):  # polygon edges (at most 128)
            inside &= ea[k] * (pb - qb[k]) - eb[k] * (pa - qa[k]) > margin[k]
        idx = idx[~inside]
    return idx
