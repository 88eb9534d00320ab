"""Harmonic-field slicing (`fibres.slicing.harmonic`) and the fibre quality numbers.

Expected values are analytic (a cylinder's linear field, straight fibres, areas of disks),
properties (single isoline loops, points inside), or the LHDL muscles' measured quality with
a margin stated next to each assertion.
"""
import warnings

import numpy as np
import pytest
from test_decompose_analytic import arc, cap_ring, rotation, straight, tube

from fibres import HarmonicPlan, decompose, make_plan
from fibres.slicing.harmonic_field import harmonic_field, mesh_edges
from fibres.mesh.inside import inside_grid
from fibres.slicing.isolines import isoline_loops
from fibres.finishing.quality import fibre_quality

RHO, L = 0.01, 0.1


def _disk(z, n=5):
    g = np.linspace(-0.8 * RHO, 0.8 * RHO, n)
    x, y = np.meshgrid(g, g)
    keep = np.hypot(x, y) < 0.85 * RHO
    return np.c_[x[keep], y[keep], np.full(keep.sum(), z)]


def _circle(th):
    return np.c_[RHO * np.cos(th), RHO * np.sin(th)]


def test_field_is_linear_along_a_straight_cylinder():
    """Caps fixed at 0 and 1: the harmonic function of the side is (z - z0) / L exactly (a
    linear function of the unrolled side, and the cotangent Laplacian reproduces linear
    functions on a flat mesh; the structured tube has right triangles, no clipped weights)."""
    v, f = tube(_circle, *straight(L), n_sect=48, n_path=41)
    zero = v[:, 2] <= 1e-12
    one = v[:, 2] >= L - 1e-12
    u = harmonic_field(v, f, zero, one)
    np.testing.assert_allclose(u, v[:, 2] / L, atol=1e-9)


def test_isolines_of_the_cylinder_are_circles():
    v, f = tube(_circle, *straight(L), n_sect=48, n_path=41)
    u = harmonic_field(v, f, v[:, 2] <= 1e-12, v[:, 2] >= L - 1e-12)
    edges, face_edges = mesh_edges(f, len(v))
    for t in (0.13, 0.5, 0.91):
        loops = isoline_loops(u, f, t, edges, face_edges, v)
        assert len(loops) == 1
        p = loops[0].points(v)
        np.testing.assert_allclose(p[:, 2], t * L, atol=1e-12)
        # the chords of a circle's inscribed 48-gon lie within rho (1 - cos(pi / 48)) of it
        r = np.hypot(p[:, 0], p[:, 1])
        assert np.all(r <= RHO + 1e-12) and np.all(r >= RHO * np.cos(np.pi / 48) - 1e-12)


def _loops_oracle(u, faces, level, edges, face_edges):
    """The isoline's loops by array code and a graph library (the package's implementation
    before its walk was compiled): crossed edges, each crossed face's falling -> rising link,
    weakly connected components, each walked from its smallest crossed edge."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    above = u >= level
    cross = above[edges[:, 0]] != above[edges[:, 1]]
    hit = np.flatnonzero(cross[face_edges].any(axis=1))
    ab = above[faces[hit]]
    rising = ~ab & np.roll(ab, -1, axis=1)
    falling = ab & ~np.roll(ab, -1, axis=1)
    fe = face_edges[hit]
    src = fe[np.arange(hit.size), falling.argmax(axis=1)]
    dst = fe[np.arange(hit.size), rising.argmax(axis=1)]
    nodes = np.flatnonzero(cross)
    index = np.full(len(edges), -1)
    index[nodes] = np.arange(nodes.size)
    nxt = np.empty(nodes.size, dtype=np.int64)
    nxt[index[src]] = index[dst]
    face = np.empty(nodes.size, dtype=np.int64)
    face[index[src]] = hit
    m = nodes.size
    _, label = connected_components(coo_matrix((np.ones(m), (np.arange(m), nxt)), (m, m)),
                                    directed=True, connection="weak")
    out = []
    for lab in range(label.max() + 1):
        members = np.flatnonzero(label == lab)
        order, k = [], members[0]
        for _ in members:
            order.append(k)
            k = nxt[k]
        out.append((nodes[order], face[order]))
    return out


def test_isoline_walk_equals_the_graph_oracle():
    """The compiled walk lists the same loops, points and faces in the same order as the
    graph oracle (exact: both are index bookkeeping), on a bent tube's field at levels with
    one loop and on a field of the height with two loops (a U-shaped tube cut across both
    arms)."""
    v, f = tube(_circle, *arc(L, np.pi), n_sect=24, n_path=31)
    edges, face_edges = mesh_edges(f, len(v))
    ring = np.arange(len(v)) // 24                       # section of each vertex; the caps' centres last
    zero = (ring == 0) | (np.arange(len(v)) == len(v) - 2)
    one = (ring == 30) | (np.arange(len(v)) == len(v) - 1)
    fields = [harmonic_field(v, f, zero, one),
              (v[:, 1] - v[:, 1].min()) / np.ptp(v[:, 1])]
    counts = set()
    for u in fields:
        for t in np.linspace(0.02, 0.98, 25):
            got = isoline_loops(u, f, t, edges, face_edges)
            want = _loops_oracle(u, f, t, edges, face_edges)
            counts.add(len(got))
            assert len(got) == len(want)
            for lp, (e, face) in zip(got, want):
                np.testing.assert_array_equal(lp.a, edges[e, 0])
                np.testing.assert_array_equal(lp.b, edges[e, 1])
                np.testing.assert_array_equal(lp.face, face)
    assert counts >= {1, 2}


def test_isoline_moments_of_a_straight_cylinder():
    """A straight cylinder's isoline at level t is the section circle at height t L: centroid
    on the axis, length and vector area those of the inscribed polygon."""
    from fibres.slicing.isolines import isoline_moments

    v, f = tube(_circle, *straight(L), n_sect=48, n_path=41)
    u = harmonic_field(v, f, v[:, 2] <= 1e-12, v[:, 2] >= L - 1e-12)
    length, centre, area = isoline_moments(u, v, f, np.array([0.25, 0.6]))
    np.testing.assert_allclose(centre, [[0, 0, 0.25 * L], [0, 0, 0.6 * L]], atol=1e-12)
    # the inscribed 48-gon: perimeter 2 n rho sin(pi / n), area n rho^2 sin(2 pi / n) / 2
    np.testing.assert_allclose(length, 2 * 48 * RHO * np.sin(np.pi / 48), rtol=1e-9)
    np.testing.assert_allclose(np.abs(area[:, 2]), 24 * RHO ** 2 * np.sin(2 * np.pi / 48),
                               rtol=1e-9)


def test_straight_cylinder_gives_straight_axial_fibres():
    """Landmarks on both caps: every fibre is a straight segment along the axis, from cap to
    cap (the loops are equal circles, the membranes and their area maps equal)."""
    v, f = tube(_circle, *straight(L), n_sect=64, n_path=41)
    b = decompose((v, f), _disk(0.0), _disk(L), n_fibres=50, resolution=10)
    p = b.points
    # the fibres' xy stays put along each fibre: every section and both caps are spread by
    # the same area map (Knothe-Rosenblatt on a disk), up to the sampling of the measures
    # (caps: the mesh's fan triangles; sections: a 16 x 16 membrane grid, cells ~1.3 mm),
    # the Lloyd steps of the ends (up to ~1.8 mm each, the same on both caps to ~0.3 mm,
    # carried along the fibre) and the containment pull of points within 0.2 mm of the
    # wall: 1 mm on a 10 mm radius (turns below 2 degrees, checked below)
    assert np.abs(p[:, :, :2] - p[:, :1, :2]).max() < 1e-3
    np.testing.assert_allclose(p[:, 0, 2], 0.0, atol=1e-9)
    np.testing.assert_allclose(p[:, -1, 2], L, atol=1e-9)
    assert b.quality.turn_max < 2.0
    assert b.quality.outside == 0
    assert isinstance(b.plan, HarmonicPlan)


def test_plan_reuse_follows_a_rigid_motion_exactly():
    """The plan's fibres are a fixed linear map of the vertices: a rotated and shifted copy of
    the mesh gives the rotated and shifted fibres (to round-off; smoothing and the
    containment pull commute with rigid motions)."""
    v, f = tube(_circle, *arc(0.08, np.pi / 2), n_sect=48, n_path=40)
    e1, e2 = np.array([0, 0, 1.0]), np.array([1.0, 0, 0])
    o = cap_ring(v[:-2][:48].mean(axis=0), e1, e2, 0.6 * RHO)
    end = v[:-2][-48:].mean(axis=0)
    i = cap_ring(end, e1, np.array([0, 1.0, 0]), 0.6 * RHO)
    b0 = decompose((v, f), o, i, n_fibres=30, resolution=12)
    rot = rotation([1, 2, 3], 0.7)
    shift = np.array([0.3, -0.1, 0.2])
    b1 = decompose((v @ rot.T + shift, f), o @ rot.T + shift, i @ rot.T + shift,
                   n_fibres=30, resolution=12, plan=b0.plan)
    np.testing.assert_allclose(b1.points, b0.points @ rot.T + shift, atol=1e-9)


def test_bent_tube_fibres_stay_inside_and_fill_it():
    """A quarter torus (tube radius 10 mm on an 80 mm bend): no fibre point outside, the
    sharpest turn is the bend's own (90 degrees over 12 segments: 7.5 per joint, 15 with
    the ends' bending), and at most 5 % of the volume farther than 5 mm from a fibre (the
    tube's 10 mm radius: fibres spaced ~2.3 mm)."""
    v, f = tube(_circle, *arc(0.08, np.pi / 2), n_sect=48, n_path=40)
    c0, c1 = v[-2], v[-1]
    o = c0 + np.c_[0.6 * RHO * np.cos(np.linspace(0, 6, 12)), np.zeros(12),
                   0.6 * RHO * np.sin(np.linspace(0, 6, 12))]
    i = c1 + np.c_[np.zeros(12), 0.6 * RHO * np.cos(np.linspace(0, 6, 12)),
                   0.6 * RHO * np.sin(np.linspace(0, 6, 12))]
    b = decompose((v, f), o, i, n_fibres=100, resolution=12)
    q = b.quality
    assert q.outside == 0
    assert q.turn_max < 15.0
    assert q.empty_5mm <= 0.05
    # and by VTK's enclosed-points test (an independent ray-parity implementation)
    import pyvista as pv

    surface = pv.PolyData(v, np.c_[np.full(len(f), 3), f].ravel())
    enclosed = pv.PolyData(b.points[:, 1:-1].reshape(-1, 3)).select_enclosed_points(surface)
    assert np.asarray(enclosed["SelectedPoints"]).all()


def test_box_fibres_stay_inside():
    import trimesh

    m = trimesh.creation.box(extents=[0.04, 0.02, 0.1])
    m = m.subdivide_to_size(0.004)
    v, f = np.array(m.vertices), np.array(m.faces)
    gx, gy = np.meshgrid(np.linspace(-0.02, 0.02, 5), np.linspace(-0.01, 0.01, 5))
    o = np.c_[gx.ravel(), gy.ravel(), np.full(25, -0.05)]     # the whole end faces
    i = o + [0, 0, 0.1]
    b = decompose((v, f), o, i, n_fibres=60, resolution=10)
    assert b.quality.outside == 0
    # parallel template in a box between its end faces: straight fibres (the loops are equal
    # rectangles), up to the containment pull near the edges (0.2 mm band)
    assert b.quality.turn_max < 5.0


def test_grid_area_map_uniform_is_the_identity_and_weights_move_the_quantiles():
    """Equal cell masses: the map is the identity. Columns x < 1/2 three times as heavy
    (masses 3 and 1 per cell, total 2): the x-marginal is F1(x) = 3x / 2 up to 1/2, so
    X = 1/2 goes to x = 1/3 and X = 3/4 (= F1(1/2)) to 1/2; rows equal: y = Y.
    Rows y < 1/4 of every column weigh 5 (the rest 1, total 5/4 + 3/4 = 2): the conditional
    F2(y) = 5y / 2 up to 1/4, so Y = 5/16 goes to y = 1/8; x stays X."""
    from fibres.attachments.patch_map import grid_area_map
    g = 8
    X = np.array([0.0, 0.1, 0.5, 0.77, 1.0])
    Y = np.array([0.3, 0.0, 0.9, 0.5, 1.0])
    xs, ys = grid_area_map(np.ones((g, g)), X, Y)
    np.testing.assert_allclose(xs, X, atol=1e-9)
    np.testing.assert_allclose(ys, Y, atol=1e-9)
    m = np.ones((g, g))
    m[: g // 2] = 3.0
    xs, ys = grid_area_map(m, np.array([0.5, 0.75]), np.array([0.2, 0.6]))
    np.testing.assert_allclose(xs, [1 / 3, 1 / 2], atol=1e-9)
    np.testing.assert_allclose(ys, [0.2, 0.6], atol=1e-9)
    m = np.ones((g, g))
    m[:, : g // 4] = 5.0
    xs, ys = grid_area_map(m, np.array([0.3]), np.array([5 / 16]))
    np.testing.assert_allclose(xs, [0.3], atol=1e-9)
    np.testing.assert_allclose(ys, [1 / 8], atol=1e-9)


def test_kr_coordinates_of_a_uniform_rectangle_and_the_round_trip():
    """A uniform rectangle [0, 2] x [0, 1] (two triangles): X = x / 2 and Y = y away from the
    rim (the measure is sampled at sub-triangle centroids, 8 x 8 per triangle here, and the
    conditional of y is a Gaussian window in x: exact to a few hundredths); `knothe_rosenblatt`
    maps the coordinates back to the points exactly (both use the same sampled measure)."""
    from fibres.attachments.patch_map import knothe_rosenblatt, kr_coordinates
    px = np.array([[0.0, 2.0, 2.0], [0.0, 2.0, 0.0]])
    py = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 1.0]])
    area = np.array([1.0, 1.0])
    qx = np.array([0.5, 1.0, 1.5, 1.2])
    qy = np.array([0.5, 0.25, 0.7, 0.4])
    X, Y = kr_coordinates(px, py, area, qx, qy)
    np.testing.assert_allclose(X, qx / 2, atol=0.03)
    np.testing.assert_allclose(Y, qy, atol=0.03)
    bx, by = knothe_rosenblatt(px, py, area, X, Y)     # the exact inverse of the sampled map
    np.testing.assert_allclose(bx, qx, atol=1e-9)
    np.testing.assert_allclose(by, qy, atol=1e-9)


def test_lloyd_steps_spread_points_evenly_over_a_square_patch():
    """A flat unit square patch (two triangles) and 16 points crowded in its lower-left
    quarter: after Lloyd steps every point has moved towards its Voronoi cell's centroid, so
    the largest distance from the square's area to the nearest point falls (the optimal 4 x 4
    grid leaves sqrt(2) / 8 = 0.18; the crowded start leaves ~0.85; the cells' centroids are
    measured on the area samples, 8 x 8 sub-triangles per triangle here, so the steps stop
    short of the optimum: 0.25 measured, below 0.3), and points stay on it."""
    from fibres.attachments.patch_map import relax_on_patch
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
    f = np.array([[0, 1, 2], [0, 2, 3]])
    rng = np.random.default_rng(3)
    uv = rng.uniform(0.05, 0.45, size=(16, 2))
    # points in face 0 (x > y) or 1, as barycentrics of its corners
    face = np.where(uv[:, 0] > uv[:, 1], 0, 1)
    bary = np.empty((16, 3))
    for k, (x, y) in enumerate(uv):
        a, b, c = v[f[face[k]]][:, :2]
        m = np.array([[a[0], b[0], c[0]], [a[1], b[1], c[1]], [1, 1, 1]])
        bary[k] = np.linalg.solve(m, [x, y, 1])
    g = (np.arange(50) + 0.5) / 50
    grid = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)

    def worst(fc, bc):
        pts = np.einsum("nk,nkd->nd", bc, v[f[fc]])[:, :2]
        return np.min(np.linalg.norm(grid[:, None] - pts[None], axis=2), axis=1).max()

    before = worst(face, bary)
    fc, bc = relax_on_patch(v, f, np.ones(2, dtype=bool), face, bary, iterations=30)
    assert before > 0.8
    assert worst(fc, bc) < 0.3
    assert np.all(bc >= -1e-12) and np.allclose(bc.sum(axis=1), 1.0)


def test_registered_seam_finds_the_same_material_start_on_a_renumbered_loop():
    """Two loops: an ellipse and the same ellipse 1 unit higher whose points are numbered from
    another start (rolled by 50 of 200). The first loop's seam at point 37 must be matched
    by the point numbered (37 - 50) mod 200 = 187 of the next loop, to within half the search
    step (shifts are tried every 1/8 of a sample spacing: 200 / 64 / 8 = 0.39 points)."""
    from fibres.slicing.harmonic_sections import _registered_seam
    th = np.linspace(0.0, 2 * np.pi, 200, endpoint=False)
    prev = np.c_[3 * np.cos(th), np.sin(th), np.zeros_like(th)]
    nxt = np.roll(prev + [0.0, 0.0, 1.0], -50, axis=0)
    segs = [np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1) for p in (prev, nxt)]
    for first, mid, seam_mid, want in ((prev, 0, 37.0, 187.0), (nxt, 1, 187.0, 37.0)):
        pos = _registered_seam(np.concatenate([prev, nxt]), np.concatenate(segs), [0, 200],
                               [200, 200], mid, seam_mid)
        assert pos[mid, 0] == seam_mid
        seam = pos[1 - mid, 0]
        assert abs((seam - want + 100.0) % 200.0 - 100.0) <= 0.5 * 200 / 64 / 8 + 1e-9


def test_bending_measure_is_zero_on_a_line_and_counts_a_half_turn():
    """A straight path adds nothing. A semicircle of radius 1 (length pi, turning pi) adds
    weight * (pi / pi) * pi at its end, less the half step of turning lost at each end by
    the one-sided directions there: pi (1 - 1 / 47) for 48 samples."""
    from fibres.slicing.harmonic_sections import bending_measure
    s = np.linspace(0.0, 2.0, 30)
    line = np.c_[s, 0.5 * s, np.zeros_like(s)] / np.sqrt(1.25)
    np.testing.assert_allclose(bending_measure(s, line, 0.25), 0.0, atol=1e-12)
    th = np.linspace(0.0, np.pi, 400)
    arc = np.c_[np.cos(th), np.sin(th), np.zeros_like(th)]
    m = bending_measure(th, arc, 0.25)
    np.testing.assert_allclose(m[-1], 0.25 * np.pi * (1 - 1 / 47), rtol=1e-3)
    assert np.all(np.diff(m) >= 0)


# -- quality numbers on known cases -------------------------------------------------------

def test_quality_of_one_axial_fibre_in_a_cylinder():
    """One fibre on the axis of a cylinder of radius 10 mm: the volume farther than 5 mm is the
    annulus, 1 - (5/10)^2 = 0.75 of it; the fibre's end at the centre of a cap covers the disk
    of radius 5 mm, 0.25 of the cap; a straight fibre turns by 0; no point outside."""
    v, f = tube(_circle, *straight(L), n_sect=96, n_path=21)
    fibre = np.c_[np.zeros(11), np.zeros(11), np.linspace(0, L, 11)][None]
    caps0 = (v[f][:, :, 2] <= 1e-12).all(axis=1)
    caps1 = (v[f][:, :, 2] >= L - 1e-12).all(axis=1)
    q = fibre_quality(fibre, v, f, caps0, caps1)
    # the inscribed 96-gon's area is 0.9993 of the circle's; the volume grid has ~40 000 cells
    assert q.empty_5mm == pytest.approx(0.75, abs=0.01)
    assert q.origin_covered == pytest.approx(0.25, abs=0.01)
    assert q.insertion_covered == pytest.approx(0.25, abs=0.01)
    assert q.turn_max == pytest.approx(0.0, abs=1e-6)
    assert q.outside == 0
    bent = fibre.copy()
    bent[0, 5] = [0.02, 0.0, L / 2]                       # one point 10 mm outside the wall
    q2 = fibre_quality(bent, v, f, caps0, caps1)
    assert q2.outside == 1
    # the kink: atan(20 / 10) on each side of the moved point, 2 atan(2) at it
    assert q2.turn_max == pytest.approx(np.degrees(2 * np.arctan(2.0)), abs=1e-6)
    assert q2.problems()


def test_inside_grid_measures_the_volume():
    v, f = tube(_circle, *straight(L), n_sect=96, n_path=21)
    cells = inside_grid(v, f, 1e-3)
    polygon = 0.5 * 96 * RHO ** 2 * np.sin(2 * np.pi / 96)
    assert len(cells) * 1e-9 == pytest.approx(polygon * L, rel=0.01)


# -- LHDL ------------------------------------------------------------------------------------

MUSCLES = ("glut_max_r", "glut_med_r", "iliacus_r", "psoas_r")
TEMPLATES = {"glut_max_r": "parallel", "glut_med_r": "fanned", "iliacus_r": "fanned",
             "psoas_r": "parallel"}


def _lhdl(lhdl_dir, muscle):
    import pandas as pd

    from fibres import as_surface

    tab = pd.read_csv(lhdl_dir / "attachments" / "attachment_landmarks.csv")
    rows = tab[tab.muscle == muscle]
    o = rows[rows.type == "origin"][["x_mm", "y_mm", "z_mm"]].to_numpy(float)
    ins = rows[rows.type == "insertion"]
    if muscle == "glut_max_r":   # cloud 2 lies on the tibia, ~310 mm from the mesh
        ins = ins[ins.cloud == 1]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        s = as_surface(lhdl_dir / "muscles_clean" / f"{muscle}.vtk", units="mm")
    return s, o, ins[["x_mm", "y_mm", "z_mm"]].to_numpy(float)


@pytest.mark.shared
@pytest.mark.slow
@pytest.mark.parametrize("muscle", MUSCLES)
def test_lhdl_isolines_are_single_loops(lhdl_dir, muscle):
    """Every inner slice level of the LHDL muscles (resolution 15) is one closed loop when the
    origin is one patch (psoas: its four lumbar origin clouds are four pieces, whose saddles
    give several loops near the origin; tested with the iliacus-area origin of Modenese &
    Kohout 2020, as tests/data/lhdl_hip.toml does)."""
    from fibres.slicing.harmonic import _levels

    s, o, i = _lhdl(lhdl_dir, muscle)
    if muscle == "psoas_r":
        o = _lhdl(lhdl_dir, "iliacus_r")[1]
    plan = make_plan(s, o * 1e-3, i * 1e-3)
    for t in _levels(plan, 15)[1:-1]:
        loops = isoline_loops(plan.field, plan.faces, t, plan.edges, plan.face_edges)
        assert len(loops) == 1, t


# measured (this code, resolution 15, 100 fibres, the TOML's templates; psoas with its own
# lumbar origins): volume farther than 5 mm 4.3 / 1.5 / 0.6 / 2.3 %, origin covered
# 100 / 94 / 97 / 100 %, insertion 100 % each; the bounds below are those numbers with a margin
# (they guard against regressions)
BOUNDS = {"glut_max_r": (0.05, 0.95, 0.95), "glut_med_r": (0.03, 0.90, 0.95),
          "iliacus_r": (0.02, 0.92, 0.95), "psoas_r": (0.04, 0.95, 0.95)}
# the turn limits of issue 11: no turn between consecutive segments over 45 degrees, 95th
# percentile of each fibre's sharpest turn <= 20 degrees. Measured with the frame-free
# orientation signs and continuous patch steps of the invariance fixes: max 23 / 29 / 19 / 23,
# p95 19.5 / 19.8 / 14.5 / 20.5 (before the fairing: p95 42 / 26 / 24 / 38, max 45.4). The
# psoas misses the 20 degrees by 0.5 (the containment pull in its tendon: 13.4 without it);
# its bound is a regression guard at the measured value plus 0.5, not the target.
TURN_MAX = 45.0
TURN_P95 = {"glut_max_r": 20.0, "glut_med_r": 20.0, "iliacus_r": 20.0, "psoas_r": 20.0}


@pytest.mark.shared
@pytest.mark.slow
@pytest.mark.parametrize("muscle", MUSCLES)
def test_lhdl_fibre_quality(lhdl_dir, muscle):
    s, o, i = _lhdl(lhdl_dir, muscle)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        b = decompose(s, o, i, units="mm", template=TEMPLATES[muscle], n_fibres=100,
                      resolution=15)
    q = b.quality
    empty, cov_o, cov_i = BOUNDS[muscle]
    assert q.outside == 0
    assert q.empty_5mm <= empty
    assert q.origin_covered >= cov_o
    assert q.insertion_covered >= cov_i
    assert q.turn_max <= TURN_MAX
    assert q.turn_p95 <= TURN_P95[muscle]


def test_bundle_and_plan_pickle_and_the_plan_still_decomposes():
    """A bundle (with its HarmonicPlan: field, patches; not its per-process cache or lock) goes
    through pickle, as process pools and Dask workers need, and its plan gives the same fibres."""
    import pickle

    v, f = tube(_circle, *straight(L), n_sect=32, n_path=21)
    b = decompose((v, f), _disk(0.0), _disk(L), n_fibres=20, resolution=8)
    b2 = pickle.loads(pickle.dumps(b))
    np.testing.assert_array_equal(b2.points, b.points)
    again = decompose((v, f), _disk(0.0), _disk(L), n_fibres=20, resolution=8, plan=b2.plan)
    np.testing.assert_allclose(again.points, b.points, atol=1e-12)
    assert b2.quality.outside == 0
