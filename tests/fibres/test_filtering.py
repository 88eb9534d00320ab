"""fibres.filtering.trim_and_reconstruct: Kohout 2012 §3.4 on a box with known attachments."""
import numpy as np
import pytest
import trimesh

from fibres.filtering import attachment_region, trim_and_reconstruct

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
    a, b = fib[:, 0], fib[:, -1]
    for k in range(len(fib)):  # independent brute-force check, fibre by fibre
        # the cut point is where the original line crosses z = 0.3
        c = a[k] + 0.3 * (b[k] - a[k])
        d = (a[k] - b[k]) / np.linalg.norm(a[k] - b[k])  # ray continuing the kept segment
        best, best_dist = None, np.inf
        for q in region:
            s = max((q - c) @ d, 0.0)
            dist = np.linalg.norm(q - c - s * d)
            if dist < best_dist:
                best, best_dist = q, dist
        np.testing.assert_allclose(out[k, 0], best, atol=1e-12)
        # on the area: within the region radius (landmark spacing 0.15) of a landmark
        assert np.linalg.norm(origin - out[k, 0], axis=1).min() <= 0.15 + 1e-12
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
    from fibres.filtering import TIE

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
    from fibres.filtering import apply_filter, filter_choices

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
    from fibres.filtering import apply_filter, filter_choices

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
    from fibres.filtering import apply_filter, filter_choices

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


def test_compiled_region_and_ray_search_equal_numpy_and_the_definition(cube, monkeypatch):
    # the attachment area by its definition (module docstring) with scipy's KD-tree, and the
    # closest-to-ray vertex by brute force: the compiled loops and the numpy fallback must
    # give exactly these (no ties on this jittered cube)
    from scipy.spatial import cKDTree

    import fibres.filtering as fl

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
    start = rng.uniform(0.2, 0.8, (50, 3))
    direction = rng.standard_normal((50, 3))
    cand = v[ref]
    dn = direction / np.linalg.norm(direction, axis=1, keepdims=True)
    rel = cand[None] - start[:, None]
    t = np.maximum((rel * dn[:, None]).sum(-1), 0.0)
    ray_ref = np.argmin(np.linalg.norm(rel - t[..., None] * dn[:, None], axis=-1), axis=1)
    for kernels in ("compiled", "numpy"):
        if kernels == "numpy":
            monkeypatch.setattr(fl, "_KERNELS", [None])
        np.testing.assert_array_equal(fl._region_indices(v, f, lms), ref)
        np.testing.assert_array_equal(fl._closest_to_rays(cand, start, direction), ray_ref)
        # the mean edge (the area's minimum radius): summation order only, 1e-12 relative
        edge = fl._mean_edge(np.ascontiguousarray(v.T), f)
        assert edge == pytest.approx(np.linalg.norm(v[f[:, [1, 2, 0]]] - v[f], axis=-1).mean(),
                                     rel=1e-12)
