"""`fibres.slicing.isolines`: the walk of many levels in one pass against one level at a time,
and the compiled isoline moments against the array code they replaced (an oracle here)."""
import numpy as np
from test_decompose_analytic import arc, tube

from fibres.slicing.harmonic_field import harmonic_field, mesh_edges
from fibres.slicing.isolines import isoline_loops, isoline_loops_at, isoline_moments

RHO, L = 0.01, 0.1


def _circle(th):
    return np.c_[RHO * np.cos(th), RHO * np.sin(th)]


def _bent_tube():
    v, f = tube(_circle, *arc(L, np.pi), n_sect=24, n_path=31)
    ring = np.arange(len(v)) // 24
    zero = (ring == 0) | (np.arange(len(v)) == len(v) - 2)
    one = (ring == 30) | (np.arange(len(v)) == len(v) - 1)
    return v, f, harmonic_field(v, f, zero, one)


def test_many_levels_in_one_pass_equal_one_level_at_a_time():
    """Enough levels that the walk's output outgrows its first allocation (E points), and a
    field with two loops on some levels (the bend's height)."""
    v, f, u = _bent_tube()
    edges, face_edges = mesh_edges(f, len(v))
    for field in (u, (v[:, 1] - v[:, 1].min()) / np.ptp(v[:, 1])):
        levels = np.linspace(0.01, 0.99, 200)
        every = isoline_loops_at(field, f, levels, edges, face_edges, v)
        assert sum(len(lp) for found in every for lp in found) > len(edges)
        for t, found in zip(levels, every):
            one = isoline_loops(field, f, t, edges, face_edges, v)
            assert len(found) == len(one) >= 1
            for a, b in zip(found, one):
                for name in ("a", "b", "s", "face"):
                    np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def _moments_oracle(u, vertices, faces, levels):
    """Length, centroid and vector area per level by array code (bincounts over the
    (face, level) crossings)."""
    uf = u[faces]
    lo = np.searchsorted(levels, uf.min(axis=1), side="right")
    hi = np.searchsorted(levels, uf.max(axis=1), side="right")
    count = hi - lo
    face = np.repeat(np.arange(len(faces)), count)
    lev = np.repeat(lo, count) + np.arange(face.size) - np.repeat(np.cumsum(count) - count, count)
    t = levels[lev]
    above = uf[face] >= t[:, None]
    ab0, ab1, ab2 = above.T

    def crossing(side):
        k1 = (side + 1) % 3
        u0, u1 = uf[face, side], uf[face, k1]
        s = ((t - u0) / (u1 - u0))[:, None]
        return (1 - s) * vertices[faces[face, side]] + s * vertices[faces[face, k1]]

    a = crossing((ab1 & ~ab2) + 2 * (ab2 & ~ab0))
    b = crossing((~ab1 & ab2) + 2 * (~ab2 & ab0))
    seg = np.linalg.norm(b - a, axis=1)
    n = len(levels)
    length = np.bincount(lev, seg, n)
    mid = 0.5 * (a + b) * seg[:, None]
    centre = np.stack([np.bincount(lev, mid[:, d], n) for d in range(3)], axis=1) / length[:, None]
    cr = 0.5 * np.cross(a, b)
    return length, centre, np.stack([np.bincount(lev, cr[:, d], n) for d in range(3)], axis=1)


def test_moments_equal_the_array_oracle():
    v, f, u = _bent_tube()
    levels = np.sort(np.random.default_rng(3).uniform(0.001, 0.999, 60))
    got = isoline_moments(u, v, f, levels)
    want = _moments_oracle(u, v, f, levels)
    for g, w in zip(got, want):
        np.testing.assert_allclose(g, w, rtol=1e-12, atol=1e-15)
    length, centre, area = isoline_moments(u, v, f, levels, area=False)
    assert area is None
    np.testing.assert_array_equal(length, got[0])


def test_moments_of_levels_beyond_the_field_and_on_vertex_values():
    """Levels below and above the field's range, repeated, and equal to vertex values (where
    a face's first level is decided by ``level <= lowest u``), against the array oracle."""
    v, f, u = _bent_tube()
    u = np.round(u * 40) / 40                       # many vertices exactly on levels
    rng = np.random.default_rng(5)
    levels = np.sort(np.concatenate([[-0.5, -0.1, 0.0, 0.5, 0.5, 1.0, 1.2],
                                     np.arange(41) / 40, rng.uniform(0.0, 1.0, 30)]))
    for lv in (levels, levels[:1], levels[-3:], np.array([0.25])):
        got = isoline_moments(u, v, f, lv)
        with np.errstate(invalid="ignore"):                 # levels with no isoline: NaN
            want = _moments_oracle(u, v, f, lv)
        for g, w in zip(got, want):
            np.testing.assert_allclose(g, w, rtol=1e-12, atol=1e-15)
