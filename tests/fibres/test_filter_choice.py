"""fibres.attachments.filtering.FilterChoice: the owned (read-only) choices of the attachment filter."""
import numpy as np
import pytest
import trimesh

from fibres.attachments.filtering import FilterChoice

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


