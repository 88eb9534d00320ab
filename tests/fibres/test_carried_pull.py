"""fibres.finishing.carried_pull: the rest pose's pull, carried to frames in wall frames."""
import numpy as np
import trimesh

from fibres.finishing.carried_pull import (REST_MARGIN, REST_ROUNDS, _frames, carry_rest_pull,
                                           pull_rounds)
from fibres.finishing.containment import CONTAIN_REACH
from fibres.mesh.surface_distance import SurfaceGrid

from test_containment import SAG, chords, torus, torus_sd  # noqa: F401 - the torus fixture


def test_at_rest_the_carried_pull_is_the_rest_pull(torus):
    """Applied to the rest pose it gives what the pull and its spread rounds give there (the
    displacement's coordinates in an orthogonal frame of equal sides are exact to rounding),
    and every inner point ends at least REST_MARGIN / 2 inside the mesh."""
    v, f = torus
    fib = chords()
    assert torus_sd(fib).max() > 3e-3                       # chords leave through the hole
    carried = carry_rest_pull(fib, v, f)
    expected, moved = pull_rounds(fib, SurfaceGrid(v, f, reach=CONTAIN_REACH),
                                  margin=REST_MARGIN, rounds=REST_ROUNDS)
    got = carried.apply(fib, v)
    # displacements are a few mm: rounding of a 3 x 3 frame product, ~1e-18 m
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(carried.fibres, np.any(expected != fib, axis=(1, 2)))
    assert moved.any()
    s, _ = SurfaceGrid(v, f, reach=CONTAIN_REACH).signed_distance(
        got[:, 1:-1].reshape(-1, 3), tau=5e-5, offset=True)
    # pulled points end below -REST_MARGIN / 2 (the correction step lands them within ~5 um
    # of their target near mesh edges, as for `contain`); the torus lies within SAG of it
    assert s.max() <= -REST_MARGIN / 2 + 5e-6
    assert torus_sd(got[:, 1:-1]).max() <= -REST_MARGIN / 2 + 5e-6 + SAG
    np.testing.assert_array_equal(got[:, [0, -1]], fib[:, [0, -1]])


def test_a_rigid_motion_and_a_scale_carry_the_displacements_alike(torus):
    v, f = torus
    fib = chords()
    carried = carry_rest_pull(fib, v, f)
    rest = carried.apply(fib, v)
    rng = np.random.default_rng(5)
    q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    q *= np.sign(np.linalg.det(q))
    t, scale = np.array([0.3, -0.1, 0.7]), 1.7
    moved = carried.apply(scale * fib @ q.T + t, scale * v @ q.T + t)
    # e' = scale Q e: the frame's sides turn with the wall and scale with sqrt(patch area)
    np.testing.assert_allclose(moved, scale * rest @ q.T + t, rtol=0, atol=1e-14)


def test_a_patch_takes_no_triangle_of_the_opposite_wall():
    """A slab 2 mm thin: a point pulled in through its top face is carried by a frame whose
    normal is the top face's (+z), and its neighbours moved by the spread (1 mm from either
    face) by one face's, +z or -z, never a mean of the two walls."""
    slab = trimesh.creation.box(extents=(0.04, 0.04, 0.002))
    slab = slab.subdivide().subdivide()                    # triangles of ~5 mm
    v, f = np.asarray(slab.vertices), np.asarray(slab.faces)
    fib = np.zeros((1, 5, 3))
    fib[0, :, 0] = np.linspace(-0.015, 0.015, 5)
    fib[0, 2, 2] = 0.0015                                  # 0.5 mm above the top face
    carried = carry_rest_pull(fib, v, f)
    assert carried.rows.size
    frames, _ = _frames(v, carried.faces, carried.patches, carried.first)
    normals = frames[:, 2] / np.linalg.norm(frames[:, 2], axis=1)[:, None]
    np.testing.assert_allclose(np.abs(normals), np.tile([0.0, 0.0, 1.0], (len(normals), 1)),
                               atol=1e-12)
    np.testing.assert_allclose(normals[carried.rows == 2], [[0.0, 0.0, 1.0]], atol=1e-12)
    out = carried.apply(fib, v)
    assert out[0, 2, 2] < 0.001 - REST_MARGIN / 2 + 5e-6   # inside, below the top face
    assert out[0, 2, 2] > -0.001                           # not through the bottom one


def test_at_rest_apply_adds_the_stored_displacements_bit_for_bit(torus):
    """On the rest surface `apply` adds the displacements stored at rest; they are what
    rebuilding the frames there gives (a copy of the vertices takes the same path)."""
    v, f = torus
    fib = chords()
    carried = carry_rest_pull(fib, v, f)
    assert carried.rows.size
    frames, _ = _frames(v, carried.faces, carried.patches, carried.first)
    shift = np.einsum("mk,mkd->md", carried.coefficients, frames)
    np.testing.assert_array_equal(carried.rest[1], shift)
    want = fib.copy()
    want.reshape(-1, 3)[carried.rows] += shift
    np.testing.assert_array_equal(carried.apply(fib, v), want)
    np.testing.assert_array_equal(carried.apply(fib, v.copy()), want)
