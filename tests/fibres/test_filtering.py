"""fibres.attachments.filtering.trim_and_reconstruct: Kohout 2012 §3.4 on a box with known attachments."""
import numpy as np
import pytest
import trimesh

from fibres.attachments.filtering import attachment_region, trim_and_reconstruct

P = 40


@pytest.fixture(scope="module")
def cube():
    m = trimesh.creation.box(bounds=[[0, 0, 0], [1, 1, 1]]).subdivide_to_size(0.05)
    return np.asarray(m.vertices), np.asarray(m.faces)


def _grid_on_x0(z0, z1, n=5):
    y, z = np.meshgrid(np.linspace(0.2, 0.8, n), np.linspace(z0, z1, n))
    return np.stack([np.zeros(y.size), y.ravel(), z.ravel()], axis=1)


def _converging_fibres(n=12):
    # fibres meeting in one point at the bottom (the unrealistic case of Fig. 8) and spread
    # over the top
    rng = np.random.default_rng(5)
    top = np.column_stack([rng.uniform(0.1, 0.9, (n, 2)), np.ones(n)])
    t = np.linspace(0, 1, P)[None, :, None]
    return np.array([0.5, 0.5, 0.0]) + t * (top[:, None] - np.array([0.5, 0.5, 0.0]))


def test_origin_side_trim_and_reconstruct(cube):
    v, f = cube
    fib = _converging_fibres()
    origin = _grid_on_x0(0.0, 0.3)              # wide origin area up the x=0 side: plane z=0.3
    insertion = np.array([[0.5, 0.5, 1.0]])     # on the top face: nothing beyond its plane
    out, trimmed, recon = trim_and_reconstruct(fib, (v, f), origin, insertion, [0, 0, 1])
    assert out.shape == fib.shape
    assert trimmed.all() and recon.all()
    np.testing.assert_allclose(out[:, -1], fib[:, -1], atol=1e-15)  # insertion end untouched
    region = attachment_region(v, f, origin)
    # the area's surface: faces with all three corners in the area (independent of the code)
    in_area = (np.linalg.norm(v[:, None] - region[None], axis=2) == 0).any(axis=1)
    tris = v[f[in_area[f].all(axis=1)]]                                  # (T, 3, 3)
    # dense samples of those triangles: a barycentric grid of 21 x 21
    g = np.linspace(0, 1, 21)
    bu, bv = np.meshgrid(g, g)
    keep = bu + bv <= 1 + 1e-12
    bw = np.stack([1 - bu[keep] - bv[keep], bu[keep], bv[keep]], 1)       # (S, 3)
    samples = np.concatenate([np.einsum("sk,tkc->tsc", bw, tris).reshape(-1, 3), region])
    a, b = fib[:, 0], fib[:, -1]

    def ray_distance(q, c, d):
        s = np.maximum((q - c) @ d, 0.0)
        return np.linalg.norm(q - c - s[..., None] * d, axis=-1)

    for k in range(len(fib)):  # independent brute-force check, fibre by fibre
        # the cut point is where the original line crosses z = 0.3
        c = a[k] + 0.3 * (b[k] - a[k])
        d = (a[k] - b[k]) / np.linalg.norm(a[k] - b[k])  # ray continuing the kept segment
        best = out[k, 0]
        # the new end lies on the area's surface (within 1e-12 of one of its triangles:
        # on the cube's x = 0 / z = 0 faces, inside the triangle's bounding box there)
        on_plane = np.isclose(best[0], 0.0, atol=1e-12) | np.isclose(best[2], 0.0, atol=1e-12)
        inside = ((tris.min(axis=1) - 1e-12 <= best) & (best <= tris.max(axis=1) + 1e-12)).all(1)
        assert on_plane and inside.any()
        # and is at least as close to the ray as every sample of the area's surface and
        # every area vertex (the paper's "closest to the ray"); 1e-12: rounding
        assert ray_distance(best, c, d) <= ray_distance(samples, c, d).min() + 1e-12
        # on the area: within the region radius (landmark spacing 0.15) of a landmark, plus
        # one edge (a point of a triangle is within one edge of its corners; edges <= 0.05)
        assert np.linalg.norm(origin - out[k, 0], axis=1).min() <= 0.15 + 0.05 * np.sqrt(2)
        # the kept part (above the plane) is still the original line
        # (points whose arc length from the new start exceeds the new segment's length)
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(out[k], axis=0), axis=1))])
        up = out[k, arc > np.linalg.norm(best - c) + 1e-12]
        assert len(up) > P // 2
        line_dir = (b[k] - a[k]) / np.linalg.norm(b[k] - a[k])
        rel = up - a[k]
        np.testing.assert_allclose(np.cross(rel, line_dir), 0.0, atol=1e-12)
        # uniform arc-length resampling of [end, c, ..., b]: length is preserved except at the
        # one corner at c, where chords cut at most one segment's worth
        true_len = np.linalg.norm(best - c) + np.linalg.norm(b[k] - c)
        new_len = np.linalg.norm(np.diff(out[k], axis=0), axis=1).sum()
        assert true_len * (1 - 1.0 / (P - 1)) <= new_len <= true_len + 1e-12
    # the reconstructed starts no longer meet in one point
    assert len(np.unique(out[:, 0], axis=0)) > len(fib) // 4


def test_reference_rays_end_where_they_hit_the_area(cube):
    # the template's own direction (the reference fibres) replaces the morphed segment's
    # where its ray from the cut hits the area: here a ray towards -x from every cut point
    # (z = 0.3, y in [0.38, 0.62]) hits the area on the wall x = 0 at (0, y, 0.3) -- inside
    # the area (landmarks y in [0.2, 0.8], z in [0, 0.3]): the new start is that hit point
    from fibres.attachments.filtering import apply_filter, filter_choices

    v, f = cube
    fib = _converging_fibres()
    origin, insertion = _grid_on_x0(0.0, 0.3), np.array([[0.5, 0.5, 1.0]])
    toward_wall = np.zeros_like(fib)
    toward_wall[..., 0] = np.arange(P) * 0.01              # segment a -> b points along -x
    ch = filter_choices(fib, (v, f), origin, insertion, [0, 0, 1], reference=toward_wall)
    out = apply_filter(fib, v, origin, insertion, [0, 0, 1], ch)[0]
    cut = fib[:, 0] + 0.3 * (fib[:, -1] - fib[:, 0])       # the line crosses z = 0.3
    np.testing.assert_allclose(out[:, 0], np.c_[np.zeros(len(fib)), cut[:, 1:]], atol=1e-12)
    # a reference ray that misses the area (towards +x, the far wall) keeps the paper's ray
    plain = trim_and_reconstruct(fib, (v, f), origin, insertion, [0, 0, 1])[0]
    ch = filter_choices(fib, (v, f), origin, insertion, [0, 0, 1], reference=-toward_wall)
    np.testing.assert_array_equal(apply_filter(fib, v, origin, insertion, [0, 0, 1], ch)[0],
                                  plain)


def test_insertion_side_is_symmetric(cube):
    v, f = cube
    fib = _converging_fibres()[:, ::-1]          # now they meet at the TOP end... reversed
    fib = fib.copy()
    fib[..., 2] = 1.0 - fib[..., 2]              # mirror so index 0 is at z=0 again
    # fibres now run from spread bottom points to one top point (0.5, 0.5, 1)
    insertion = _grid_on_x0(0.7, 1.0)
    origin = np.array([[0.5, 0.5, 0.0]])
    out, trimmed, recon = trim_and_reconstruct(fib, (v, f), origin, insertion, [0, 0, 1])
    assert trimmed.all() and recon.all()
    np.testing.assert_allclose(out[:, 0], fib[:, 0], atol=1e-15)
    near = np.linalg.norm(insertion[None] - out[:, -1, None], axis=2).min(axis=1)
    assert (near <= 0.15 + 1e-12).all()  # within the region radius (landmark spacing 0.15)
    assert (out[:, -1, 2] >= 0.7 - 0.15).all()


def test_fibres_not_beyond_the_planes_are_unchanged(cube):
    v, f = cube
    fib = _converging_fibres()
    origin = np.array([[0.2, 0.3, 0.0], [0.7, 0.6, 0.0]])   # plane z = 0: nothing below it
    insertion = np.array([[0.5, 0.5, 1.0]])
    out, trimmed, recon = trim_and_reconstruct(fib, (v, f), origin, insertion, [0, 0, 1])
    np.testing.assert_array_equal(out, fib)
    assert not trimmed.any() and not recon.any()


def test_overlapping_attachment_bands_leave_fibres_alone(cube):
    v, f = cube
    fib = _converging_fibres()
    out, trimmed, _ = trim_and_reconstruct(fib, (v, f), _grid_on_x0(0.0, 0.8),
                                           _grid_on_x0(0.5, 1.0), [0, 0, 1])
    np.testing.assert_array_equal(out, fib)
    assert not trimmed.any()


def test_attachment_region_of_one_landmark_is_its_neighbourhood(cube):
    v, f = cube
    reg = attachment_region(v, f, np.array([[0.0, 0.5, 0.5]]))
    assert len(reg) >= 1
    # all within one mean edge length of the projected landmark
    edges = np.linalg.norm(v[f[:, [1, 2, 0]]] - v[f], axis=-1).mean()
    assert (np.linalg.norm(reg - [0.0, 0.5, 0.5], axis=1) <= edges + 1e-12).all()


# --- ties, frozen choices (apply_filter) -------------------------------------------------

def test_fibre_ends_on_the_planes_are_not_trimmed(cube):
    # flat caps: the fibres run from the bottom face to the top face and the landmarks lie
    # on those faces, so every end is ON its plane; rounding noise of 1e-15 (far below the
    # tie tolerance TIE * diagonal = 1.7e-9) must not decide that they are beyond it
    from fibres.attachments.filtering import TIE

    v, f = cube
    xy = np.random.default_rng(1).uniform(0.1, 0.9, (20, 2))
    t = np.linspace(0, 1, P)
    fib = np.concatenate([np.broadcast_to(xy[:, None], (20, P, 2)),
                          np.broadcast_to(t[None, :, None], (20, P, 1))], axis=2).copy()
    fib[::2, 0, 2] = -1e-15
    fib[1::2, -1, 2] = 1.0 + 1e-15
    origin = np.array([[0.2, 0.2, 0.0], [0.8, 0.7, 0.0]])
    insertion = np.array([[0.3, 0.6, 1.0], [0.7, 0.2, 1.0]])
    assert 1e-15 < TIE * np.sqrt(3) * 1e-3
    out, trimmed, _ = trim_and_reconstruct(fib, (v, f), origin, insertion, [0, 0, 1])
    assert not trimmed.any()
    np.testing.assert_array_equal(out, fib)


def _wide_case(cube):
    v, f = cube
    return v, f, _converging_fibres(), _grid_on_x0(0.0, 0.3), _grid_on_x0(0.7, 1.0)


def test_recorded_choices_reproduce_the_paper_filter_exactly(cube):
    from fibres.attachments.filtering import apply_filter, filter_choices

    v, f, fib, origin, insertion = _wide_case(cube)
    ref, trimmed, _ = trim_and_reconstruct(fib, (v, f), origin, insertion, [0, 0, 1])
    assert trimmed.all()
    choice = filter_choices(fib, (v, f), origin, insertion, [0, 0, 1])
    out, t2, _ = apply_filter(fib, v, origin, insertion, [0, 0, 1], choice)
    np.testing.assert_array_equal(out, ref)
    np.testing.assert_array_equal(t2, trimmed)
    # the first n fibres' choices serve a smaller bundle (Sobol fibre k is the same for all N)
    head, _, _ = apply_filter(fib[:5], v, origin, insertion, [0, 0, 1], choice)
    np.testing.assert_array_equal(head, ref[:5])
    with pytest.raises(ValueError, match="choices are for"):
        apply_filter(np.concatenate([fib, fib]), v, origin, insertion, [0, 0, 1], choice)


def _rotation(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ np.array([[1, 0, 0], [0, c, s],
                                                                    [0, -s, c]])


def test_recorded_choices_move_rigidly(cube):
    # a rigid motion of fibres, surface, landmarks and axis moves the filtered fibres rigidly
    from fibres.attachments.filtering import apply_filter, filter_choices

    v, f, fib, origin, insertion = _wide_case(cube)
    choice = filter_choices(fib, (v, f), origin, insertion, [0, 0, 1])
    ref, _, _ = apply_filter(fib, v, origin, insertion, [0, 0, 1], choice)
    rot, shift = _rotation(0.7), np.array([0.3, -1.0, 2.0])
    moved, _, _ = apply_filter(fib @ rot.T + shift, v @ rot.T + shift, origin @ rot.T + shift,
                               insertion @ rot.T + shift, rot[:, 2], choice)
    np.testing.assert_allclose(moved, ref @ rot.T + shift, atol=1e-12)


def test_recorded_choices_are_smooth_under_deformation(cube):
    # fibres, surface and landmarks deformed by a smooth map x -> x + e g(x): with the
    # choices frozen the filtered fibres are a smooth function of e, so central differences
    # at h and 2h agree to O(h^2) (a flipped choice -- another target vertex, another cut
    # segment -- would make them differ by jump / h ~ 1e3)
    from fibres.attachments.filtering import apply_filter, filter_choices

    v, f, fib, origin, insertion = _wide_case(cube)

    def g(x):
        return np.c_[0.05 * np.sin(3 * x[:, 2]), 0.04 * x[:, 0] * x[:, 2], 0.03 * x[:, 1] ** 2]

    def run(e):
        def d(x):
            return (x.reshape(-1, 3) + e * g(x.reshape(-1, 3))).reshape(x.shape)
        return apply_filter(d(fib), d(v), d(origin), d(insertion), [0, 0, 1], choice)[0]

    choice = filter_choices(fib, (v, f), origin, insertion, [0, 0, 1])
    h = 1e-4
    d1 = (run(h) - run(-h)) / (2 * h)
    d2 = (run(2 * h) - run(-2 * h)) / (4 * h)
    scale = np.abs(d1).max()
    assert scale > 1e-3
    # O(h^2) truncation with second derivatives of order 1: |d1 - d2| ~ h^2 ~ 1e-8
    assert np.abs(d1 - d2).max() <= 1e-6 * scale


def test_region_equals_the_definition(cube):
    # the attachment area by its definition (module docstring) with scipy's KD-tree: the
    # search must give exactly it (no ties on this jittered cube)
    from scipy.spatial import cKDTree

    import fibres.attachments.area as fl
    import fibres.attachments.ray_triangles as rt

    rng = np.random.default_rng(2)
    v = cube[0] + 1e-4 * rng.standard_normal(cube[0].shape)
    f = cube[1]
    lms = _grid_on_x0(0.1, 0.3, 3) + [0.02, 0.0, 0.0]
    tree = cKDTree(v)
    _, nearest = tree.query(lms)
    radius = max(np.linalg.norm(v[f[:, [1, 2, 0]]] - v[f], axis=-1).mean(),
                 np.median(cKDTree(lms).query(lms, k=2)[0][:, 1]))
    near = tree.query_ball_point(v[np.unique(nearest)], r=radius)
    ref = np.unique(np.concatenate([np.asarray(n, np.int64) for n in near] + [nearest]))
    assert 5 < ref.size < len(v) // 4                  # a real area, not one point or all
    np.testing.assert_array_equal(fl._region_indices(v, f, lms), ref)
    # the area's triangles: the faces with all corners in it (definition), plus each
    # area vertex on none of them as a point held by a face with that corner
    corners, owner = rt.region_triangles(f, ref, len(v))
    full = np.flatnonzero(np.isin(f, ref).all(axis=1))
    np.testing.assert_array_equal(owner[:len(full)], full)
    np.testing.assert_array_equal(corners[:len(full)], f[full])
    lone = np.setdiff1d(ref, f[full])
    np.testing.assert_array_equal(corners[len(full):], np.repeat(lone[:, None], 3, 1))
    assert (f[owner[len(full):]] == lone[:, None]).any(axis=1).all()
    # the mean edge (the area's minimum radius): summation order only, 1e-12 relative
    edge = fl._mean_edge(np.ascontiguousarray(v.T), f)
    assert edge == pytest.approx(np.linalg.norm(v[f[:, [1, 2, 0]]] - v[f], axis=-1).mean(),
                                 rel=1e-12)


# --- the new end: the surface point of the area closest to the ray (paper §3.4) ----------

def test_closest_point_on_triangles_is_first_hit_or_nearest():
    # random triangles and rays: where a ray hits some triangle, the answer is the hit with
    # the smallest ray parameter (each hit solved independently as the 3x3 system
    # s + t d = a + u (b - a) + v (c - a)); otherwise no surface sample is closer to the ray
    import fibres.attachments.ray_triangles as rt

    rng = np.random.default_rng(7)
    tv = rng.uniform(-1, 1, (30, 3, 3))
    tv[5] = tv[5, 0]                                     # a degenerate triangle (a point)
    start = rng.uniform(-1.5, 1.5, (200, 3))
    direction = rng.standard_normal((200, 3))
    k, bary = rt.closest_on_triangles(tv, start, direction)
    assert ((bary >= -1e-12) & (bary <= 1 + 1e-12)).all()
    np.testing.assert_allclose(bary.sum(axis=1), 1.0, atol=1e-12)
    end = np.einsum("nk,nkc->nc", bary, tv[k])
    d = direction / np.linalg.norm(direction, axis=1, keepdims=True)
    g = np.linspace(0, 1, 31)
    bu, bv = np.meshgrid(g, g)
    keep = bu + bv <= 1 + 1e-12
    bw = np.stack([1 - bu[keep] - bv[keep], bu[keep], bv[keep]], 1)
    samples = np.einsum("sk,tkc->tsc", bw, tv).reshape(-1, 3)
    n_hit = 0
    for n in range(len(start)):  # brute force reference, ray by ray
        hits = []
        for t_ in range(len(tv)):
            m = np.column_stack([tv[t_, 1] - tv[t_, 0], tv[t_, 2] - tv[t_, 0], -d[n]])
            if abs(np.linalg.det(m)) < 1e-9:
                continue
            u, v, t = np.linalg.solve(m, start[n] - tv[t_, 0])
            if u >= 0 and v >= 0 and u + v <= 1 and t >= 0:
                hits.append(t)
        rel = samples - start[n]
        s = np.maximum(rel @ d[n], 0.0)
        ref = np.linalg.norm(rel - s[:, None] * d[n], axis=1).min()
        q = end[n] - start[n]
        got = np.linalg.norm(q - max(q @ d[n], 0.0) * d[n])
        if hits:
            n_hit += 1
            # on the ray at the first hit (1e-12: rounding of unit-size coordinates)
            np.testing.assert_allclose(end[n], start[n] + min(hits) * d[n], atol=1e-12)
        else:
            assert got <= ref + 1e-12
    assert 20 < n_hit < 180                              # both branches are exercised


def test_closest_on_triangles_with_shared_corner_ids_is_the_same_answer():
    # corner_ids (the mesh's vertex indices) only let the compiled loop project each shared
    # corner once per ray: indices and barycentric coordinates are bit for bit those
    # without them, with and without `within` (rays towards and past a tube's wall)
    import fibres.attachments.ray_triangles as rt

    v, f = tube()
    rng = np.random.default_rng(3)
    start = rng.uniform(-1.5, 1.5, (300, 3)) + [0.0, 0.0, 2.0]
    direction = rng.standard_normal((300, 3))
    for within in (None, 0.05):
        a = rt.closest_on_triangles(v[f], start, direction, within=within)
        b = rt.closest_on_triangles(v[f], start, direction, within=within, corner_ids=f)
        np.testing.assert_array_equal(a[0], b[0])
        np.testing.assert_array_equal(a[1], b[1])
        assert (a[0] >= 0).sum() > 50 and (within is None or (a[0] < 0).sum() > 10)


def tube(length=4.0, radius=1.0, n_around=24, n_along=20):
    """Closed cylinder along z from 0 to ``length`` with flat caps whose only vertices are
    the centre and the rim (as in tests/analysis/test_run_cylinders.py)."""
    th = np.linspace(0, 2 * np.pi, n_around, endpoint=False)
    z = np.linspace(0, length, n_along + 1)
    ring = radius * np.c_[np.cos(th), np.sin(th)]
    v = np.concatenate([np.c_[np.tile(ring, (len(z), 1)), np.repeat(z, n_around)],
                        [[0, 0, 0], [0, 0, length]]])
    i, j = np.meshgrid(np.arange(n_along), np.arange(n_around), indexing="ij")
    a, b = i * n_around + j, i * n_around + (j + 1) % n_around
    jj = np.arange(n_around)
    top = n_along * n_around
    f = np.concatenate([np.stack([a, b, b + n_around], -1).reshape(-1, 3),
                        np.stack([a, b + n_around, a + n_around], -1).reshape(-1, 3),
                        np.stack([np.full(n_around, len(v) - 2), (jj + 1) % n_around, jj], -1),
                        np.stack([np.full(n_around, len(v) - 1), top + jj,
                                  top + (jj + 1) % n_around], -1)])
    return v, f


def _tube_case(n=30):
    # landmarks: the cap centre, a ring at 0.6 R on the cap and a ring on the side wall at
    # 0.3 from the cap (the extreme landmarks: the cutting planes are z = 0.3 and z = 3.7);
    # straight slanted fibres overshooting both caps by 0.5 (a morph overshoot)
    v, f = tube()
    th = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    cap = np.r_[[[0.0, 0.0]], 0.6 * np.c_[np.cos(th), np.sin(th)]]
    wall = np.c_[np.cos(th + 0.2), np.sin(th + 0.2)]
    origin = np.r_[np.c_[cap, np.zeros(9)], np.c_[wall, np.full(8, 0.3)]]
    insertion = np.r_[np.c_[cap, np.full(9, 4.0)], np.c_[wall, np.full(8, 3.7)]]
    rng = np.random.default_rng(3)
    r0 = 0.45 * np.sqrt(rng.uniform(0, 1, (2, n)))
    a0 = rng.uniform(0, 2 * np.pi, (2, n))
    lo = np.c_[r0[0] * np.cos(a0[0]), r0[0] * np.sin(a0[0]), np.full(n, -0.5)]
    hi = np.c_[r0[1] * np.cos(a0[1]), r0[1] * np.sin(a0[1]), np.full(n, 4.5)]
    fib = lo[:, None] + np.linspace(0, 1, P)[None, :, None] * (hi - lo)[:, None]
    return v, f, fib, origin, insertion, lo, hi


def test_flat_cap_end_is_the_ray_cap_intersection_and_fibres_stay_straight():
    v, f, fib, origin, insertion, lo, hi = _tube_case()
    out, trimmed, recon = trim_and_reconstruct(fib, (v, f), origin, insertion, [0, 0, 1])
    assert trimmed.all() and recon.all()
    # closed form: the fibre's line meets the caps z = 0 and z = 4 (inside the cap discs of
    # radius 1: |xy| <= 0.45 + 0.05); rounding of unit-size coordinates: 1e-12
    e0 = lo + (0.0 - lo[:, 2:]) / (hi - lo)[:, 2:] * (hi - lo)
    e1 = lo + (4.0 - lo[:, 2:]) / (hi - lo)[:, 2:] * (hi - lo)
    np.testing.assert_allclose(out[:, 0], e0, atol=1e-12)
    np.testing.assert_allclose(out[:, -1], e1, atol=1e-12)
    # straight: every point on the chord of its ends, within 1e-9 of the length L (the
    # closest VERTEX would kink each end towards the cap centre or rim: ~0.1 L)
    chord = out[:, -1] - out[:, 0]
    L = np.linalg.norm(chord, axis=1)
    rel = out - out[:, :1]
    dev = np.linalg.norm(np.cross(rel, chord[:, None] / L[:, None, None]), axis=-1)
    assert (dev <= 1e-9 * L[:, None]).all()
    # and uniformly resampled (the arc-length resampling of a straight line)
    steps = np.linalg.norm(np.diff(out, axis=1), axis=-1)
    np.testing.assert_allclose(steps, np.broadcast_to(L[:, None] / (P - 1), steps.shape), rtol=1e-9)


def test_flat_cap_filter_is_rigid_motion_equivariant():
    # making the choices and applying them commute with a rigid motion of every input
    v, f, fib, origin, insertion, _, _ = _tube_case()
    ref, _, _ = trim_and_reconstruct(fib, (v, f), origin, insertion, [0, 0, 1])
    rot, shift = _rotation(1.1), np.array([-2.0, 0.5, 3.0])
    moved, _, _ = trim_and_reconstruct(fib @ rot.T + shift, (v @ rot.T + shift, f),
                                       origin @ rot.T + shift, insertion @ rot.T + shift,
                                       rot[:, 2])
    np.testing.assert_allclose(moved, ref @ rot.T + shift, atol=1e-12)


def test_plan_reuse_keeps_the_end_on_its_material_point():
    # choices made at rest, applied to a smoothly deformed copy: each new end is the same
    # material point -- the same cap triangle and barycentric coordinates. These are found
    # here from the rest-pose end (the cap-fan triangle containing it, 2-D solve), not read
    # from the choice.
    from fibres.attachments.filtering import apply_filter, filter_choices

    v, f, fib, origin, insertion, _, _ = _tube_case()
    choice = filter_choices(fib, (v, f), origin, insertion, [0, 0, 1])
    rest, _, _ = apply_filter(fib, v, origin, insertion, [0, 0, 1], choice)

    def deform(x):
        x = x.reshape(-1, 3)
        return x + np.c_[0.1 * np.sin(x[:, 2]) + 0.05 * x[:, 1] ** 2, 0.08 * x[:, 0] * x[:, 2],
                         0.04 * x[:, 0] ** 2 + 0.03 * x[:, 1]]

    out, _, _ = apply_filter(deform(fib).reshape(fib.shape), deform(v), deform(origin),
                             deform(insertion), [0, 0, 1], choice)
    cap = f[np.isin(f, [len(v) - 2]).any(axis=1)]                       # origin cap fan
    for k in range(len(fib)):  # reference, fibre by fibre
        p = rest[k, 0]
        for tri in cap:
            m = np.column_stack([v[tri[1], :2] - v[tri[0], :2], v[tri[2], :2] - v[tri[0], :2]])
            uu, vv = np.linalg.solve(m, p[:2] - v[tri[0], :2])
            if uu >= -1e-12 and vv >= -1e-12 and uu + vv <= 1 + 1e-12:
                break
        else:
            raise AssertionError("rest end not on the origin cap")
        want = (1 - uu - vv) * deform(v[tri[0]]) + uu * deform(v[tri[1]]) + vv * deform(v[tri[2]])
        np.testing.assert_allclose(out[k, 0], want[0], atol=1e-12)
    # the deformation really moves the ends (not a trivial check): by 1e-3 .. 0.03, far
    # above the 1e-12 tolerance
    assert np.linalg.norm(out[:, 0] - rest[:, 0], axis=1).min() > 1e-3




def test_regions_triangles_is_region_triangles_of_each_area():
    # regions_triangles marks each area's vertices with its own bit and collects the full
    # faces of all areas in one pass over the faces: for overlapping areas with lone
    # vertices (points on no full face) every area's corners and owning faces must be
    # exactly region_triangles'
    import fibres.attachments.ray_triangles as rt

    v, f = tube()
    rng = np.random.default_rng(5)
    areas = [np.flatnonzero(v[:, 2] < 1.0),                          # a cap and its rim
             np.flatnonzero((v[:, 2] > 0.5) & (v[:, 2] < 2.5)),      # overlaps the first
             np.sort(rng.choice(len(v), 40, replace=False))]         # scattered: lone points
    got = rt.regions_triangles(f, areas, len(v))
    n_lone = 0
    for area, (corners, face) in zip(areas, got):
        ref_c, ref_f = rt.region_triangles(f, area, len(v))
        np.testing.assert_array_equal(corners, ref_c)
        np.testing.assert_array_equal(face, ref_f)
        n_lone += int((corners[:, 0] == corners[:, 1]).sum())
    assert n_lone > 10 and len(got[0][0]) > 20 and len(got[1][0]) > 20   # not vacuous
