"""The compiled steps of the attachment ends (`fibres.attachments.patch_map`: `_lloyd`,
`_window`, and the membranes' `_grid_map`) and the patch's holes and pieces
(`fibres.attachments.patch._pieces`) against plain numpy oracles written here from their
definitions: brute force over every point, sample and triangle, and one graph search per
mask.
"""
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull

from fibres.attachments import patch as P
from fibres.attachments import patch_map as PM
from fibres.mesh.closest_point import closest_points_on_triangles
from fibres.slicing.harmonic_field import mesh_edges


def _sphere(n=600, seed=0):
    """A closed triangulated unit sphere (the hull of a Fibonacci point set, jittered)."""
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    th = np.pi * (1.0 + 5 ** 0.5) * k
    v = np.c_[np.sqrt(1 - z * z) * np.cos(th), np.sqrt(1 - z * z) * np.sin(th), z]
    f = ConvexHull(v).simplices.astype(np.int64)                # every point on the hull
    return v * (1.0 + 0.02 * np.random.default_rng(seed).standard_normal((n, 1))), f


def _ends(v, f, mask, n, rng):
    face = rng.choice(np.flatnonzero(mask), n)
    bary = rng.dirichlet(np.ones(3), n)
    return mask, face, bary


def _lloyd_oracle(v, f, mask, face, bary, samples=PM.SAMPLES):
    """One Lloyd step by brute force: samples to their nearest point, each point with
    samples to the patch point nearest their weighted centroid (all triangles measured)."""
    i = np.flatnonzero(mask)
    t = v[f[i]]
    area = 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
    n = int(np.clip(np.sqrt(samples / len(i)), 1, 8))
    sub = PM._sub_centroids(n)
    s = np.einsum("sk,tkd->tsd", sub, t).reshape(-1, 3)
    w = np.repeat(area / len(sub), len(sub))
    p = np.einsum("nk,nkd->nd", bary, v[f[face]])
    owner = np.argmin(((s[:, None] - p[None]) ** 2).sum(axis=2), axis=1)
    mass = np.bincount(owner, w, len(p))
    c = np.stack([np.bincount(owner, w * s[:, d], len(p)) for d in range(3)], 1)
    out = p.copy()
    for j in np.flatnonzero(mass > 0):
        y = c[j] / mass[j]
        q = closest_points_on_triangles(y, t[:, 0], t[:, 1], t[:, 2])
        out[j] = q[np.argmin(((q - y) ** 2).sum(axis=1))]
    return out


def test_lloyd_kernel_matches_a_brute_force_step_on_two_curved_patches():
    """Two caps of a bumpy sphere relaxed together (the kernel's patch segments): one step
    puts every point where the brute-force oracle does, to rounding, and the returned face
    and barycentric weights give that point."""
    v, f = _sphere()
    cz = v[f].mean(axis=1)[:, 2]
    rng = np.random.default_rng(1)
    ends = [_ends(v, f, cz > 0.5, 40, rng), _ends(v, f, cz < -0.7, 25, rng)]
    got = PM.relax_on_patches(v, f, ends, iterations=1)
    for (mask, face, bary), (gf, gb) in zip(ends, got):
        want = _lloyd_oracle(v, f, mask, face, bary)
        at = np.einsum("nk,nkd->nd", gb, v[f[gf]])
        np.testing.assert_allclose(at, want, atol=1e-12)
        assert mask[gf].all()



def test_lloyd_steps_keep_the_brute_force_owners_over_several_steps_and_ties():
    """Three steps at once against three brute-force steps (the triangle search's bound
    tightens as closest points are found), with two points on the same spot (their tie
    goes to the lower point, whose cell takes all the samples: in the first step the other
    one stays)."""
    v, f = _sphere()
    cz = v[f].mean(axis=1)[:, 2]
    rng = np.random.default_rng(5)
    mask, face, bary = _ends(v, f, cz > 0.3, 50, rng)
    face[7], bary[7] = face[3], bary[3]
    got_f, got_b = PM.relax_on_patches(v, f, [(mask, face, bary)], iterations=3)[0]
    want_f, want_b = face, bary
    for _ in range(3):
        at = _lloyd_oracle(v, f, mask, want_f, want_b)
        i = np.flatnonzero(mask)
        want_f, want_b = _onto(v, f, i, at)
    np.testing.assert_allclose(np.einsum("nk,nkd->nd", got_b, v[f[got_f]]),
                               np.einsum("nk,nkd->nd", want_b, v[f[want_f]]), atol=1e-12)
    one_f, one_b = PM.relax_on_patches(v, f, [(mask, face, bary)], iterations=1)[0]
    assert one_f[7] == face[7] and np.array_equal(one_b[7], bary[7])   # no samples: stays
    assert one_f[3] != face[3] or not np.array_equal(one_b[3], bary[3])


def _onto(v, f, idx, q):
    """Faces (among ``idx``) and barycentric weights of points ``q`` lying on them."""
    t = v[f[idx]]
    near = [int(np.argmin(np.linalg.norm(closest_points_on_triangles(x, t[:, 0], t[:, 1],
                                                                      t[:, 2]) - x, axis=1)))
            for x in q]
    return idx[near], PM._barycentric_3d(t[near], q)

def _window_oracle(px, py, area, X, Y, samples=PM.SAMPLES):
    """`knothe_rosenblatt` with the (N, S) window weights and cumulative sums in numpy."""
    n = int(np.clip(np.sqrt(samples / len(px)), 1, 8))
    sub = PM._sub_centroids(n)
    sx, sy = (px @ sub.T).reshape(-1), (py @ sub.T).reshape(-1)
    sw = np.repeat(area / len(sub), len(sub))
    xs = PM._quantile(sx, sw, np.clip(X, 0.0, 1.0))
    h = PM.WINDOW * (sx.max() - sx.min())
    order = np.argsort(sy, kind="stable")
    sy, sx, sw = sy[order], sx[order], sw[order]
    w = np.exp(-0.5 * ((sx[None] - xs[:, None]) / h) ** 2) * sw
    cum = np.cumsum(w, axis=1)
    mid = (cum - 0.5 * w) / cum[:, -1:]
    ys = np.array([np.interp(q, m, sy) for q, m in zip(np.clip(Y, 0, 1), mid)])
    return xs, ys


def test_window_kernel_matches_the_numpy_conditional_quantile():
    """The Knothe-Rosenblatt targets of a curved patch's projection: the compiled
    conditional (`_window`) gives the numpy window's quantiles (piecewise linear in the
    mid-point cumulative weights, clamped at the ends), to rounding."""
    v, f = _sphere()
    tri = v[f[v[f].mean(axis=1)[:, 2] > 0.3]]
    px, py = tri[..., 0], tri[..., 1]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    rng = np.random.default_rng(2)
    X, Y = rng.uniform(0, 1, 60), np.r_[rng.uniform(0, 1, 58), 0.0, 1.0]
    xs, ys = PM.knothe_rosenblatt(px, py, area, X, Y)
    wx, wy = _window_oracle(px, py, area, X, Y)
    np.testing.assert_allclose(xs, wx, atol=1e-12)
    np.testing.assert_allclose(ys, wy, atol=1e-12)



def _grid_oracle(mass, X, Y):
    """`grid_area_map` of one grid in numpy, from its definition: F1 by `np.interp` of the
    cumulative column masses, the conditional profile of y blended between the two
    bracketing columns and its cumulative sums inverted linearly."""
    m = np.maximum(mass, 0.0)
    g = m.shape[0]
    m = m + 1e-12 * max(float(m.sum()), 1e-300) / m.size
    col = m.sum(axis=1)
    f1 = np.concatenate([[0.0], np.cumsum(col)]) / col.sum()
    xs = np.interp(np.clip(X, 0.0, 1.0), f1, np.linspace(0.0, 1.0, g + 1))
    c = np.clip(xs * g - 0.5, 0.0, g - 1.0)
    a0 = np.minimum(np.floor(c).astype(np.int64), g - 1)
    a1 = np.minimum(a0 + 1, g - 1)
    t = (c - a0)[:, None]
    prof = m / col[:, None]
    p = (1.0 - t) * prof[a0] + t * prof[a1]
    cum = np.concatenate([np.zeros((len(xs), 1)), np.cumsum(p, axis=1)], axis=1)
    cum /= cum[:, -1:]
    q = np.clip(Y, 0.0, 1.0)
    k = np.clip(np.count_nonzero(cum[:, 1:] < q[:, None], axis=1), 0, g - 1)
    lo, hi = cum[np.arange(len(xs)), k], cum[np.arange(len(xs)), k + 1]
    return xs, (k + np.clip((q - lo) / np.maximum(hi - lo, 1e-300), 0.0, 1.0)) / g


def test_grid_map_kernel_of_a_stack_matches_one_numpy_map_per_grid():
    """Grids of several sizes with uneven, empty and all-zero cells, points inside, on the
    knots and outside the square: the stacked call (`_grid_map`, each point in its own
    grid) gives the oracle's coordinates grid by grid, bit for bit."""
    rng = np.random.default_rng(6)
    for g, n_grids in ((16, 14), (8, 3), (5, 1), (3, 4)):
        mass = rng.uniform(0.0, 1.0, (n_grids, g, g)) ** 3
        mass[0, :, 1] = 0.0                                      # an empty row
        if n_grids > 1:
            mass[-1] = 0.0                                       # an empty grid
        X, Y = rng.uniform(-0.1, 1.1, 400), rng.uniform(-0.1, 1.1, 400)
        X[:4], Y[:4] = [0.0, 1.0, 0.5, 0.25], [1.0, 0.0, 0.5, 0.75]
        groups = rng.integers(0, n_grids, 400)
        xs, ys = PM.grid_area_map(mass, X, Y, groups)
        for j in range(n_grids):
            at = groups == j
            wx, wy = _grid_oracle(mass[j], X[at], Y[at])
            assert np.array_equal(xs[at], wx) and np.array_equal(ys[at], wy)
        one = PM.grid_area_map(mass[0], X, Y)
        assert np.array_equal(one[0], _grid_oracle(mass[0], X, Y)[0])


def test_window_weights_are_the_gaussian_to_rounding_and_sw_far_from_every_sample():
    """`_window`'s own exponential (Cody-Waite reduction, Taylor polynomial) against numpy's
    exp: the mid-point cumulative sums and totals agree to a few units of rounding; a point
    beyond 34 window widths from every sample gets the samples' own weights."""
    rng = np.random.default_rng(8)
    sx, sw = rng.uniform(0.0, 1.0, 700), rng.uniform(0.1, 1.0, 700) * 1e-6
    x, h = np.r_[rng.uniform(-0.2, 1.2, 50), 4.0], 0.08
    k = np.arange(len(x)) % 690 + 1
    out = np.empty((len(x), 5))
    PM._window(sx, sw, x, h, np.zeros(len(x)), k.copy(), out, np.empty(len(sx)))
    w = np.exp(-0.5 * ((sx[None] - x[:, None]) / h) ** 2) * sw
    w[-1] = sw                                                      # 4.0: 37 widths away
    cum = np.cumsum(w, axis=1)
    half = cum - 0.5 * w
    rows = np.arange(len(x))
    want = np.stack([half[rows, k - 1], half[rows, k], cum[:, -1], half[:, 0], half[:, -1]], 1)
    scale = np.array([1.0] * 50 + [np.exp(-600.0)])[:, None]       # the far point's weights
    np.testing.assert_allclose(out / scale, want, rtol=1e-13)

def _pieces_oracle(patch, edges, vertex_area):
    """Holes filled, then small pieces dropped, each from the components of the masked
    vertices alone (module docstring of `fibres.attachments.patch`, steps 3 and 4)."""
    def components(mask):
        idx = np.flatnonzero(mask)
        where = np.full(mask.size, -1)
        where[idx] = np.arange(idx.size)
        keep = mask[edges[:, 0]] & mask[edges[:, 1]]
        a, b = where[edges[keep, 0]], where[edges[keep, 1]]
        return idx, connected_components(coo_matrix((np.ones(a.size), (a, b)),
                                                    (idx.size, idx.size)), directed=False)[1]
    rest, label = components(~patch)
    area = np.bincount(label, vertex_area[rest])
    small = area < 0.5 * vertex_area[patch].sum()
    small[area.argmax()] = False
    patch = patch.copy()
    patch[rest[small[label]]] = True
    idx, label = components(patch)
    area = np.bincount(label, vertex_area[idx])
    out = np.zeros_like(patch)
    out[idx[(area >= P.MIN_PIECE * area.sum())[label]]] = True
    return out


def test_holes_and_pieces_from_one_components_search_match_two():
    """A patch with holes (rings of free vertices inside it), a small stray piece and a
    large second piece: `_pieces` (one components search of the patch and the rest at
    once, a second only when holes were filled) fills and drops what the oracle does."""
    v, f = _sphere(900)
    edges, _ = mesh_edges(f, len(v))
    graph, rows, _ = P.edge_graph(v, edges)
    area = np.full(len(v), 1.0)
    z = v[:, 2]
    rng = np.random.default_rng(3)
    cap = z > 0.4
    holey = cap & ~((np.abs(z - 0.7) < 0.05) & (v[:, 0] > 0.2))          # a hole inside
    holey[rng.choice(np.flatnonzero(cap), 8)] = False                     # pinholes
    stray = holey.copy()
    stray[np.argmin(z)] = True                                          # a stray vertex
    two = (z > 0.8) | ((z < -0.3) & (z > -0.7))                          # two large pieces
    cases = [cap, holey, stray, two]
    notes = []
    for patch in cases:
        np.testing.assert_array_equal(P._pieces(patch, graph, rows, area, "origin", notes),
                                      _pieces_oracle(patch, edges, area))
    assert P._pieces(holey, graph, rows, area, "o", []).sum() > holey.sum()      # filled
    assert any("dropped" in n for n in notes) and any("separate" in n for n in notes)
