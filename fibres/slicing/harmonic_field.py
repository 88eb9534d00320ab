"""A harmonic scalar field on a closed muscle surface between its two attachment patches.

Dong, Kircher & Garland, "Harmonic functions for quadrilateral remeshing of arbitrary
manifolds", Computer Aided Geometric Design 22(5):392-423 (2005), and Modenese & Kohout,
"Automated generation of three-dimensional complex muscle geometries for use in personalised
musculoskeletal models", Ann. Biomed. Eng. 48:1793-1804 (2020): the field is 0 on the origin
patch, 1 on the insertion patch and harmonic (Laplace's equation) on the rest of the surface.
Its isolines (`fibres.slicing.isolines`) are the cross-sections of the muscle: they follow its bends
and fans and begin and end on the attachment boundaries.

Discretisation: piecewise linear on the triangles, the cotangent Laplacian (Pinkall &
Polthier, "Computing discrete minimal surfaces and their conjugates", Exp. Math. 2(1), 1993):
edge weight ``w_ij = (cot alpha_ij + cot beta_ij) / 2`` over the two angles opposite the edge.
Negative weights (an edge opposite two obtuse angles whose cotangents sum below zero) are set
to zero: the matrix is then an M-matrix, so the discrete field obeys the maximum principle
(no interior extrema, values in [0, 1], so no spurious small isoline loops), at the price of
exact linear precision on such edges only. Dirichlet values on the patch vertices; the free
vertices' system ``L_ff u_f = -L_fb u_b`` is symmetric positive definite and solved by a sparse
LU factorisation (scipy.sparse.linalg.splu: SuperLU in symmetric mode with a minimum degree
ordering of A^T + A, pivots on the diagonal: the matrix is symmetric positive definite;
panels of one column, since the factors of a surface mesh's Laplacian are too sparse for
wider panels to pay).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from ..errors import InputError

__all__ = ["mesh_edges", "cotangent_weights", "harmonic_field"]


def mesh_edges(faces: np.ndarray, n_vertices: int):
    """Unique undirected edges of a triangle mesh.

    Returns
    -------
    edges : (E, 2) int64
        Vertex pairs, smaller index first.
    face_edges : (T, 3) int64
        Edge index of each face's sides (v0 v1, v1 v2, v2 v0).
    """
    f = np.asarray(faces, dtype=np.int64)
    a = f.reshape(-1)
    b = np.roll(f, -1, axis=1).reshape(-1)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = lo * np.int64(n_vertices) + hi
    uniq, inverse = np.unique(key, return_inverse=True)
    edges = np.stack([uniq // n_vertices, uniq % n_vertices], axis=1)
    return edges, inverse.reshape(-1, 3)


def cotangent_weights(vertices, faces, edges, face_edges) -> np.ndarray:
    """(E,) cotangent weights ``(cot alpha + cot beta) / 2`` of the edges, clipped at 0."""
    a, b, c = np.take(vertices, np.ascontiguousarray(faces.T), axis=0)  # (T, 3) each
    # the sides from each corner; |cross| is twice the area whichever corner it is taken at
    ab, bc, ca = b - a, c - b, a - c
    cx = ab[:, 1] * ca[:, 2] - ab[:, 2] * ca[:, 1]
    cy = ab[:, 2] * ca[:, 0] - ab[:, 0] * ca[:, 2]
    cz = ab[:, 0] * ca[:, 1] - ab[:, 1] * ca[:, 0]
    half = -0.5 / np.maximum(np.sqrt(cx * cx + cy * cy + cz * cz), 1e-300)
    # the angle at corner k is opposite side k + 1 (v_{k+1} v_{k+2}), face_edges' column
    # k + 1: cot = a . b / |a x b|, written into that column; each edge of the closed surface
    # sums its two faces' halves (in either order: the same bits)
    cot = np.empty((len(half), 3))
    for column, (u, w) in ((1, (ab, ca)), (2, (bc, ab)), (0, (ca, bc))):
        np.einsum("ij,ij->i", u, w, out=cot[:, column])
    cot *= half[:, None]
    w = np.bincount(face_edges.reshape(-1), cot.reshape(-1), len(edges))
    return np.maximum(w, 0.0)


def _rhs(where, i, j, w, one, n_free):
    """Right-hand side of the free vertices: the weights of their edges to the value-1 patch."""
    rhs = np.zeros(n_free)
    for x, y in ((i, j), (j, i)):
        sel = (where[x] >= 0) & one[y]
        rhs += np.bincount(where[x[sel]], w[sel], n_free)
    return rhs


def harmonic_field(vertices, faces, zero, one, *, edges=None, face_edges=None) -> np.ndarray:
    """The discrete harmonic field with value 0 on ``zero`` and 1 on ``one`` (module docstring).

    Parameters
    ----------
    vertices : (V, 3) float
    faces : (T, 3) int
        A closed surface.
    zero, one : (V,) bool
        The origin and insertion patches' vertices (disjoint, both non-empty).
    edges, face_edges : optional
        `mesh_edges` of the faces, when at hand.

    Returns
    -------
    (V,) float
        The field, in [0, 1].
    """
    v = np.asarray(vertices, dtype=np.float64)
    n = len(v)
    zero = np.asarray(zero, dtype=bool)
    one = np.asarray(one, dtype=bool)
    if not zero.any() or not one.any():
        raise InputError("an attachment patch is empty", where="attachments",
                         fix="Give landmarks of both the origin and the insertion.")
    if (zero & one).any():
        raise InputError("the origin and insertion patches overlap", where="attachments",
                         fix="Check that the origin and insertion landmarks are not swapped or "
                             "mixed.")
    if edges is None or face_edges is None:
        edges, face_edges = mesh_edges(faces, n)
    w = cotangent_weights(v, np.asarray(faces, dtype=np.int64), edges, face_edges)
    # tiny floor: keeps the free system non-singular where a vertex's every weight is 0
    w = w + 1e-12 * (w.max() if w.size else 1.0)
    i, j = edges[:, 0], edges[:, 1]
    fixed = zero | one
    free = np.flatnonzero(~fixed)
    u = np.where(one, 1.0, 0.0)
    if free.size:
        # the free vertices' block of the Laplacian straight from the edges: diagonal the sum
        # of all a vertex's weights, off-diagonal -w between two free vertices; the edges to
        # the insertion patch (u = 1) move to the right-hand side
        where = np.full(n, -1, dtype=np.int64)
        where[free] = np.arange(free.size)
        diag = (np.bincount(i, w, n) + np.bincount(j, w, n))[free]
        both = (where[i] >= 0) & (where[j] >= 0)
        a, b, wb = where[i[both]], where[j[both]], w[both]
        k = np.arange(free.size)
        # entries in (column, row) order once converted (the edges are sorted): above the
        # diagonal, the diagonal, below it; no sort in the conversion
        mat = sp.csc_matrix((np.concatenate([-wb, diag, -wb]),
                             (np.concatenate([a, k, b]), np.concatenate([b, k, a]))),
                            shape=(free.size, free.size))
        rhs = _rhs(where, i, j, w, one, free.size)
        u[free] = splu(mat, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, panel_size=1,
                       options={"SymmetricMode": True}).solve(rhs)
    return np.clip(u, 0.0, 1.0)
