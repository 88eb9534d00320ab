"""fibres.filter_passes: the attachment filter's compiled passes are its steps bit for bit."""
import numpy as np
import pytest
import trimesh

from fibres.filtering import FilterChoice, apply_filter, filter_choices

from test_filtering import _tube_case

FIELDS = ("landmarks", "cut", "segment", "cut_param", "target_face", "target_vertices",
          "target_bary", "piece", "param")


def _cube():
    m = trimesh.creation.box(bounds=[[0, 0, 0], [1, 1, 1]]).subdivide_to_size(0.05)
    return np.asarray(m.vertices), np.asarray(m.faces)


def _grid_on_x0(z0, z1, n=5):
    y, z = np.meshgrid(np.linspace(0.2, 0.8, n), np.linspace(z0, z1, n))
    return np.stack([np.zeros(y.size), y.ravel(), z.ravel()], axis=1)


def _cases():
    """(name, vertices, faces, fibres, origin, insertion, axis, keyword arguments)."""
    rng = np.random.default_rng(5)
    v, f, fib, origin, insertion, _, _ = _tube_case()
    wobbly = fib + rng.normal(0.0, 0.05, fib.shape) * [1, 1, 0.3]
    # reference rays: half straight down/up the tube (they hit the caps' areas), half
    # mirrored (pointing away from their area: they miss, the paper's ray is used)
    ref = fib.copy()
    ref[1::2] = fib[1::2, ::-1]
    yield "tube, both ends, reference hits and misses", v, f, wobbly, origin, insertion, \
        [0, 0, 1], {"reference": ref}
    # one landmark per end at the cap centre: its neighbours (the rim) are farther than the
    # mean edge, so each area is that vertex alone (a point: a lone vertex and its owner face)
    yield "tube, areas of one lone vertex", v, f, wobbly, origin[:1], insertion[:1], \
        [0, 0, 1], {"mean_edge": None}
    # some fibres beyond neither plane, short fibres, P = 2, 3, 7 (the linspace record)
    mixed = wobbly.copy()
    mixed[::3, :, 2] = np.linspace(0.5, 3.5, mixed.shape[1])
    yield "tube, cut and uncut fibres", v, f, mixed, origin, insertion, [0, 0, 1], {}
    for p in (2, 3, 7):
        keep = np.linspace(0, wobbly.shape[1] // 2, p).round().astype(int)   # z -0.5 .. 2
        yield f"tube, P = {p}", v, f, wobbly[:, keep], origin, insertion, [0, 0, 1], {"seed": 3}
    cv, cf = _cube()
    t = np.linspace(0, 1, 40)[None, :, None]
    top = np.column_stack([rng.uniform(0.1, 0.9, (12, 2)), np.ones(12)])
    conv = np.array([0.5, 0.5, 0.0]) + t * (top[:, None] - np.array([0.5, 0.5, 0.0]))
    toward = np.zeros_like(conv)
    toward[..., 0] = np.arange(40) * 0.01
    yield "cube, origin end only, reference hits", cv, cf, conv, _grid_on_x0(0.0, 0.3), \
        np.array([[0.5, 0.5, 1.0]]), [0, 0, 1], {"reference": toward, "mean_edge": 0.05}
    yield "cube, both wide ends, tilted axis", cv, cf, conv, _grid_on_x0(0.0, 0.3), \
        _grid_on_x0(0.7, 1.0), [0.01, -0.02, 1], {}
    yield "cube, nothing beyond the planes", cv, cf, conv, np.array([[0.2, 0.3, 0.0]]), \
        np.array([[0.5, 0.5, 1.0]]), [0, 0, 1], {}


@pytest.mark.parametrize("case", list(_cases()), ids=lambda c: c[0])
def test_fused_passes_equal_the_steps(case, monkeypatch):
    # choices (every field) and filtered points on the rest pose, a deformed copy and the
    # first fibres alone: the compiled passes and the step-by-step path bit for bit
    import fibres.filter_passes as fp

    if fp.passes() is None:
        pytest.skip("numba not installed")
    _, v, f, fib, origin, insertion, axis, kw = case
    moved_v = v + 0.01 * np.sin(v[:, [2, 0, 1]] * 3.0)
    moved = fib + 0.01 * np.sin(fib[..., [2, 0, 1]] * 3.0)

    def run():
        ch = filter_choices(fib, (v, f), origin, insertion, axis, **kw)
        outs = [apply_filter(fib, v, origin, insertion, axis, ch),
                apply_filter(moved, moved_v, origin * 1.01, insertion, axis, ch),
                apply_filter(fib[:5], v, origin, insertion, axis, ch)]
        return ch, outs

    fused, fused_out = run()
    monkeypatch.setattr(fp, "_PASSES", [None])
    steps, steps_out = run()
    for name in FIELDS:
        a, b = getattr(fused, name), getattr(steps, name)
        assert a.dtype == b.dtype and a.shape == b.shape, name
        np.testing.assert_array_equal(a, b, err_msg=name)
        assert not a.flags.writeable
    assert (fused.seed, fused.template) == (steps.seed, steps.template)
    for got, ref in zip(fused_out, steps_out):
        for a, b in zip(got, ref):
            assert a.dtype == b.dtype
            np.testing.assert_array_equal(a, b)
    n_cut = fused.cut.any(axis=1).sum()
    if case[0].startswith("cube, nothing"):
        assert n_cut == 0
    elif "uncut" in case[0]:
        assert 0 < n_cut < len(fib)
    else:
        assert n_cut > len(fib) // 2
    if "reference" in kw and case[0].startswith("tube"):
        # both kinds of ray occur: the misses (odd fibres) end where the paper's ray does,
        # the hits (even fibres, straight down the tube) elsewhere on the cap
        paper = filter_choices(fib, (v, f), origin, insertion, axis)
        same = (paper.target_bary == fused.target_bary).all(axis=(1, 2))
        assert same[1::2].all() and not same[::2].any()
    if "lone" in case[0]:
        # the new ends are the cap centres: a point area, the vertex on its owner's slot
        at = fused.target_vertices[fused.cut] == len(v) - 2              # origin cap centre
        at |= fused.target_vertices[fused.cut] == len(v) - 1             # insertion's
        np.testing.assert_array_equal(fused.target_bary[fused.cut][at], 1.0)
        assert at.sum(axis=1).tolist() == [1] * len(at)


def test_owned_choices_are_read_only_and_equal_to_the_constructor():
    # FilterChoice._owned (arrays made for the choices: no copies) is the constructor's
    # result for arrays of the fields' dtypes
    rng = np.random.default_rng(1)
    n, p = 4, 6
    arrays = (np.array([1, 0]), rng.random((n, 2)) > 0.5, rng.integers(0, 5, (n, 2)),
              rng.random((n, 2)), rng.integers(-1, 9, (n, 2)), rng.integers(0, 9, (n, 2, 3)),
              rng.random((n, 2, 3)), rng.integers(0, 3, (n, p)).astype(np.int8),
              rng.random((n, p)))
    made = FilterChoice(*arrays, seed=7, template=("parallel", ()))
    owned = FilterChoice._owned(*[a.copy() for a in arrays], seed=7, template=("parallel", ()))
    for name in FIELDS:
        a, b = getattr(owned, name), getattr(made, name)
        assert a.dtype == b.dtype and not a.flags.writeable
        np.testing.assert_array_equal(a, b)
    assert (owned.seed, owned.template, owned.n_fibres, owned.n_points) == (
        7, ("parallel", ()), n, p)
    with pytest.raises(Exception):
        owned.seed = 3


@pytest.mark.parametrize("surface", ["cap", "tube", "random"])
def test_restricted_search_pre_test_changes_nothing(surface, monkeypatch):
    # closest_on_triangles(..., within=w): the separating-axis pre-test on the blocks' and
    # triangles' boxes only returns -1 early; indices and barycentric coordinates are bit
    # for bit those without it, for rays that hit, graze (just inside / outside w) or miss
    import fibres.ray_triangles as rt

    if rt._kernels() is None:
        pytest.skip("numba not installed")
    rng = np.random.default_rng(4)
    if surface == "cap":
        m = trimesh.creation.icosphere(subdivisions=4)
        v, f = np.asarray(m.vertices), np.asarray(m.faces)
        f = f[(v[f][:, :, 2] > 0.6).all(axis=1)]
    elif surface == "tube":
        from test_filtering import tube
        v, f = tube()
    else:
        v = rng.uniform(-1, 1, (300, 3))
        f = rng.integers(0, 300, (200, 3))
        f[:10] = f[:10, :1]                                # points (lone vertices)
    tv = v[f]
    n = 400
    start = rng.uniform(-1.5, 1.5, (n, 3)) + [0.0, 0.0, 0.8 if surface != "random" else 0.0]
    direction = rng.standard_normal((n, 3))
    k_all, b_all = rt.closest_on_triangles(tv, start, direction, corner_ids=f)
    p = np.einsum("nk,nkc->nc", b_all, tv[k_all]) - start
    d = direction / np.linalg.norm(direction, axis=1, keepdims=True)
    dist = np.linalg.norm(p - np.maximum(np.einsum("nc,nc->n", p, d), 0)[:, None] * d, axis=1)
    for w in (0.0, 1e-9, 0.02, 0.2, float(np.median(dist))):
        got = rt.closest_on_triangles(tv, start, direction, within=w, corner_ids=f)
        with monkeypatch.context() as mp:
            mp.setattr(rt, "_HIT_BLOCKS", (0, 1))
            ref = rt.closest_on_triangles(tv, start, direction, within=w, corner_ids=f)
        np.testing.assert_array_equal(got[0], ref[0])
        np.testing.assert_array_equal(got[1], ref[1])
        assert ((got[0] >= 0) == (dist <= w * (1 + 1e-9) + 1e-12)).all()
    # rays grazing a triangle's corner at just under / over the radius
    w = 0.05
    corner = tv[len(tv) // 2, 0]
    side = np.cross(d[:20], rng.standard_normal((20, 3)))
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    for scale in (0.999, 1.001):
        s0 = corner + scale * w * side - d[:20]              # passes the corner at scale * w
        got = rt.closest_on_triangles(tv, s0, d[:20], within=w, corner_ids=f)
        with monkeypatch.context() as mp:
            mp.setattr(rt, "_HIT_BLOCKS", (0, 1))
            ref = rt.closest_on_triangles(tv, s0, d[:20], within=w, corner_ids=f)
        np.testing.assert_array_equal(got[0], ref[0])
        np.testing.assert_array_equal(got[1], ref[1])
        if scale < 1:
            assert (got[0] >= 0).all()
