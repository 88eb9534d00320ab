"""`fibres.mesh.closest_point`: the one point-triangle routine, against the np.select oracle of
tests/fibres/distance_oracle.py and against the property that defines it (no point of the
triangle is nearer)."""
import numpy as np
import pytest

from distance_oracle import closest_points
from fibres.mesh.closest_point import closest_points_on_triangles


def test_equals_the_oracle_on_every_region():
    rng = np.random.default_rng(7)
    tri = rng.normal(size=(20000, 3, 3))
    p = 2.0 * rng.normal(size=(20000, 3))        # far and near: every Voronoi region is hit
    got = closest_points_on_triangles(p, tri[:, 0], tri[:, 1], tri[:, 2])
    np.testing.assert_allclose(got, closest_points(tri, p), rtol=0, atol=1e-12)


def test_no_point_of_the_triangle_is_nearer_and_broadcasting():
    rng = np.random.default_rng(8)
    tri = rng.normal(size=(6, 3, 3))
    p = rng.normal(size=(300, 3))
    q = closest_points_on_triangles(p[:, None, :], tri[None, :, 0], tri[None, :, 1], tri[None, :, 2])
    assert q.shape == (300, 6, 3)
    w = rng.dirichlet(np.ones(3), size=2000)                  # points of each triangle
    inside = np.einsum("sk,tkd->tsd", w, tri)                 # (6, 2000, 3)
    best = np.linalg.norm(p[:, None, None, :] - inside[None], axis=-1).min(axis=2)
    assert (np.linalg.norm(q - p[:, None, :], axis=-1) <= best + 1e-12).all()


@pytest.mark.parametrize("tri", [
    [[0, 0, 0], [1, 0, 0], [1, 0, 0]],          # two corners equal: an edge
    [[0, 0, 0], [0, 0, 0], [0, 0, 0]],          # a point
    [[0, 0, 0], [1, 0, 0], [2, 0, 0]],          # collinear
])
def test_degenerate_triangles_give_a_point_of_the_segment(tri):
    tri = np.asarray(tri, dtype=float)
    p = np.random.default_rng(9).normal(size=(500, 3))
    q = closest_points_on_triangles(p, tri[0], tri[1], tri[2])
    assert np.isfinite(q).all()
    lo, hi = tri.min(axis=0), tri.max(axis=0)
    assert ((q >= lo - 1e-15) & (q <= hi + 1e-15)).all()
