"""Rectangle <-> contour correspondence (Kohout 2012 §3.3): exactness of the split."""
import itertools

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from fibres.slicing.correspondence import (correspond, rectangle, split_chain, start_vertex,
                                   subdivide_rectangle)
from fibres.slicing.mvc import mean_value_coordinates


def _brute_force(seg, sides):
    """The paper's error minimised over every split (reference)."""
    m = len(seg)
    k = sides.sum() / seg.sum()
    c = np.concatenate([[0.0], np.cumsum(seg)])
    best = (np.inf, None)
    for i1, i2, i3 in itertools.combinations(range(1, m), 3):
        parts = np.array([c[i1], c[i2] - c[i1], c[i3] - c[i2], c[m] - c[i3]])
        err = np.sum((sides - k * parts) ** 2)
        if err < best[0]:
            best = (err, (i1, i2, i3))
    return best


def _error(seg, sides, split):
    k = sides.sum() / seg.sum()
    c = np.concatenate([[0.0], np.cumsum(seg)])
    i1, i2, i3 = split
    parts = np.array([c[i1], c[i2] - c[i1], c[i3] - c[i2], c[-1] - c[i3]])
    return np.sum((sides - k * parts) ** 2)


@settings(max_examples=150, deadline=None)
@given(st.integers(4, 22), st.integers(0, 2**31), st.floats(0.2, 5.0))
def test_split_is_the_exact_minimum(m, seed, aspect):
    rng = np.random.default_rng(seed)
    seg = rng.exponential(1.0, m) * (rng.random(m) > 0.15)     # some zero-length segments
    if seg.sum() == 0:
        seg[0] = 1.0
    sides = np.array([1.0, aspect, 1.0, aspect])
    split = split_chain(seg, sides)
    assert 0 < split[0] < split[1] < split[2] < m
    err_ref, _ = _brute_force(seg, sides)
    # both are sums of the same four squares; 1e-12 relative covers the rounding
    assert _error(seg, sides, split) <= err_ref * (1 + 1e-12) + 1e-15


def test_square_contour_of_a_square_is_the_identity():
    # a square contour subdivided 3 times per side, same size as the rectangle, clockwise
    rect = rectangle(2.0, 2.0)
    t = np.arange(3) / 3
    contour = np.concatenate([rect[j] + t[:, None] * (rect[(j + 1) % 4] - rect[j])
                              for j in range(4)])
    contour = np.roll(contour, 5, axis=0)   # start anywhere
    P, Q, start, split = correspond(contour, rect)
    assert start == 5 and np.array_equal(split, [3, 6, 9])
    assert np.abs(P - Q).max() <= 1e-15


def test_circle_on_square_quarters_and_ratios():
    th = -np.linspace(0, 2 * np.pi, 40, endpoint=False) + 5 * np.pi / 4   # clockwise
    contour = 1.0 + np.c_[np.cos(th), np.sin(th)]
    rect = rectangle(2.0, 2.0)
    assert start_vertex(contour, rect[0]) == 0
    P, Q, start, split = correspond(contour, rect)
    assert np.array_equal(split, [10, 20, 30])
    # corners land on the split vertices; each side keeps the part's length ratios
    assert np.allclose(Q[[0, 10, 20, 30]], rect, atol=1e-15)
    seg = np.hypot(*(np.roll(P, -1, 0) - P).T)
    qseg = np.hypot(*(np.roll(Q, -1, 0) - Q).T)
    assert np.allclose(qseg / seg, 2.0 * 4 / seg.sum(), rtol=1e-12)


def test_subdivision_of_zero_length_part_is_uniform():
    seg = np.array([1.0, 0.0, 0.0, 1.0, 1.0, 1.0])
    Q = subdivide_rectangle(rectangle(1.0, 1.0), seg, np.array([1, 3, 4]))
    assert np.allclose(Q[1:4], [[0, 1], [0.5, 1], [1, 1]])


def test_too_short_chain_refused():
    with pytest.raises(ValueError):
        split_chain(np.ones(3), np.ones(4))


def test_all_planes_at_once_equals_plane_by_plane():
    # fibres.slicing.morph.slice_maps (vectorised over planes) against correspond() per plane on
    # an irregular closed surface (a bumpy ellipsoid); and anchored_maps with the anchors
    # of the same surface reproduces the same correspondence
    import trimesh

    from fibres.slicing.contours import choose_loops
    from fibres.slicing.morph import _slice_maps_loop, anchored_maps, slice_maps
    from fibres.slicing.planes import mesh_topology, slice_mesh

    m = trimesh.creation.icosphere(subdivisions=4)
    v = np.asarray(m.vertices) * [0.03, 0.015, 0.1]
    v = v * (1 + 0.1 * np.sin(7 * m.vertices[:, [1]]) * np.cos(5 * m.vertices[:, [2]]))
    top = mesh_topology(m.faces, len(v))
    lo = v.min(axis=0)
    ext = v.max(axis=0) - lo
    tf = np.eye(4)
    tf[:3, 3] = lo
    sec = slice_mesh(v, top, tf, np.linspace(0.001, 0.999, 25) * ext[2])
    chosen, _ = choose_loops(sec, np.tile(ext[:2] / 2, (25, 1)), n_slices=25)
    P, Q, choice, (av, aw), notes = slice_maps(sec, chosen, ext, topology=top)
    P_ref, Q_ref, choice_ref, notes_ref = _slice_maps_loop(sec, chosen, ext, topology=top)
    assert np.array_equal(choice, choice_ref) and notes == notes_ref
    for a, b in zip(P, P_ref):
        # split positions from one running arc-length sum instead of per plane: rounding
        assert a.shape == b.shape and np.abs(a - b).max() <= 1e-12 * ext.max()
    for a, b in zip(Q, Q_ref):
        # arc lengths from one running sum instead of per plane: rounding only
        assert np.abs(a - b).max() <= 1e-12 * ext.max()
    # anchors are the material points of the chosen vertices: X = sum w V
    x = np.einsum("skn,sknd->skd", aw, v[av] - lo)[..., :2]
    assert np.abs(x[:, 0] - np.stack([p[0] for p in P])).max() <= 1e-15
    # inserting them again (same surface) gives the same map up to duplicate vertices and
    # the soft closest point's offset (Gaussian width SOFT_FLOOR * L at distance 0; measured
    # 1.3e-11 m on this 0.2 m mesh, so 1e-9 of the size bounds it with margin)
    P2, Q2, notes2 = anchored_maps(sec, chosen, ext, x, topology=top)
    assert notes2 == notes
    for s in range(25):
        pts = np.linspace(0.05, 0.95, 7)[:, None] * ext[:2]
        f1 = mean_value_coordinates(pts, Q[s]) @ P[s]
        f2 = mean_value_coordinates(pts, Q2[s]) @ P2[s]
        assert np.abs(f1 - f2).max() <= 1e-9 * ext.max()


def test_roll_and_subdivide_keeps_the_arc_length_ratios():
    # each contour starts at its start point (P = pts[roll], a rotation of the contour), and the
    # rectangle's four sides are subdivided like the contour's four parts: the point of Q at
    # local index j lies on side `part` at the part's arc-length fraction (measured here with
    # an independent loop over each contour)
    from fibres.slicing.morph import _roll_and_subdivide

    rng = np.random.default_rng(9)
    m = rng.integers(4, 60, 12)
    offs = np.concatenate([[0], np.cumsum(m)])
    t = np.concatenate([np.sort(rng.uniform(0, 2 * np.pi, k))[::-1] for k in m])
    r = 1.0 + 0.2 * rng.uniform(size=t.size)
    pts = np.c_[0.02 * r * np.cos(t) + 0.03, 0.01 * r * np.sin(t) + 0.02]
    start = rng.integers(0, m)
    rect = rectangle(0.06, 0.04)
    for given in (None, np.stack([np.sort(rng.choice(np.arange(1, k), 3, replace=False))
                                  for k in m])):
        P, Q, roll, split = _roll_and_subdivide(pts, m, offs, start, given, rect)
        np.testing.assert_array_equal(P, pts[roll])
        if given is not None:
            np.testing.assert_array_equal(split, given)
        for s in range(m.size):
            c = pts[offs[s]:offs[s + 1]]
            rolled = np.roll(c, -start[s], axis=0)
            np.testing.assert_array_equal(P[offs[s]:offs[s + 1]], rolled)
            seg = np.linalg.norm(np.roll(rolled, -1, axis=0) - rolled, axis=1)
            arc = np.concatenate([[0.0], np.cumsum(seg)])
            bounds = [0, *split[s], m[s]]
            for part in range(4):
                lo, hi = bounds[part], bounds[part + 1]
                a0, a1 = arc[lo], arc[hi]
                for j in range(lo, hi):
                    frac = (arc[j] - a0) / (a1 - a0)
                    want = rect[part] + frac * (rect[(part + 1) % 4] - rect[part])
                    np.testing.assert_allclose(Q[offs[s] + j], want, atol=1e-12)


def test_soft_anchor_points():
    # the anchor search of a plan (fibres.slicing.correspondence._soft_anchor_loop): anchors on the
    # contour give the hard closest point (the array version) to the Gaussian floor
    # (SOFT_FLOOR * L ~ 1e-9 m here); off the contour, a smooth function of the anchor
    # (central differences at two steps agree, where the hard argmin jumps); split points
    # in order after the start, ARC_GAP apart, inside their windows
    pytest.importorskip("numba")
    from fibres.slicing.correspondence import (ARC_GAP, ARC_WINDOW, SOFT_FLOOR, SOFT_SPREAD,
                                       anchor_kernel, closest_points)

    rng = np.random.default_rng(12)
    m = rng.integers(8, 40, 9)
    offs = np.concatenate([[0], np.cumsum(m)])
    t = np.concatenate([np.sort(rng.uniform(0, 2 * np.pi, k))[::-1] for k in m])
    pts = np.c_[0.02 * np.cos(t), 0.01 * np.sin(t)]
    frac = np.array([0.0, 0.2, 0.5, 0.7])
    on = np.stack([pts[offs[s] + (frac * m[s]).astype(int)] for s in range(m.size)])
    on[1, 1] = 0.5 * (pts[offs[1] + 1] + pts[offs[1] + 2])    # on an edge
    nominal = np.array([0.2, 0.5, 0.7])
    zn, zan = np.zeros((pts.shape[0], 1)), np.zeros((m.size, 4, 1))    # no normal filter
    kern = anchor_kernel()

    def run(anchors):
        return kern(pts, pts, zn, m, offs, anchors, zan, nominal, ARC_GAP, ARC_WINDOW,
                    SOFT_SPREAD, SOFT_FLOOR)

    seg, tk, point, moved = run(on)
    ref = closest_points(pts, m, offs, on)
    assert not moved.any()
    np.testing.assert_allclose(point, ref[2], atol=1e-9)
    # off the contour (1.2x outwards), moved along a smooth path: the start point is a
    # smooth function of the anchor (h / 2h central differences agree to O(h^2))
    out = 1.2 * on

    def start(e):
        a = out.copy()
        a[:, 0] += e * np.array([0.003, -0.002])
        return run(a)[2][:, 0]

    h = 1e-6
    d1 = (start(h) - start(-h)) / (2 * h)
    d2 = (start(2 * h) - start(-2 * h)) / (4 * h)
    assert np.abs(d1 - d2).max() <= 1e-4 * np.abs(d1).max()
    # random anchors: split points after the start, in order, >= ARC_GAP apart
    seg, tk, point, moved = run(rng.uniform(-0.03, 0.03, (m.size, 4, 2)))
    for s in range(m.size):
        p = pts[offs[s]:offs[s + 1]]
        seg_len = np.hypot(*(np.roll(p, -1, axis=0) - p).T)
        cum = np.concatenate([[0.0], np.cumsum(seg_len)])
        arc = cum[seg[s]] + tk[s] * seg_len[seg[s]]
        rel = (arc[1:] - arc[0]) % cum[-1]
        gaps = np.diff(np.concatenate([[0.0], rel, [cum[-1]]]))
        assert gaps.min() >= ARC_GAP * cum[-1] * (1 - 1e-9)
        off = (rel / cum[-1] - nominal + 0.5) % 1.0 - 0.5
        # (the window weight is taken at segment midpoints: one segment's overhang)
        assert np.abs(off).max() <= ARC_WINDOW + seg_len.max() / cum[-1] or moved[s]
        # the points lie on the contour
        np.testing.assert_allclose(point[s], p[seg[s]] + tk[s][:, None]
                                   * (np.roll(p, -1, axis=0)[seg[s]] - p[seg[s]]), atol=1e-15)



def test_order_arcs_is_the_bounded_isotonic_projection():
    # _order_arcs against a brute-force projection onto {lo <= a0 <= a1 <= a2 <= hi}
    # (scipy SLSQP on the same convex problem): identical to 1e-7 (the solver's tolerance);
    # ordered input is returned unchanged, and the map is 1-Lipschitz (a projection onto a
    # convex set), which is what keeps the anchored split points continuous
    from scipy.optimize import minimize

    from fibres.slicing.correspondence import _order_arcs

    rng = np.random.default_rng(5)
    A = np.array([[1.0, 0, 0], [-1, 1, 0], [0, -1, 1], [0, 0, -1]])
    for _ in range(40):
        a = rng.uniform(-0.5, 1.5, 3)
        got = _order_arcs(a, 0.0, 1.0)
        ref = minimize(lambda x: ((x - a) ** 2).sum(), np.full(3, 0.5), method="SLSQP",
                       constraints={"type": "ineq", "fun": lambda x: A @ x - [0, 0, 0, -1]},
                       options={"ftol": 1e-14}).x
        np.testing.assert_allclose(got, ref, atol=1e-7)
        b = a + rng.normal(0, 1e-3, 3)
        assert np.linalg.norm(_order_arcs(b, 0.0, 1.0) - got) <= np.linalg.norm(b - a) + 1e-15
    ordered = np.array([0.1, 0.4, 0.9])
    np.testing.assert_array_equal(_order_arcs(ordered, 0.0, 1.0), ordered)


def test_anchor_search_respects_the_normals():
    # a thin sheet: two long parallel faces 1 mm apart; an anchor 0.4 mm outside the lower
    # face but given the upper face's normal (+v) is matched on the upper face, 1.4 mm
    # away, not on the nearer lower face; without normals the nearer face is taken
    pytest.importorskip("numba")
    from fibres.slicing.correspondence import (ARC_GAP, SOFT_FLOOR, SOFT_SPREAD,
                                       anchor_kernel)

    x = np.linspace(0.0, 0.05, 26)
    top = np.c_[x, np.full_like(x, 0.001)]
    bottom = np.c_[x[::-1], np.zeros_like(x)]
    pts = np.concatenate([top, bottom])                    # clockwise: top to +u, back below
    normals = np.concatenate([np.tile([0.0, 1.0], (26, 1)), np.tile([0.0, -1.0], (26, 1))])
    m, offs = np.array([52]), np.array([0, 52])
    anchors = np.array([[[0.02, -0.0004]] * 4])
    nominal = np.array([0.25, 0.5, 0.75])
    up = np.array([[[0.0, 1.0]] * 4])
    seg, tk, point, _ = anchor_kernel()(pts, pts, normals, m, offs, anchors, up, nominal,
                                        ARC_GAP, 0.5, SOFT_SPREAD, SOFT_FLOOR)
    np.testing.assert_allclose(point[0, 0], [0.02, 0.001], atol=1e-9)
    seg, tk, point, _ = anchor_kernel()(pts, pts, np.zeros((52, 1)), m, offs, anchors,
                                        np.zeros((1, 4, 1)), nominal, ARC_GAP, 0.5,
                                        SOFT_SPREAD, SOFT_FLOOR)
    np.testing.assert_allclose(point[0, 0], [0.02, 0.0], atol=1e-9)


# --- the continuous rule (start at the exact closest point, splits at perimeter ratios) ---

def _circle(n, turn=0.0, r=1.0, c=(1.0, 1.0)):
    th = -np.linspace(0, 2 * np.pi, n, endpoint=False) + turn              # clockwise
    return np.asarray(c) + r * np.c_[np.cos(th), np.sin(th)]


def _refined(contour, rng, k):
    """The same closed curve with k extra vertices at random places on random edges,
    and the vertex order rolled (another meshing of the same section)."""
    m = len(contour)
    nxt = np.roll(contour, -1, axis=0)
    seg = np.sort(rng.integers(0, m, k))
    tau = rng.uniform(0.05, 0.95, k)
    pts = list(contour)
    for j, t in sorted(zip(seg, tau), key=lambda x: (-x[0], -x[1])):   # back to front
        pts.insert(j + 1, contour[j] + t * (nxt[j] - contour[j]))
    return np.roll(np.array(pts), int(rng.integers(0, m + k)), axis=0)


def test_continuous_rule_is_independent_of_the_meshing():
    # Issue #3: two meshings of the same contour curve must give the same map. With the
    # paper's vertex snapping they do not (the start and split vertices move by up to a
    # segment); with the continuous rule the start and split points are the same points
    # of the curve, and mean value coordinates do not change when a vertex is inserted on
    # an edge along which P is linear in Q, so the maps agree to rounding.
    from fibres.slicing.correspondence import correspond_continuous

    rng = np.random.default_rng(4)
    rect = rectangle(2.0, 1.2)
    x = rng.uniform(0.02, 0.98, (200, 2)) * [2.0, 1.2]
    # Q0's direction from the centre falls in the middle of a segment, where the inserted
    # vertices are nearer to Q0 than the segment's ends
    base = _circle(64, turn=np.arctan2(-0.6, -1.0) + np.pi / 64, r=0.5, c=(1.0, 0.6))
    P0, Q0, _, _ = correspond_continuous(base, rect)
    f0 = mean_value_coordinates(x, Q0) @ P0
    P3, Q3, _, _ = correspond(base, rect)
    g3 = mean_value_coordinates(x, Q3) @ P3
    vertex_rule = []
    for _ in range(5):
        other = _refined(base, rng, 40)
        P1, Q1, _, _ = correspond_continuous(other, rect)
        f1 = mean_value_coordinates(x, Q1) @ P1
        # the start's segment integrals (erf, erfcx: relative accuracy ~1e-11) are summed
        # over other pieces: measured 1.1e-10 on this unit-size contour
        assert np.abs(f1 - f0).max() <= 1e-9
        P2, Q2, _, _ = correspond(other, rect)            # the paper's vertex rule
        vertex_rule.append(np.abs(mean_value_coordinates(x, Q2) @ P2 - g3).max())
    # the vertex rule moves points by a good fraction of a segment (2 pi 0.5 / 64 = 0.05)
    assert max(vertex_rule) > 0.01


def test_continuous_rule_points():
    # start = soft closest point to Q0 (against a dense sampling of the contour); the
    # split points at arc lengths a0 + f_k L with f = corner fractions of the perimeter, so
    # that the paper's part errors (side_j - k length_j)^2 all vanish; the rectangle's
    # corners correspond to the four points
    from fibres.slicing.correspondence import correspond_continuous, split_fractions

    rng = np.random.default_rng(8)
    for _ in range(10):
        n = int(rng.integers(3, 30))
        th = -np.sort(rng.uniform(0, 2 * np.pi, n))
        contour = np.c_[np.cos(th), 0.6 * np.sin(th)] * rng.uniform(0.5, 2.0) + rng.normal(size=2)
        rect = rectangle(*rng.uniform(0.5, 3.0, 2))
        P, Q, seg, tau = correspond_continuous(contour, rect)
        assert P.shape == Q.shape == (n + 4, 2)
        nxt = np.roll(contour, -1, axis=0)
        dense = (contour[:, None] + np.linspace(0, 1, 2001)[None, :, None]
                 * (nxt - contour)[:, None]).reshape(-1, 2)
        d_dense = np.linalg.norm(dense - rect[0], axis=1).min()
        # the soft closest point (soft_start) is on the contour and near the closest point:
        # its weights fall off over SOFT_SPREAD * d_min = d_min / 2, so on these smooth
        # convex contours it is within a few % of the distance (measured < 1 %)
        d = np.linalg.norm(P[0] - rect[0])
        step = np.linalg.norm(nxt - contour, axis=1).max() / 2000
        assert d_dense - step <= d <= 1.05 * d_dense + 1e-12
        np.testing.assert_allclose(P[0], contour[seg[0]] + tau[0] * (nxt[seg[0]] - contour[seg[0]]),
                                   atol=1e-14)
        corner = [int(np.flatnonzero(np.all(Q == c, axis=1))[0]) for c in rect]
        assert corner[0] == 0 and corner == sorted(corner)
        arc = np.concatenate([[0.0], np.cumsum(np.hypot(*(np.roll(P, -1, 0) - P).T))])
        sides = np.hypot(*(np.roll(rect, -1, axis=0) - rect).T)
        parts = np.diff(np.r_[arc[corner], arc[-1]])
        k = sides.sum() / arc[-1]
        np.testing.assert_allclose(k * parts, sides, rtol=1e-12)        # zero part errors
        np.testing.assert_allclose(arc[corner[1:]] / arc[-1], split_fractions(rect), rtol=1e-12)


def test_continuous_rule_on_the_rectangle_itself_is_the_identity():
    # a contour equal to the rectangle (sides subdivided unevenly, any start): P0 is Q0
    # itself, the splits land on the corners, so P = Q and the map is the identity
    from fibres.slicing.correspondence import correspond_continuous

    rect = rectangle(2.0, 0.7)
    t = np.array([0.0, 0.3, 0.45, 0.8])
    contour = np.concatenate([rect[j] + t[:, None] * (rect[(j + 1) % 4] - rect[j])
                              for j in range(4)])
    P, Q, _, _ = correspond_continuous(np.roll(contour, 7, axis=0), rect)
    assert np.abs(P - Q).max() <= 1e-15


def test_soft_start_is_the_closest_point_where_defined_and_continuous_where_not():
    # fibres.slicing.correspondence.soft_start: on a finely meshed circle with Q0 outside in the
    # direction of a vertex, the weights are symmetric about that vertex, so the soft point
    # is the closest point itself (to rounding of the exact segment integrals); on a
    # dumbbell whose two lobes are equally near Q0 the hard closest point jumps from one
    # lobe to the other as Q0 moves, the soft one moves continuously (through the waist)
    from fibres.slicing.correspondence import closest_points, soft_start

    n = 720
    circle = _circle(n, turn=np.pi / 4 + np.pi, c=(0.0, 0.0))                 # vertex 0 at 225 deg
    one = (np.array([n]), np.array([0, n]))
    seg, tau, point = soft_start(circle, *one, np.array([-2.0, -2.0]))
    np.testing.assert_allclose(point[0], circle[0], atol=1e-12)
    th = -np.linspace(0, 2 * np.pi, 400, endpoint=False)
    r = 1.0 + 0.9 * np.cos(2 * th)                                           # lobes at +-u
    bell = np.c_[r * np.cos(th), r * np.sin(th)]
    one = (np.array([400]), np.array([0, 400]))
    q0 = np.array([0.0, -1.2])        # the lobes' bottoms 0.75 away, the waist 1.1

    def start(x):
        return soft_start(bell, *one, q0 + [x, 0.0])[2][0]

    def hard(x):
        return closest_points(bell, *one, (q0 + [x, 0.0])[None, None])[2][0, 0]

    assert np.linalg.norm(hard(1e-3) - hard(-1e-3)) > 0.5                    # jumps lobes
    # no jump where the hard point switches lobes: the step over 2e-7 is the slope over
    # 2e-3 times the step (Lipschitz; sigma follows the hard distance, which has a kink
    # there, so the soft point has one too, but no jump)
    slope = np.linalg.norm(start(1e-3) - start(-1e-3)) / 2e-3
    assert 1.0 < slope < 100.0
    assert np.linalg.norm(start(1e-7) - start(-1e-7)) <= 2.0 * slope * 2e-7



def test_soft_start_compiled_equals_python():
    # the compiled start loop and the same loop run by Python: the same arithmetic
    pytest.importorskip("numba")
    from fibres.slicing.correspondence import ratio_points, soft_start

    rng = np.random.default_rng(17)
    m = rng.integers(3, 40, 7)
    offs = np.concatenate([[0], np.cumsum(m)])
    t = np.concatenate([-np.sort(rng.uniform(0, 2 * np.pi, k)) for k in m])
    pts = np.c_[0.02 * np.cos(t), 0.01 * np.sin(t)] + rng.normal(0, 0.002, (t.size, 2))
    q0 = np.array([-0.03, -0.02])
    for a, b in zip(soft_start(pts, m, offs, q0), soft_start(pts, m, offs, q0, compiled=False)):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-15)
    # the split points found in the same pass equal `ratio_points` (arc lengths summed per
    # contour instead of over all contours: rounding, 1e-12 of the 0.1 m size)
    f = np.array([0.2, 0.55, 0.7])
    seg, tau, point = soft_start(pts, m, offs, q0, fractions=f)
    rs, rt, rp = ratio_points(pts, m, offs, seg[:, 0], tau[:, 0], f)
    np.testing.assert_allclose(point[:, 1:], rp, rtol=0, atol=1e-13)
    np.testing.assert_allclose(point[:, 0], soft_start(pts, m, offs, q0)[2], rtol=0, atol=0)


def test_ratio_points_with_fractions_per_plane():
    # (S, F) fractions: each plane's points are those of a one-plane call with its own row;
    # and each point lies at arc a0 + f L from the start (checked against the cumulated
    # segment lengths, to rounding: 1e-12 of the lengths, which are O(1))
    from fibres.slicing.correspondence import ratio_points

    rng = np.random.default_rng(3)
    loops = []
    for _ in range(5):
        n = int(rng.integers(4, 25))
        th = -np.sort(rng.uniform(0, 2 * np.pi, n))
        loops.append(np.c_[np.cos(th), 0.7 * np.sin(th)] * rng.uniform(0.5, 2.0))
    m = np.array([len(c) for c in loops])
    offs = np.concatenate([[0], np.cumsum(m)])
    pts = np.concatenate(loops)
    seg0 = np.array([int(rng.integers(0, k)) for k in m])
    tau0 = rng.uniform(0, 1, m.size)
    fr = np.sort(rng.uniform(0, 1, (m.size, 3)), axis=1)
    seg, tau, point = ratio_points(pts, m, offs, seg0, tau0, fr)
    for s, c in enumerate(loops):
        one = ratio_points(c, m[s:s + 1], np.array([0, m[s]]), seg0[s:s + 1], tau0[s:s + 1],
                           fr[s])
        np.testing.assert_array_equal(seg[s], one[0][0])
        np.testing.assert_allclose(point[s], one[2][0], rtol=0, atol=1e-14)
        seg_len = np.hypot(*(np.roll(c, -1, axis=0) - c).T)
        cum = np.concatenate([[0.0], np.cumsum(seg_len)])
        arc = lambda j, t: cum[j] + t * seg_len[j]                      # noqa: E731
        want = (arc(seg0[s], tau0[s]) + fr[s] * cum[-1]) % cum[-1]
        np.testing.assert_allclose(arc(seg[s], tau[s]), want, rtol=0, atol=1e-12)


def _lobed_stack(n_s=9, lobe_from=5, n=120):
    """Clockwise ellipses in the box [0, 3] x [0, 2], all alike except that planes
    ``>= lobe_from`` carry a lobe (a radial bump of 0.8) between the start (near Q0) and the
    first split point; with the start and split points of `soft_start`."""
    from fibres.slicing.correspondence import soft_start, split_fractions

    rect = rectangle(3.0, 2.0)
    th = -np.linspace(0, 2 * np.pi, n, endpoint=False)             # clockwise
    loops = []
    for s in range(n_s):
        # the lobe centred at angle 200 degrees (the start is near 225, Q0 = (0, 0))
        bump = 0.8 * np.exp(-((np.angle(np.exp(1j * (th - np.deg2rad(200))))) / 0.25) ** 2)
        r = 1.0 + (bump if s >= lobe_from else 0.0)
        loops.append(np.c_[1.5 + 1.2 * r * np.cos(th), 1.0 + 0.8 * r * np.sin(th)])
    m = np.full(n_s, n)
    offs = np.concatenate([[0], np.cumsum(m)])
    pts = np.concatenate(loops)
    seg, tau, point = soft_start(pts, m, offs, rect[0], fractions=split_fractions(rect))
    return pts, m, offs, seg, tau, point


def test_split_smoothing_off_is_the_identity_and_alike_planes_stay():
    from fibres.slicing.correspondence import SPLIT_SMOOTHING, smooth_split_points

    pts, m, offs, seg, tau, point = _lobed_stack()
    assert SPLIT_SMOOTHING["iterations"] == 0                  # off by default (docstring)
    s0, t0, p0 = smooth_split_points(pts, m, offs, seg, tau, point)
    np.testing.assert_array_equal(s0, seg)
    np.testing.assert_array_equal(t0, tau)
    np.testing.assert_array_equal(p0, point)
    # identical contours: each neighbour's split point lies on this contour, so the average
    # is the point itself (to rounding of the closest-point projection, ~1e-15 of the size)
    pts1, m1, offs1, seg1, tau1, point1 = _lobed_stack(lobe_from=99)
    s1, t1, p1 = smooth_split_points(pts1, m1, offs1, seg1, tau1, point1, iterations=3)
    np.testing.assert_allclose(p1, point1, rtol=0, atol=1e-12)


def test_split_smoothing_spreads_a_lobe_jump_and_keeps_the_order():
    # the perimeter-ratio rule moves every split point after the lobe along the contour
    # between planes 4 and 5; smoothed along the axis the split points' spatial step there
    # is spread over the neighbouring planes (measured: one step of 0.67 -> largest step
    # 0.19, box 3 x 2), the start is kept and the four points stay in clockwise order
    from fibres.slicing.correspondence import smooth_split_points

    pts, m, offs, seg, tau, point = _lobed_stack()
    s3, t3, p3 = smooth_split_points(pts, m, offs, seg, tau, point, iterations=3)
    np.testing.assert_array_equal(p3[:, 0], point[:, 0])
    step_ratio = np.linalg.norm(np.diff(point[:, 1:], axis=0), axis=-1).max(axis=1)
    step_smooth = np.linalg.norm(np.diff(p3[:, 1:], axis=0), axis=-1).max(axis=1)
    assert step_ratio[4] > 0.5 and np.delete(step_ratio, 4).max() < 1e-9   # one jump
    assert step_smooth.max() <= 0.4 * step_ratio[4]
    for s in range(m.size):
        c = pts[offs[s]:offs[s + 1]]
        seg_len = np.hypot(*(np.roll(c, -1, axis=0) - c).T)
        cum = np.concatenate([[0.0], np.cumsum(seg_len)])
        arc = cum[s3[s]] + t3[s] * seg_len[s3[s]]
        rel = (arc - arc[0]) % cum[-1]
        assert (np.diff(rel) > 0).all()
        # each point lies on its contour's segment
        nxt = np.roll(c, -1, axis=0)
        np.testing.assert_allclose(p3[s], c[s3[s]] + t3[s][:, None] * (nxt[s3[s]] - c[s3[s]]),
                                   atol=1e-12)


def test_split_smoothing_straightens_the_lhdl_gluteus_medius(lhdl_dir, monkeypatch):
    # the zig-zag: 95th percentile of the turning angle between consecutive fibre
    # segments, measured 15.1 degrees with the ratio rule and 9.8 with 3 iterations
    # (bench/render_lhdl.py's inputs); bounds halfway
    import warnings

    import pandas as pd

    from fibres import as_surface, decompose
    from fibres.slicing.correspondence import SPLIT_SMOOTHING

    tab = pd.read_csv(lhdl_dir / "attachments" / "attachment_landmarks.csv")
    rows = tab[tab.muscle == "glut_med_r"]
    o = rows[rows.type == "origin"][["x_mm", "y_mm", "z_mm"]].to_numpy(float)
    i = rows[rows.type == "insertion"][["x_mm", "y_mm", "z_mm"]].to_numpy(float)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        surface = as_surface(lhdl_dir / "muscles" / "glut_med_r.vtk", units="mm")

    def turning_p95():
        p = decompose(surface, o, i, units="mm", template="fanned", n_fibres=100,
                          slicing="planes").points
        d = np.diff(p, axis=1)
        d /= np.linalg.norm(d, axis=2, keepdims=True)
        cos = np.clip(np.einsum("nkd,nkd->nk", d[:, 1:], d[:, :-1]), -1.0, 1.0)
        return np.percentile(np.degrees(np.arccos(cos)), 95)

    before = turning_p95()
    monkeypatch.setitem(SPLIT_SMOOTHING, "iterations", 3)
    after = turning_p95()
    assert before > 12.5 and after < 12.5



def _bumpy_sections(n_s=25, seed=None):
    import trimesh

    from fibres.slicing.contours import choose_loops
    from fibres.slicing.planes import mesh_topology, slice_mesh

    m = trimesh.creation.icosphere(subdivisions=4)
    v = np.asarray(m.vertices) * [0.03, 0.015, 0.1]
    v = v * (1 + 0.1 * np.sin(7 * m.vertices[:, [1]]) * np.cos(5 * m.vertices[:, [2]]))
    if seed is not None:
        v = v + np.random.default_rng(seed).normal(0, 2e-4, v.shape)
    top = mesh_topology(m.faces, len(v))
    lo = v.min(axis=0)
    ext = v.max(axis=0) - lo
    tf = np.eye(4)
    tf[:3, 3] = lo
    sec = slice_mesh(v, top, tf, np.linspace(0.001, 0.999, n_s) * ext[2])
    chosen, _ = choose_loops(sec, np.tile(ext[:2] / 2, (n_s, 1)), n_slices=n_s)
    return sec, chosen, ext, top



def test_soft_start_float_modulo_is_pythons():
    # the soft start's `x % length` without fmod where |x| < length: Python's float modulo
    # bit for bit (signed zeros, the bounds, far outside, both signs)
    pytest.importorskip("numba")
    from fibres.slicing import correspondence_kernels as ck

    ck._start_kernel()
    rng = np.random.default_rng(4)
    for length in (1.0, 0.3, 7.25e-3, 123.456):
        x = np.r_[rng.uniform(-2.5, 2.5, 3000) * length, 0.0, -0.0, length, -length,
                  np.nextafter(length, 0), -np.nextafter(length, 0), 5e-324, -5e-324,
                  1e30, -1e30]
        for v in x:
            got, ref = ck._mod(float(v), length), float(v) % length
            assert got == ref and np.signbit(got) == np.signbit(ref), (v, length)
