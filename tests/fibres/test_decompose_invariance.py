"""Invariances of the decomposition, for every template and both slicings.

The fibres are a geometric construction on the surface and its attachments, so they must
not depend on where the muscle stands or on how its mesh is numbered:

- a rigid motion of mesh and landmarks moves the fibres by the same motion;
- a uniform scale of mesh and landmarks scales the fibres, given the two absolute lengths
  (metres, anatomy-scale choices; docs/decisions.md) scaled alike or left out: the bound on
  the planar smoothing's shift (`fibres.finishing.smoothing.DECOMPOSE_MAX_SHIFT`, 1 mm) is
  scaled with the muscle, and the containment pull (its band and reach) is switched off;
- renumbering the vertices and reordering the faces (and the landmarks) gives the same fibres.

Shape: the bent tube of `test_decompose_analytic` (a curved muscle, the case where slicing
choices matter most). Tolerance: 1e-7 of the tube's length; the constructions are
sequences of linear solves and smooth maps of the coordinates, so a change of frame or of
numbering changes the results only by rounding (~1e-13 relative), and a discrete choice
flipped by a rounding tie would move fibres by a fraction of a fibre spacing (~1e-3 L).
"""
from __future__ import annotations

import importlib

import numpy as np
import pytest

from fibres import SLICINGS, TEMPLATES, decompose

from test_decompose_analytic import L, _bent, rotation

TOL = 1e-7 * L
CASES = [(t, s) for t in TEMPLATES for s in SLICINGS]
IDS = [f"{t}-{s}" for t, s in CASES]


@pytest.fixture(scope="module")
def bent():
    return _bent()


def _fibres(v, f, o, i, template, slicing, **kw):
    return decompose((v, f), o, i, template=template, slicing=slicing, n_fibres=24, resolution=10,
                     **kw).points


@pytest.mark.parametrize("template, slicing", CASES, ids=IDS)
def test_rigid_motion_moves_the_fibres_rigidly(bent, template, slicing):
    v, f, o, i = bent
    rot, t = rotation([0.3, -1.0, 0.5], 1.1), np.array([0.2, 0.05, -0.4])

    def move(x):
        return x @ rot.T + t

    ref = _fibres(v, f, o, i, template, slicing)
    moved = _fibres(move(v), f, move(o), move(i), template, slicing)
    assert np.abs(moved - move(ref)).max() <= TOL


@pytest.mark.parametrize("template, slicing", CASES, ids=IDS)
def test_uniform_scale_scales_the_fibres(bent, template, slicing, monkeypatch):
    """Scale covariance with the absolute lengths scaled too (module docstring): the
    smoothing bound is read by `fibres.decompose` at call time, so the scaled muscle gets
    ``s`` times it; the containment pull is off. Same tolerance as the other invariances:
    with the bound scaled, every step is a function of the coordinates that commutes with
    scaling, so only rounding differs."""
    v, f, o, i = bent
    s = 1.7
    ref = _fibres(v, f, o, i, template, slicing, contain=False)
    module = importlib.import_module("fibres.decompose")     # `fibres.decompose` is the function
    monkeypatch.setattr(module, "DECOMPOSE_MAX_SHIFT", s * module.DECOMPOSE_MAX_SHIFT)
    scaled = _fibres(s * v, f, s * o, s * i, template, slicing, contain=False)
    assert np.abs(scaled - s * ref).max() <= s * TOL


@pytest.mark.parametrize("template, slicing", CASES, ids=IDS)
def test_renumbered_mesh_gives_the_same_fibres(bent, template, slicing):
    """Four random renumberings: a rule on the vertex numbering (a sign fixed by
    ``sum_k k (V_k - c)``) flips with about half of all renumberings, so four of them miss
    such a rule with probability 1/16."""
    v, f, o, i = bent
    ref = _fibres(v, f, o, i, template, slicing)
    for seed in range(4):
        rng = np.random.default_rng(seed)
        perm = rng.permutation(len(v))            # new vertex k is old vertex perm[k]
        new_index = np.empty_like(perm)
        new_index[perm] = np.arange(len(v))
        faces = new_index[f][rng.permutation(len(f))]
        faces = np.roll(faces, 1, axis=1)         # same orientation, another first corner
        again = _fibres(v[perm], faces, o[::-1], i[::-1], template, slicing)
        assert np.abs(again - ref).max() <= TOL, seed


def test_shape_sign_reads_the_shape_not_the_frame_or_the_order():
    """`fibres.fit.box.shape_sign` on a half disk in the plane z = 0 (axis u = z), bulk
    towards +y: along e = y the skew points along e (+1), against -y (-1); along e = x the
    shape is mirror-symmetric about the plane x = 0 and the handedness decides (u x e = y:
    +1; e = -x: -1). A rotation of points and directions, a uniform scale or a permutation
    of the points leaves the answer; a full disk (symmetric) gives 0."""
    from fibres.fit.box import shape_sign

    r, th = np.meshgrid(np.linspace(0.1, 1.0, 7), np.linspace(0.0, np.pi, 13))
    half = np.c_[r.ravel() * np.cos(th.ravel()), r.ravel() * np.sin(th.ravel()),
                 np.zeros(r.size)]
    z = np.array([0.0, 0.0, 1.0])

    def sign(points, u, e):
        c = points.mean(axis=0)
        dt = (points - c).T
        axial = u @ dt
        return shape_sign(dt - np.outer(u, axial), axial, u, e)

    x, y = np.eye(3)[0], np.eye(3)[1]
    cases = [(y, 1), (-y, -1), (x, 1), (-x, -1)]
    assert [sign(half, z, e) for e, _ in cases] == [s for _, s in cases]
    rot = rotation([0.3, -1.0, 0.5], 1.1)
    perm = np.random.default_rng(1).permutation(len(half))
    for e, s in cases:
        assert sign(2.5 * half[perm] @ rot.T + [1.0, 2.0, 3.0], rot @ z, rot @ e) == s
    full = np.vstack([half, -half])
    assert sign(full, z, x) == 0 and sign(full, z, y) == 0
