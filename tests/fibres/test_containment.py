"""fibres.finishing.containment (the smooth pull back inside) and fibres.mesh.surface_distance.

Reference shapes with closed-form distances: a torus (a bent tube: its inner wall is concave)
and an extruded V notch (two walls meeting in a concave edge). Mesh sagitta bounds the
difference between the polygonal surface and the analytic one.
"""
import numpy as np
import pytest
import trimesh

from fibres.finishing.containment import CONTAIN_MARGIN, CONTAIN_SOFTNESS, contain
from fibres.mesh.surface_distance import KAPPA, SurfaceGrid, surface_distance

from distance_oracle import brute

R, RHO = 0.05, 0.01                       # torus major / minor radius (m)
N_MAJOR, N_MINOR = 96, 32
# the mesh's vertices lie on the torus and its faces within the sagittas of the two polygon
# directions of it (inside where the torus is convex, outside on the concave inner wall):
# (R + RHO)(1 - cos(pi / 96)) + RHO (1 - cos(pi / 32)) = 8.0e-5 m
SAG = (R + RHO) * (1 - np.cos(np.pi / N_MAJOR)) + RHO * (1 - np.cos(np.pi / N_MINOR))
M = CONTAIN_MARGIN


@pytest.fixture(scope="module")
def torus():
    m = trimesh.creation.torus(major_radius=R, minor_radius=RHO, major_sections=N_MAJOR,
                               minor_sections=N_MINOR)
    assert m.is_watertight and m.volume > 0
    return np.asarray(m.vertices), np.asarray(m.faces)


def torus_sd(x):
    """Analytic signed distance to the torus (positive outside)."""
    return np.hypot(np.hypot(x[..., 0], x[..., 1]) - R, x[..., 2]) - RHO


def chords(n_points=16):
    """Straight fibres between points of the tube's centre circle 30-90 degrees apart, at
    heights within the tube: they cut through the hole (outside) for wide angles, by at most
    R (1 - cos 45 deg) - RHO = 4.6 mm (within the default reach, 8 mm)."""
    rng = np.random.default_rng(3)
    phi0 = rng.uniform(0, 2 * np.pi, 40)
    phi1 = phi0 + rng.uniform(np.deg2rad(30), np.deg2rad(90), 40)
    z = rng.uniform(-0.5, 0.5, (40, 2)) * RHO
    a = np.c_[R * np.cos(phi0), R * np.sin(phi0), z[:, 0]]
    b = np.c_[R * np.cos(phi1), R * np.sin(phi1), z[:, 1]]
    t = np.linspace(0, 1, n_points)[None, :, None]
    return a[:, None] + t * (b - a)[:, None]


def test_torus_chords_end_inside(torus):
    v, f = torus
    fib = chords()
    before = torus_sd(fib)
    assert before.max() > 3e-3                # not vacuous: chords leave through the hole
    out, moved = contain(fib, v, f)
    after = torus_sd(out)
    # every inner point ends about m / 2 inside the mesh or deeper by the blend's distance:
    # pulled points go to s' < -m / 2 (after two steps within 5 um of it near mesh edges,
    # where the second step starts from another closest point; measured -0.0977 mm), deeper
    # ones stay
    mesh_sd, _ = surface_distance(out[:, 1:-1], v, f, reach=0.008, softness=CONTAIN_SOFTNESS)
    assert np.nanmax(mesh_sd) <= -M / 2 + 5e-6
    # and inside the torus itself: the mesh lies within SAG (< m / 2 - 5 um) of it
    assert SAG < M / 2 - 5e-6
    assert after[:, 1:-1].max() <= -M / 2 + 5e-6 + SAG
    # pulled points land near s' in (-0.57 m, -m / 2) of the mesh: within the sagitta (mesh
    # vs torus) and the soft blend's bias (KAPPA tau) of the torus surface
    was_out = before > SAG
    assert after[was_out].min() >= -(0.57 * M + SAG + KAPPA * CONTAIN_SOFTNESS)
    assert moved[(before[:, 1:-1] > SAG).any(axis=1)].all()
    # points deeper than the band (m, plus the sagitta) never move (bit for bit), nor do
    # the ends
    deep = before < -(M + SAG)
    assert not moved[deep[:, 1:-1].all(axis=1)].any()
    np.testing.assert_array_equal(out[:, [0, -1]], fib[:, [0, -1]])
    np.testing.assert_array_equal(out[deep], fib[deep])


def test_a_point_deeper_than_the_band_is_not_moved(torus):
    v, f = torus
    rng = np.random.default_rng(8)
    phi = rng.uniform(0, 2 * np.pi, 300)
    r = RHO * np.sqrt(rng.uniform(0, 1, 300)) * (1 - (M + 2 * SAG) / RHO)
    th = rng.uniform(0, 2 * np.pi, 300)
    x = np.c_[(R + r * np.cos(th)) * np.cos(phi), (R + r * np.cos(th)) * np.sin(phi),
              r * np.sin(th)].reshape(100, 3, 3)
    assert torus_sd(x).max() < -(M + SAG)
    out, moved = contain(x, v, f)
    np.testing.assert_array_equal(out, x)
    assert not moved.any()


def test_rigid_motion_moves_the_result_rigidly(torus):
    v, f = torus
    fib = chords()
    ax = np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
    k = np.array([[0, -ax[2], ax[1]], [ax[2], 0, -ax[0]], [-ax[1], ax[0], 0]])
    rot = np.eye(3) + np.sin(0.7) * k + (1 - np.cos(0.7)) * k @ k
    t = np.array([0.3, -0.2, 0.5])
    out, _ = contain(fib, v, f)
    moved, _ = contain(fib @ rot.T + t, v @ rot.T + t, f)
    # rounding of coordinates ~0.5 m from the origin (1e-16 relative) through a few steps
    assert np.abs(moved - (out @ rot.T + t)).max() <= 1e-12


def _slab():
    """A box 40 x 40 x 20 mm (metres), subdivided."""
    m = trimesh.creation.box(extents=(0.04, 0.04, 0.02)).subdivide().subdivide()
    return np.asarray(m.vertices), np.asarray(m.faces)


def test_flat_face_pull_is_the_c1_depth_map():
    # a point on the normal through the middle of the top face (z = 0.01) at signed distance
    # s goes to s' = -m + a (1 - exp(-(s + m) / a)), a = m / 2, for s > -m and stays deeper:
    # exactly (the closest point is in the face's interior, its direction the face normal)
    v, f = _slab()
    top = f[(v[f][:, :, 2] > 0.01 - 1e-12).all(axis=1)][0]
    c = v[top].mean(axis=0)       # a top triangle's centroid: its edges are > KAPPA tau away
    s = np.linspace(-1e-3, 5e-3, 121)
    mid = np.c_[np.full(121, c[0]), np.full(121, c[1]), 0.01 + s]
    fib = np.stack([np.zeros((121, 3)), mid, np.zeros((121, 3))], axis=1)
    out, _ = contain(fib, v, f)
    a = M / 2
    band = s > -M
    expect = np.where(band, -M - a * np.expm1(-(np.maximum(s, -M) + M) / a), s)
    # to the soft blend: far out, coplanar neighbours within KAPPA tau of the nearest
    # triangle get a little weight and tilt the direction (measured 4e-8 m at s = 5 mm)
    np.testing.assert_allclose(out[:, 1, 2] - 0.01, expect, rtol=0, atol=1e-7)
    np.testing.assert_allclose(out[:, 1, :2], mid[:, :2], rtol=0, atol=1e-7)
    np.testing.assert_array_equal(out[~band, 1], mid[~band])       # deeper: not moved
    # every point of the band or outside ends inside, at least m / 2 deep; points that were
    # outside at most m (1 - (1 - e^-2) / 2) = 0.57 m deep
    assert (out[band, 1, 2] - 0.01 <= -M / 2 + 1e-7).all()
    assert (out[s >= 0, 1, 2] - 0.01 >= -M * (1 - 0.5 * (1 - np.exp(-2))) - 1e-7).all()
    # C1 where the band starts: the map's slope is 1 on both sides of s = -m (the central
    # difference over +-e differs from 1 by the curvature term e / (4 a) = e / (2 m))
    e = 1e-7
    pts = np.stack([np.zeros((2, 3)), [[c[0], c[1], 0.01 - M - e], [c[0], c[1], 0.01 - M + e]],
                    np.zeros((2, 3))], axis=1)
    z = contain(pts, v, f)[0][:, 1, 2]
    assert abs((z[1] - z[0]) / (2 * e) - 1) <= e / (2 * M) + 1e-6


def _notch():
    """A prism (metres) whose top has a V notch: a pentagon (0,0) (40,0) (40,20) (20,10)
    (0,20) mm extruded 20 mm along z; its walls meet in a concave edge at x = 20 mm."""
    poly = np.array([[0, 0], [40, 0], [40, 20], [20, 10], [0, 20]], float) * 1e-3
    n = len(poly)
    v = np.vstack([np.c_[poly, np.zeros(n)], np.c_[poly, np.full(n, 0.02)]])
    cap = np.array([[3, 4, 0], [3, 0, 1], [3, 1, 2]])          # a fan from the reflex corner
    sides = [[i, (i + 1) % n, n + (i + 1) % n] for i in range(n)] + \
            [[i, n + (i + 1) % n, n + i] for i in range(n)]
    f = np.vstack([cap[:, ::-1], cap + n, sides])
    m = trimesh.Trimesh(v, f, process=False)
    m.fix_normals()
    assert m.is_watertight and m.volume > 0
    return np.asarray(m.vertices), np.asarray(m.faces)


def test_pull_is_continuous_across_the_medial_plane_of_a_concave_notch():
    # points outside in the notch, 4 mm above its edge, crossing the plane x = 20 mm where
    # both walls are equally near (the single closest wall would jump from one side to the
    # other: a jump of ~5.6 mm); the soft blend turns the direction continuously
    v, f = _notch()
    x = 0.02 + np.linspace(-3e-4, 3e-4, 601)
    mid = np.c_[x, np.full_like(x, 0.014), np.full_like(x, 0.01)]
    fib = np.stack([np.tile([0.01, 0.005, 0.01], (len(x), 1)), mid,
                    np.tile([0.03, 0.005, 0.01], (len(x), 1))], axis=1)
    out = contain(fib, v, f)[0][:, 1]
    step = np.linalg.norm(np.diff(out, axis=0), axis=1).max()
    # steepest where the blend turns (over ~tau = 0.05 mm): measured 0.06 mm per 1 um step,
    # far from a 5.6 mm jump; halving the step halves it (continuous, not a jump)
    assert step <= 0.2e-3
    half = contain(np.stack([fib[:-1, 0], 0.5 * (mid[:-1] + mid[1:]), fib[:-1, 2]], axis=1),
                   v, f)[0][:, 1]
    fine = np.linalg.norm(np.r_[half - out[:-1], out[1:] - half], axis=1).max()
    assert fine <= 0.6 * step
    # and the pulled points end inside, near the walls: on the medial plane the blended
    # direction bisects them, so the two steps leave a point less deep than m / 2 (measured
    # 0.066 mm = 0.33 m); elsewhere m / 2 or deeper
    sd, _ = surface_distance(out, v, f, reach=0.01, softness=CONTAIN_SOFTNESS)
    assert sd.max() <= -M / 4


def test_surface_distance_matches_the_torus(torus):
    v, f = torus
    rng = np.random.default_rng(2)
    x = rng.uniform(-1, 1, (2000, 3)) * [R + 2 * RHO, R + 2 * RHO, 2 * RHO]
    s, n = surface_distance(x, v, f, reach=0.008, softness=CONTAIN_SOFTNESS)
    exact = torus_sd(x)
    ok = np.isfinite(s)
    assert ok.sum() > 500
    # the mesh is within SAG inside the torus; the blend overestimates by < KAPPA tau
    assert np.abs(s[ok] - exact[ok]).max() <= SAG + KAPPA * CONTAIN_SOFTNESS
    # -inf only for points farther than reach (8 mm) from the surface, or inside and
    # deeper than one grid cell
    assert ((exact[~ok] > 8e-3 - SAG) | (exact[~ok] < 0)).all()
    assert np.allclose(np.linalg.norm(n[ok], axis=1), 1.0)


def test_tree_search_equals_the_brute_force_oracle(torus):
    # the k-d tree search (fibres.mesh.surface_distance) against every point x every triangle
    # (tests/fibres/distance_oracle.py): the same blend on the same triangle sets, equal to
    # rounding where both measure; the search leaves -inf only where the oracle finds the
    # point inside (deeper than watch) or nothing within reach
    v, f = torus
    rng = np.random.default_rng(4)
    x = rng.uniform(-1, 1, (400, 3)) * [R + 2 * RHO, R + 2 * RHO, 2 * RHO]
    for offset, watch in ((False, None), (True, M)):
        s1, n1 = SurfaceGrid(v, f, reach=0.008).signed_distance(
            x, tau=CONTAIN_SOFTNESS, watch=watch, offset=offset)
        s2, n2 = brute(x, v, f, 0.008, CONTAIN_SOFTNESS, offset=offset)
        both = np.isfinite(s1)
        assert both.sum() > 50
        np.testing.assert_allclose(s1[both], s2[both], rtol=0, atol=1e-12)
        np.testing.assert_allclose(n1[both], n2[both], rtol=0, atol=1e-9)
        assert ((s2[~both] < 0) | ~np.isfinite(s2[~both])).all()
        if watch is not None:
            assert (s2[~both & np.isfinite(s2)] < -M).all()


@pytest.mark.parametrize("bad", [0.0, -1.0, np.nan])
def test_bad_parameters_are_refused(torus, bad):
    v, f = torus
    with pytest.raises(ValueError, match="margin"):
        contain(chords(), v, f, margin=bad)
    with pytest.raises(ValueError, match="reach"):
        surface_distance(np.zeros(3), v, f, reach=bad, softness=1e-4)
    with pytest.raises(ValueError, match="points"):
        contain(np.zeros((4, 3)), v, f)


def _bottle(n_sect=48):
    """A solid of revolution about z (metres) whose axial hole narrows to 0.5 mm radius at
    both ends and widens to 4 mm inside: an outside pocket closed off by the surface's grid
    cells (narrower than a cell at the necks)."""
    prof = np.array([[8, -6], [8, 6], [0.5, 6], [0.5, 4], [4, 2], [4, -2], [0.5, -4],
                     [0.5, -6]], float) * 1e-3
    pts = []
    for a, b in zip(prof, np.roll(prof, -1, axis=0)):  # profile edges of <= 0.5 mm
        k = max(int(np.ceil(np.linalg.norm(b - a) / 5e-4)), 1)
        pts.extend(a + (b - a) * t for t in np.arange(k) / k)
    prof = np.array(pts)
    th = np.linspace(0, 2 * np.pi, n_sect, endpoint=False)
    k = len(prof)
    v = np.stack([prof[:, None, 0] * np.cos(th), prof[:, None, 0] * np.sin(th),
                  np.broadcast_to(prof[:, None, 1], (k, n_sect))], -1).reshape(-1, 3)
    i, j = np.arange(k)[:, None], np.arange(n_sect)[None]
    a, b = i * n_sect + j, i * n_sect + (j + 1) % n_sect
    c, d = ((i + 1) % k) * n_sect + j, ((i + 1) % k) * n_sect + (j + 1) % n_sect
    f = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3),
                        np.stack([a, d, c], -1).reshape(-1, 3)])
    m = trimesh.Trimesh(v, f, process=True)
    m.fix_normals()
    assert m.is_watertight and m.volume > 0
    return np.asarray(m.vertices), np.asarray(m.faces)


def test_an_outside_pocket_enclosed_by_surface_cells_is_outside():
    # the pocket's empty cells are not connected to the grid's border through empty cells;
    # they must still count as outside (their component's sign), so a fibre through the
    # pocket is pulled into the wall. Analytic: the pocket is r < 4 mm, |z| < 2 mm.
    v, f = _bottle()
    grid = SurfaceGrid(v, f, reach=8e-3)
    x = np.array([[0.0, 0.0, 0.0], [1e-3, 0.0, 0.0], [0.0, 1e-3, 1e-3]])
    s, _ = grid.signed_distance(x, tau=CONTAIN_SOFTNESS, watch=0.0)
    # analytic distances to the pocket's walls (cylinder r = 4 mm, cones to the necks):
    # 3.721, 3.0, 2.357 mm; the 48-gon and the blend change them by < 0.05 mm (measured 0.04)
    np.testing.assert_allclose(s, [3.721e-3, 3.0e-3, 2.357e-3], atol=5e-5)
    fib = np.stack([np.tile([6e-3, 0, 0], (3, 1)), x, np.tile([-6e-3, 0, 0], (3, 1))], 1)
    out, moved = contain(fib, v, f)
    assert moved.all()
    after, _ = surface_distance(out[:, 1], v, f, reach=8e-3, softness=CONTAIN_SOFTNESS)
    # the two steps land within 7 um of s' < m on these curved walls (measured 0.2066 mm)
    assert after.max() <= 1.05 * M


@pytest.mark.parametrize("shape", ["torus", "bottle"])
def test_inside_by_ray_parity_agrees_with_the_distance_sign(torus, shape):
    # contain asks only which points are outside (watch = 0): points in surface cells are
    # classified by the vote of their nearest triangles (watch = 0); they must agree with the sign
    # of the blended distance wherever it is defined
    v, f = torus if shape == "torus" else _bottle()
    grid = SurfaceGrid(v, f, reach=8e-3)
    rng = np.random.default_rng(6)
    x = rng.uniform(v.min(axis=0) - 1e-3, v.max(axis=0) + 1e-3, (20000, 3))
    quick, _ = grid.signed_distance(x, tau=CONTAIN_SOFTNESS, watch=0.0)
    full, _ = grid.signed_distance(x, tau=CONTAIN_SOFTNESS)
    defined = np.isfinite(full)
    assert defined.sum() > 5000
    # inside (-inf) exactly where the blended distance is <= 0, except within 2 tau of the
    # surface, where the blend's sign (soft over near ties) and the exact parity may differ
    # (measured: 4 of 19489 bottle points, all within 0.045 mm); a point missed there would
    # have moved by at most (2 tau)^2 / (2 m) = 0.025 mm
    clear = defined & (np.abs(full) > 2 * CONTAIN_SOFTNESS)
    np.testing.assert_array_equal(np.isinf(quick)[clear], full[clear] <= 0)
    assert (np.isinf(quick) != (full <= 0))[defined].mean() < 1e-3
    out = np.isfinite(quick)
    np.testing.assert_array_equal(quick[out], full[out])


def test_pull_is_continuous_through_the_surface_near_an_edge():
    # a point crossing the top face of the slab 0.1 mm from its edge with a side face (the
    # blend weighs both faces): the band pull moves points on both sides of the surface, so
    # its measure must be continuous through it. The blended distance is not: its mean over
    # the near ties stays ~tau / 7 above 0 on the surface while its sign flips (a jump of
    # 2 x 7 um in s); the blended normal offset used by `contain` passes through 0.
    v, f = _slab()
    z = 0.01 + np.linspace(-2e-5, 2e-5, 401)                  # 0.1 um steps through z = 10 mm
    mid = np.c_[np.full_like(z, 0.0199), np.full_like(z, 0.003), z]
    fib = np.stack([np.zeros_like(mid), mid, np.zeros_like(mid)], axis=1)
    out = contain(fib, v, f)[0][:, 1]
    step = np.linalg.norm(np.diff(out, axis=0), axis=1).max()
    # C1 map: a step moves a pulled point by at most the step times the map's slope (< 1)
    # and the direction's turn; measured 0.1 um per 0.1 um step
    assert step <= 2 * (z[1] - z[0])
    grid = SurfaceGrid(v, f, reach=8e-3)
    s_off, _ = grid.signed_distance(mid, tau=CONTAIN_SOFTNESS, watch=M, offset=True)
    s_blend, _ = grid.signed_distance(mid, tau=CONTAIN_SOFTNESS)
    assert np.abs(np.diff(s_off)).max() <= 2 * (z[1] - z[0])
    # not vacuous: the signed blended distance jumps here
    assert np.abs(np.diff(s_blend)).max() > 1e-6


def _sphere(radius, subdivisions):
    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    assert m.is_watertight and m.volume > 0
    return np.asarray(m.vertices), np.asarray(m.faces)


def test_signed_distance_of_a_sphere_is_radial_within_the_tessellation_error():
    # an icosphere's vertices lie on the sphere |x| = r and each face is the chord plane of
    # its circumcircle (circumradius rc): the face lies in the shell between r - h and r with
    # h = r - sqrt(r^2 - rc^2), and each sphere point is within h of the mesh (radially), so
    # the Hausdorff distance of mesh and sphere is <= h and the exact distances to them differ
    # by <= h everywhere. The blend adds 0 .. KAPPA tau (a weighted mean of distances in
    # [d_min, d_min + KAPPA tau]); with tau = 1 um that is 8 um.
    r, tau = 0.02, 1e-6
    v, f = _sphere(r, 4)
    a, b, c = (v[f[:, k]] for k in range(3))
    la, lb, lc = (np.linalg.norm(y, axis=1) for y in (b - c, c - a, a - b))
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    rc = (la * lb * lc / (4 * area)).max()
    h = r - np.sqrt(r * r - rc * rc)
    assert 1e-6 < h < 3e-5                     # the mesh is fine enough for the check to bite
    rng = np.random.default_rng(11)
    u = rng.standard_normal((3000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    radial = rng.uniform(-6e-3, 6e-3, 3000)    # within reach (8 mm) of the surface
    x = u * (r + radial)[:, None]
    s, n = surface_distance(x, v, f, reach=8e-3, softness=tau)
    assert np.isfinite(s).all()
    np.testing.assert_allclose(s, radial, rtol=0, atol=h + KAPPA * tau)
    # the direction of the shortest path is radial up to the facets' tilt (away from the
    # shell, where the nearest point may be a facet's edge or vertex)
    far = np.abs(radial) > 1e-3
    assert (np.einsum("ij,ij->i", n[far], u[far]) > 0.99).all()
    # the parity test: inside exactly below the shell
    grid = SurfaceGrid(v, f, reach=8e-3)
    clear = np.abs(radial) > h
    np.testing.assert_array_equal(grid.inside(x)[clear], radial[clear] < 0)


def test_grid_search_equals_the_oracle_on_an_lhdl_muscle(lhdl_dir):
    # the real mesh (iliacus: 4K vertices, 8K triangles, edges up to 11 mm) against the brute
    # force oracle, for points on both sides of the surface and deep inside: the same blend on
    # the same triangle sets, equal to rounding where the search measures (the closest points
    # are computed in two ways: the kernel's plane projection or nearest edge, the oracle's
    # Voronoi regions)
    import warnings

    from fibres import as_surface

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        surf = as_surface(lhdl_dir / "muscles_clean" / "iliacus_r.vtk", units="mm")
    v, f = np.asarray(surf.vertices), np.asarray(surf.faces)
    rng = np.random.default_rng(12)
    tri = v[f[rng.choice(len(f), 300, replace=False)]]                  # (300, 3, 3)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    x = np.concatenate([tri.mean(axis=1) + normal * rng.uniform(-3e-3, 3e-3, (300, 1)),
                        rng.uniform(v.min(axis=0), v.max(axis=0), (200, 3))])
    grid = SurfaceGrid(v, f, reach=0.008)
    for offset, watch in ((False, None), (True, M)):
        s1, n1 = grid.signed_distance(x, tau=CONTAIN_SOFTNESS, watch=watch, offset=offset)
        s2, n2 = brute(x, v, f, 0.008, CONTAIN_SOFTNESS, offset=offset)
        both = np.isfinite(s1)
        # watch = M: the inside points deeper than M are not measured
        assert both.sum() > (250 if watch is None else 150)
        np.testing.assert_allclose(s1[both], s2[both], rtol=0, atol=1e-12)
        np.testing.assert_allclose(n1[both], n2[both], rtol=0, atol=1e-9)
        # -inf only where the oracle finds nothing within reach or (watch) an inside point
        # deeper than the band
        assert (~np.isfinite(s2[~both]) | (s2[~both] < 0)).all()
        if watch is not None:
            assert (s2[~both & np.isfinite(s2)] < -M).all()


def test_degenerate_triangles_are_measured_like_the_oracle(torus):
    # zero-area triangles (three collinear corners, a repeated corner, a single point) have no
    # plane: their closest point is on an edge or the point itself. Added to the torus (they
    # cross no parity ray), the search and the oracle must still agree to rounding
    v, f = torus
    extra = np.array([[0, 0, 1], [5, 5, 5], [7, 8, 7]])
    line = len(v) + np.arange(3)                         # three collinear new vertices
    v2 = np.concatenate([v, v[[0]] + np.outer([0.0, 0.5, 1.0], v[1] - v[0])])
    f2 = np.concatenate([f, extra, line[None]])
    rng = np.random.default_rng(13)
    x = np.concatenate([v[[0, 5, 7, 8]] + rng.normal(0, 5e-4, (4, 3)),
                        rng.uniform(-1, 1, (300, 3)) * [R + 2 * RHO, R + 2 * RHO, 2 * RHO]])
    s1, n1 = SurfaceGrid(v2, f2, reach=0.008).signed_distance(x, tau=CONTAIN_SOFTNESS)
    s2, n2 = brute(x, v2, f2, 0.008, CONTAIN_SOFTNESS)
    both = np.isfinite(s1)
    assert both[:4].all() and both.sum() > 100
    np.testing.assert_allclose(s1[both], s2[both], rtol=0, atol=1e-12)
    np.testing.assert_allclose(n1[both], n2[both], rtol=0, atol=1e-9)
