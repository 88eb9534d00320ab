"""Mean value coordinates (Hormann & Floater 2006): analytic and property checks."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from fibres.slicing import mvc
from fibres.slicing.mvc import mean_value_coordinates


@pytest.fixture(autouse=True)
def _strict(monkeypatch):
    monkeypatch.setattr(mvc, "strict", True)


def _reference(x, poly):
    """Direct evaluation with angles from atan2 (H&F 2006 eq. for w_i), one point at a time."""
    s = poly - x
    r = np.linalg.norm(s, axis=1)
    sn = np.roll(s, -1, axis=0)
    alpha = np.arctan2(s[:, 0] * sn[:, 1] - s[:, 1] * sn[:, 0], (s * sn).sum(axis=1))
    w = (np.tan(np.roll(alpha, 1) / 2) + np.tan(alpha / 2)) / r
    return w / w.sum()


SQUARE = np.array([[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]])   # clockwise
# a non-convex "L" / arrow shape, counter-clockwise
ARROW = np.array([[0, 0], [4, 0], [4, 1], [1.5, 1.2], [4, 3], [0, 3], [1, 1.5]], float)


def test_square_centre_and_closed_form():
    lam = mean_value_coordinates(np.array([[0.5, 0.5]]), SQUARE)
    # symmetry: the centre has equal coordinates (exact up to rounding)
    assert np.allclose(lam, 0.25, atol=1e-15)
    rng = np.random.default_rng(3)
    pts = rng.uniform(0.01, 0.99, (200, 2))
    lam = mean_value_coordinates(pts, SQUARE)
    ref = np.array([_reference(p, SQUARE) for p in pts])
    # two evaluations of the same closed form, 1e-12 covers rounding in tan(alpha/2)
    assert np.abs(lam - ref).max() <= 1e-12


@pytest.mark.parametrize("poly", [SQUARE, ARROW, ARROW[::-1]])
def test_linear_precision_and_partition_of_unity(poly):
    rng = np.random.default_rng(0)
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    pts = rng.uniform(lo, hi, (500, 2))
    lam = mean_value_coordinates(pts, poly)
    assert np.abs(lam.sum(axis=1) - 1).max() <= 1e-12
    assert np.abs(lam @ poly - pts).max() <= 1e-12 * np.abs(poly).max()
    # any linear function f(x) = a.x + b is reproduced
    a, b = np.array([0.3, -1.7]), 0.25
    assert np.abs(lam @ (poly @ a + b) - (pts @ a + b)).max() <= 1e-12 * 10


@pytest.mark.parametrize("poly", [SQUARE, ARROW])
def test_exact_on_vertices_and_edges(poly):
    lam = mean_value_coordinates(poly, poly)
    assert np.array_equal(lam, np.eye(len(poly)))
    t = np.array([0.0, 0.25, 0.5, 0.9])
    nxt = np.roll(poly, -1, axis=0)
    for i in range(len(poly)):
        pts = poly[i] + t[1:, None] * (nxt[i] - poly[i])
        lam = mean_value_coordinates(pts, poly)
        expected = np.zeros((3, len(poly)))
        expected[:, i] = 1 - t[1:]
        expected[:, (i + 1) % len(poly)] += t[1:]
        assert np.abs(lam - expected).max() <= 1e-15


def test_non_convex_has_negative_weights_but_reproduces():
    # inside the notch of the arrow some coordinates are negative (H&F 2006 fig. 5) yet
    # the point is still reproduced exactly
    pt = np.array([[1.2, 1.5]])
    lam = mean_value_coordinates(pt, ARROW)
    assert lam.min() < 0
    assert np.abs(lam @ ARROW - pt).max() <= 1e-13


@settings(max_examples=60, deadline=None)
@given(st.integers(min_value=3, max_value=40), st.integers(min_value=0, max_value=2**31))
def test_random_star_shaped_polygons(k, seed):
    rng = np.random.default_rng(seed)
    angles = np.sort(rng.uniform(0, 2 * np.pi, k))
    gaps = np.diff(np.append(angles, angles[0] + 2 * np.pi))
    # near-equal angles make a near-radial spike: points beside it lose ~1e-10 to
    # cancellation (seed 52868, k=17: 3.6e-10), a conditioning limit of the formula, not
    # the rule under test -- such polygons are replaced by evenly spread angles
    if gaps.max() >= np.pi * 0.95 or gaps.min() < 1e-3:
        angles = np.linspace(0, 2 * np.pi, k, endpoint=False) + rng.uniform(0, 0.1)
    radii = rng.uniform(0.3, 2.0, k)
    poly = np.c_[radii * np.cos(angles), radii * np.sin(angles)]
    # points inside: star-shaped w.r.t. the origin -> shrink random boundary points
    j = rng.integers(0, k, 50)
    t = rng.uniform(0, 1, 50)
    u = rng.uniform(0.0, 0.999, 50)
    boundary = poly[j] + t[:, None] * (np.roll(poly, -1, axis=0)[j] - poly[j])
    pts = u[:, None] * boundary
    lam = mean_value_coordinates(pts, poly)
    assert np.abs(lam.sum(axis=1) - 1).max() <= 1e-12
    assert np.abs(lam @ poly - pts).max() <= 1e-12 * 2.0 * 10


def test_shapes_are_checked():
    with pytest.raises(ValueError):
        mean_value_coordinates(np.zeros((3, 3)), SQUARE)
    with pytest.raises(ValueError):
        mean_value_coordinates(np.zeros((3, 2)), SQUARE[:2])


def test_mvc_map_equals_coordinates_times_targets():
    from fibres.slicing.mvc import mvc_map

    rng = np.random.default_rng(5)
    polys = [SQUARE * 2.0, ARROW, ARROW[::-1] * 0.5]
    targets = [p + 0.1 * np.sin(3 * p[:, ::-1]) for p in polys]
    groups = rng.integers(0, 3, 400)
    pts = np.empty((400, 2))
    for g, p in enumerate(polys):
        sel = groups == g
        pts[sel] = rng.uniform(p.min(axis=0), p.max(axis=0), (sel.sum(), 2))
    # include exact vertices and edge points of group 1
    pts[:7], groups[:7] = ARROW, 1
    pts[7], groups[7] = 0.25 * ARROW[2] + 0.75 * ARROW[3], 1
    weights = rng.uniform(0, 1, 400)
    got = mvc_map(pts, groups, polys, targets, weights=weights)
    for g, p in enumerate(polys):
        sel = groups == g
        ref = weights[sel, None] * (mean_value_coordinates(pts[sel], p) @ targets[g])
        # the compiled loop and the array expression sum the same terms in another order
        assert np.abs(got[sel] - ref).max() <= 1e-12
    assert np.array_equal(got[:7], weights[:7, None] * targets[1])



def test_packed_planes_map_like_separate_polygons():
    # `planes` views of one array skip mvc_map's concatenation: the same result bit for bit
    # as the separate polygons (and the views are the rows they name)
    from fibres.slicing.mvc import mvc_map, planes

    rng = np.random.default_rng(9)
    pts = rng.uniform(0.05, 0.95, (200, 2)) * [4, 3]
    groups = rng.integers(0, 2, 200)
    src, dst = [ARROW, SQUARE * 3], [ARROW * 2 + 1, SQUARE[::-1] * 3]
    offs = np.cumsum([0, len(ARROW), len(SQUARE)])
    ps, pd = planes(np.concatenate(src), offs), planes(np.concatenate(dst), offs)
    assert all(np.array_equal(a, b) for a, b in zip(ps, src)) and len(ps) == 2
    np.testing.assert_array_equal(mvc_map(pts, groups, ps, pd), mvc_map(pts, groups, src, dst))


def _array_oracle(points, polygon):
    """The coordinates as one array expression over all points and edges (the package's
    implementation before it was compiled; same formula, same special cases)."""
    pts, poly = np.asarray(points, float), np.asarray(polygon, float)
    k = len(poly)
    nxt = np.append(np.arange(1, k), 0)
    prv = np.append(k - 1, np.arange(k - 1))
    sx, sy = poly[:, 0] - pts[:, 0, None], poly[:, 1] - pts[:, 1, None]
    sxn, syn = sx[:, nxt], sy[:, nxt]
    r = np.sqrt(sx * sx + sy * sy)
    rr = r * r[:, nxt]
    cross, dot = sx * syn - sy * sxn, sx * sxn + sy * syn
    denom = rr + dot
    on_edge = ((np.abs(cross) <= 1e-14 * rr) | (denom <= 0.0)) & (dot < 0.0) & (rr > 0.0)
    on_vertex = r == 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        tan_half = np.where(denom > 0.0, cross / np.where(denom > 0.0, denom, 1.0), 0.0)
        w = (tan_half[:, prv] + tan_half) / np.where(on_vertex, 1.0, r)
        lam = w / w.sum(axis=1, keepdims=True)
    for row in np.flatnonzero(on_vertex.any(axis=1) | on_edge.any(axis=1)):
        lam[row] = 0.0
        if on_vertex[row].any():
            lam[row, np.argmax(on_vertex[row])] = 1.0
        else:
            e = np.argmax(on_edge[row])
            ra, rb = r[row, e], r[row, (e + 1) % k]
            lam[row, e] = rb / (ra + rb)
            lam[row, (e + 1) % k] += ra / (ra + rb)
    return lam


@pytest.mark.parametrize("poly", [SQUARE, ARROW, ARROW[::-1] * 3.0])
def test_compiled_loop_equals_the_array_oracle(poly):
    # the compiled loop evaluates the same terms in the same order as the array expression,
    # so the two agree to rounding (1e-13 of coordinates of order 1); vertices, edge points
    # and a coincident pair of polygon vertices take the special branches
    rng = np.random.default_rng(11)
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    t = rng.uniform(0, 1, (40, 1))
    j = np.arange(40) % len(poly)
    edge_pts = poly[j] + t * (np.roll(poly, -1, axis=0)[j] - poly[j])
    pts = np.concatenate([rng.uniform(lo, hi, (300, 2)), poly, edge_pts])
    np.testing.assert_allclose(mean_value_coordinates(pts, poly), _array_oracle(pts, poly),
                               rtol=0, atol=1e-13)
    doubled = np.insert(poly, 2, poly[2], axis=0)
    np.testing.assert_allclose(mean_value_coordinates(pts, doubled),
                               _array_oracle(pts, doubled), rtol=0, atol=1e-13)
