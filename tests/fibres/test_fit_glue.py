"""Compiled glue of the fresh decomposition (box fit, cross-section reference, template
fibres): the same numbers as the array versions, bit for bit."""
import importlib

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from fibres.fit import fitting

decompose_module = importlib.import_module("fibres.decompose")


def _shapes():
    rng = np.random.default_rng(2)
    for k in range(5):
        rot = Rotation.random(random_state=k).as_matrix()
        v = (rng.normal(size=(4000 + k, 3)) * [0.02, 0.035, 0.12]) @ rot.T + rng.normal(size=3)
        yield v, rot[:, 2]
    t = np.linspace(0, 2 * np.pi, 64, endpoint=False)       # circular cylinder: isotropic
    ring = np.c_[np.cos(t), np.sin(t)]
    v = np.concatenate([np.c_[0.02 * ring, np.full(64, z)] for z in np.linspace(0, 0.1, 9)])
    yield v, np.array([0.0, 0.0, 1.0])



def test_prepare_bounds_with_zero_and_signed_zero_coordinates(monkeypatch):
    pytest.importorskip("numba")
    v = np.array([[0.0, -0.0, 1.0], [-0.0, 0.0, 2.0], [1.0, 0.0, -0.0], [0.5, 0.5, 0.5]])
    got = fitting.prepare(v)
    np.testing.assert_array_equal(np.signbit(got.lo), np.signbit(v.min(axis=0)))
    np.testing.assert_array_equal(np.signbit(got.hi), np.signbit(v.max(axis=0)))
    np.testing.assert_array_equal(got.lo, v.min(axis=0))


