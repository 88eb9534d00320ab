"""The harmonic decomposition's fibre map (`fibres.slicing.harmonic`): its sparse builders
against their direct COO construction, and the rest pose's cached points against the map
applied to the rest vertices."""
import numpy as np
import scipy.sparse as sp
from test_decompose_analytic import arc, cap_ring, tube

from fibres import decompose
from fibres.slicing import harmonic
from fibres.slicing.mvc import mean_value_coordinates

RHO = 0.01


def _rectangle_samples(k: int, share: float) -> np.ndarray:
    """Oracle of `fibres.slicing.harmonic._rectangles`, one loop at a time: (k, 2) points of
    the unit square's boundary, counter-clockwise from (0, 0), evenly spaced on the perimeter
    of a rectangle whose sides along x take ``share`` of its perimeter."""
    w = min(max(float(share), 0.02), 0.98)
    phi = np.arange(k) / k
    out = np.empty((k, 2))
    bounds = np.array([0.0, w / 2, 0.5, 0.5 + w / 2, 1.0])
    side = np.searchsorted(bounds, phi, side="right") - 1
    f = (phi - bounds[side]) / np.diff(bounds)[side]
    out[:, 0] = np.choose(side, [f, np.ones_like(f), 1 - f, np.zeros_like(f)])
    out[:, 1] = np.choose(side, [np.zeros_like(f), f, np.ones_like(f), 1 - f])
    return out


def _circle(th):
    return np.c_[RHO * np.cos(th), RHO * np.sin(th)]


def _bend_oracle(n, p):
    """`_bend_to_ends` written entry by entry (identity plus each end's three weights per
    bent point, duplicates summed by the COO -> CSR conversion)."""
    bend = max(3.0, harmonic.END_BEND * (p - 1))
    rows, cols, vals = [np.arange(n * p)], [np.arange(n * p)], [np.ones(n * p)]
    base = np.arange(n) * p
    for end, one, two, sign in ((0, 1, 2, 1), (p - 1, p - 2, p - 3, -1)):
        for q in range(1, p - 1 if p >= 3 else 1):
            g = (1.0 - q / bend) ** 2 if q < bend else 0.0
            if g <= 0.0:
                break
            r = base + (q if sign > 0 else p - 1 - q)
            for c, w in ((end, g), (one, -2.0 * g), (two, g)):
                rows.append(r)
                cols.append(base + c)
                vals.append(np.full(n, w))
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(n * p, n * p))


def test_bend_and_even_steps_equal_their_entrywise_construction():
    for n, p in ((4, 16), (3, 5), (2, 3), (2, 2), (5, 41)):
        got, ref = harmonic._bend_to_ends(n, p), _bend_oracle(n, p)
        assert abs(got - ref).max() <= 1e-15
    rng = np.random.default_rng(2)
    pts = np.cumsum(rng.uniform(0.0, 1.0, (6, 12, 3)), axis=1)
    pts[0, 3] = pts[0, 2]                                  # a zero-length segment
    even = harmonic._even(pts)
    assert np.allclose(even.sum(axis=1), 1.0, atol=1e-15) and even.nnz == 2 * 6 * 12
    out = (even @ pts.reshape(-1, 3)).reshape(pts.shape)
    seg = np.linalg.norm(np.diff(out, axis=1), axis=2)
    # equal steps along each polyline: the chords of equal arc-length steps are at most
    # those steps, equal where a step stays on one segment
    total = np.linalg.norm(np.diff(pts, axis=1), axis=2).sum(axis=1)
    assert np.all(seg <= total[:, None] / 11 + 1e-12)
    np.testing.assert_allclose(out[:, [0, -1]], pts[:, [0, -1]], atol=1e-12)


def test_stacked_polygons_give_each_polygon_s_own_coordinates():
    """One call for the loops' rectangles (and points on their vertices and edges) gives the
    rows of one call per polygon bit for bit."""
    polys = np.stack([_rectangle_samples(64, s) for s in (0.1, 0.35, 0.5, 0.9)])
    rng = np.random.default_rng(4)
    pts = rng.uniform(0.0, 1.0, (300, 2))
    groups = rng.integers(0, 4, 300)
    pts[:5], groups[:5] = polys[2, [0, 7, 16, 33, 63]], 2                 # vertices
    pts[5] = 0.3 * polys[1, 10] + 0.7 * polys[1, 11]                      # an edge
    groups[5] = 1
    got = mean_value_coordinates(pts, polys, groups)
    for g in range(4):
        sel = groups == g
        assert np.array_equal(got[sel], mean_value_coordinates(pts[sel], polys[g]))
    assert np.array_equal(got[:5], np.eye(64)[[0, 7, 16, 33, 63]])
    np.testing.assert_allclose(got[5, [10, 11]], [0.3, 0.7], atol=1e-15)



def test_the_loops_rectangles_at_once_equal_one_call_per_loop():
    """`_rectangles` (all loops' square samples in one pass) gives `_rectangle_samples` of
    each share bit for bit, clipped shares and sample counts that do not split evenly
    included."""
    shares = np.r_[np.random.default_rng(7).uniform(0.0, 1.0, 20), 0.0, 1.0, 0.02, 0.5, 1 / 3]
    for k in (64, 7, 5):
        assert np.array_equal(harmonic._rectangles(k, shares),
                              np.stack([_rectangle_samples(k, s) for s in shares]))

def test_rest_points_are_the_map_of_the_rest_vertices():
    """The plan keeps the rest pose's points: a copy of the rest vertices (another array)
    and the map itself give them bit for bit; a moved copy moves them."""
    v, f = tube(_circle, *arc(0.08, np.pi / 3), n_sect=32, n_path=30)
    e1, e2 = np.array([0, 0, 1.0]), np.array([1.0, 0, 0])
    o = cap_ring(v[:-2][:32].mean(axis=0), e1, e2, 0.6 * RHO)
    i = cap_ring(v[:-2][-32:].mean(axis=0), e1, np.array([0, 1.0, 0]), 0.6 * RHO)
    b = decompose((v, f), o, i, n_fibres=20, resolution=9)
    plan = b.plan
    args = (b.template, 20, 9, 0, 0)
    slices, loops, verts, post, fair, rs, rest = harmonic._maps(plan, *args)
    v = plan.rest_vertices
    direct = fair @ (post @ (loops @ (slices.samples @ v) + verts @ v))
    assert np.array_equal(direct.reshape(rest.shape), rest)
    again = harmonic.harmonic_points(plan, plan.rest_vertices.copy(), *args)[0]
    assert np.array_equal(again, rest) and again is not rest
    shift = np.array([0.01, -0.02, 0.005])
    moved = harmonic.harmonic_points(plan, plan.rest_vertices + shift, *args)[0]
    np.testing.assert_allclose(moved, rest + shift, atol=1e-12)
