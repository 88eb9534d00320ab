"""Plane sections of closed meshes: analytic shapes and invariants of the loops."""
import numpy as np
import pytest
import trimesh

from fibres.slicing.contours import choose_loops, clockwise_contour, loop_areas
from fibres.slicing.planes import (_cycles, _cycles_doubling, _first_at_or_above, mesh_topology,
                            slice_mesh)


def _polygon_area(p):
    return 0.5 * np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1])


def test_cycles_of_random_permutation():
    rng = np.random.default_rng(0)
    nxt = rng.permutation(3000)
    label, rank = _cycles(nxt)
    # follow the permutation explicitly from every cycle's label
    seen = np.zeros(3000, bool)
    for lab in np.unique(label):
        node, k = lab, 0
        while True:
            assert label[node] == lab and rank[node] == k
            seen[node] = True
            node, k = nxt[node], k + 1
            if node == lab:
                break
    assert seen.all()
    # the compiled walk and the pointer doubling agree exactly
    label2, rank2 = _cycles_doubling(nxt)
    assert np.array_equal(label, label2) and np.array_equal(rank, rank2)


def test_fast_plane_search_equals_searchsorted():
    rng = np.random.default_rng(1)
    h = np.linspace(-1, 1, 21)
    h[0], h[-1] = -0.999, 0.999          # inset ends as used by the morph
    x = np.concatenate([rng.uniform(-1.5, 1.5, 100000), h, np.nextafter(h, 5), np.nextafter(h, -5)])
    assert np.array_equal(_first_at_or_above(h, x), np.searchsorted(h, x, side="left"))


def test_sphere_sections_are_circles():
    m = trimesh.creation.icosphere(subdivisions=5)
    v = np.asarray(m.vertices)
    top = mesh_topology(m.faces, len(v))
    h = np.linspace(-0.95, 0.95, 20)
    sec = slice_mesh(v, top, np.eye(4), h)
    assert np.array_equal(sec.loop_slice, np.arange(20))          # one loop per plane
    areas = loop_areas(sec)
    for s in range(20):
        p = sec.loop_points(s)
        r = np.hypot(p[:, 0], p[:, 1])
        # an inscribed polyhedron: section radius <= true radius, and within the
        # icosphere's sagitta (edge ~0.04 -> depth < 1e-3 of the radius ... use 2e-3)
        true = np.sqrt(1 - h[s] ** 2)
        assert r.max() <= true + 1e-12 and r.min() >= true - 2e-3
        assert 0 < areas[s] <= np.pi * true**2            # counter-clockwise, inscribed
        # every point is on its mesh edge at the plane height
        e = top.edges[sec.edge[sec.loop_start[s]:sec.loop_start[s + 1]]]
        t = sec.t[sec.loop_start[s]:sec.loop_start[s + 1]]
        q = v[e[:, 0]] + t[:, None] * (v[e[:, 1]] - v[e[:, 0]])
        assert np.abs(q[:, :2] - p).max() <= 1e-15 and np.abs(q[:, 2] - h[s]).max() <= 1e-15
        assert t.min() >= 0 and t.max() <= 1


def test_torus_gives_two_loops_and_rigid_frame():
    m = trimesh.creation.torus(major_radius=1.0, minor_radius=0.3, major_sections=64,
                               minor_sections=32)
    v = np.asarray(m.vertices)
    top = mesh_topology(m.faces, len(v))
    # planes containing the torus axis (z): frame with third axis = world x
    rot = np.array([[0, 1, 0], [0, 0, 1], [1, 0, 0]], float).T   # columns: y, z, x
    tf = np.eye(4)
    tf[:3, :3] = rot
    tf[:3, 3] = [0.05, 0.0, 0.0]
    sec = slice_mesh(v, top, tf, np.array([-0.1, 0.0, 0.1]))
    assert np.array_equal(np.bincount(sec.loop_slice), [2, 2, 2])
    # two circles of radius <= 0.3 around u = +-1 (u = world y, v = world z)
    for loop in range(6):
        p = sec.loop_points(loop)
        c = p.mean(axis=0)
        assert abs(abs(c[0]) - np.sqrt(1 - 0.0)) < 0.06 and abs(c[1]) < 1e-2
    centres = np.array([[1.0, 0.0]] * 3)
    chosen, notes = choose_loops(sec, centres, n_slices=3)
    for s in range(3):
        assert sec.loop_points(chosen[s]).mean(axis=0)[0] > 0
    assert len(notes) == 3 and "2 loops" in notes[0]
    # mapping back to 3D lands on the plane x = 0.05 + h
    p3 = sec.to_world(sec.loop_points(0), sec.heights[0])
    assert np.abs(p3[:, 0] - (0.05 - 0.1)).max() <= 1e-15


def test_clockwise_orientation_and_open_mesh_refused():
    m = trimesh.creation.box(extents=(2.0, 1.0, 3.0))
    m = m.subdivide().subdivide()
    v = np.asarray(m.vertices)
    top = mesh_topology(m.faces, len(v))
    sec = slice_mesh(v, top, np.eye(4), np.array([-1.0, 0.3]))
    for loop in range(2):
        p, e = clockwise_contour(sec, loop)
        assert _polygon_area(p) == pytest.approx(-2.0, rel=1e-12)  # exact rectangle, cw
        assert len(e) == len(p)
    with pytest.raises(ValueError, match="not closed"):
        mesh_topology(m.faces[:-1], len(v))


def test_crossings_are_every_face_plane_crossing_once():
    # independent count: face f crosses plane s iff min d <= h_s < max d over its corners (a
    # brute-force double loop); each node's "down" edge runs from a corner at or above h_s to
    # one below it, and following ``nxt`` stays on the node's plane; including planes exactly
    # through vertices and a plane missing the mesh
    from fibres.slicing.planes import _crossings, mesh_topology

    m = trimesh.creation.icosphere(subdivisions=3)
    v = np.asarray(m.vertices) * [1.0, 0.7, 2.0]
    topo = mesh_topology(np.asarray(m.faces), len(v))
    d = v @ np.array([0.1, 0.2, 0.97])
    rng = np.random.default_rng(2)
    for h in (np.linspace(d.min() + 1e-6, d.max() - 1e-6, 20),
              np.sort(rng.uniform(d.min(), d.max(), 17)),
              np.unique(d[[5, 90, 40]]),                   # through vertices
              np.array([d.max() + 1.0])):                  # misses the mesh
        node_face, node_slice, down, nxt = _crossings(d, topo.faces, topo.neighbours, h)
        expected = {(f, s) for f, tri in enumerate(topo.faces) for s, hs in enumerate(h)
                    if d[tri].min() <= hs < d[tri].max()}
        got = set(zip(node_face.tolist(), node_slice.tolist()))
        assert got == expected and len(got) == node_face.size
        tri = topo.faces[node_face]
        a = tri[np.arange(tri.shape[0]), down]
        b = tri[np.arange(tri.shape[0]), (down + 1) % 3]
        assert np.all(d[a] > h[node_slice]) and np.all(d[b] <= h[node_slice])
        assert np.array_equal(node_slice[nxt], node_slice)
        assert np.array_equal(np.sort(nxt), np.arange(nxt.size))      # a permutation: closed loops



def _circle(c, r, n, phase=0.0):
    t = phase - np.linspace(0, 2 * np.pi, n, endpoint=False)          # clockwise
    return np.c_[c[0] + r * np.cos(t), c[1] + r * np.sin(t)]


def _no_material(n):
    return np.zeros((n, 4), np.int64), np.zeros((n, 4))


def test_bridge_loops_is_continuous_through_a_pinch_and_an_island():
    from fibres.slicing.contours import bridge_loops

    a = _circle((0.0, 0.0), 1.0, 40)
    # two circles 2e-9 apart (just split): the bridge is the pinch point, 2e-9 long
    b = _circle((2.0 + 2e-9, 0.0), 1.0, 40, phase=np.pi)
    pts, (av, aw), gap = bridge_loops(a, _no_material(40), b, _no_material(40))
    assert pts.shape == (84, 2) and av.shape == (84, 4) and aw.shape == (84, 4)
    assert abs(gap - 2e-9) <= 1e-12
    # the contour runs round a, crosses at (1, 0) and runs round b: its length is the two
    # perimeters (polygons of 40 sides) plus twice the gap
    per = 40 * 2 * np.sin(np.pi / 40)
    length = np.hypot(*(np.roll(pts, -1, axis=0) - pts).T).sum()
    assert abs(length - 2 * per) <= 1e-8
    np.testing.assert_allclose(pts[0], [1.0, 0.0], atol=1e-8)
    # an island of (almost) no area (3e-12) 3 units away: shrunk onto the other loop with
    # its bridge, so it adds (almost) nothing to the contour (scale ~ area / gap^2 ~ 3e-13,
    # times the ~6-unit bridge and island), and the big loop stays itself (its scale is
    # 1 - O(area_island / area_a))
    island = _circle((4.0, 0.0), 1e-6, 12)
    pts, _, gap = bridge_loops(a, _no_material(40), island, _no_material(12))
    assert abs(gap - 3.0) <= 1e-5
    extra = np.hypot(*(np.roll(pts, -1, axis=0) - pts).T).sum() - per
    assert abs(extra) <= 1e-10
    # and the same with the island first (the anchored loop about to vanish)
    pts, _, gap = bridge_loops(island, _no_material(12), a, _no_material(40))
    extra = np.hypot(*(np.roll(pts, -1, axis=0) - pts).T).sum() - per
    assert abs(extra) <= 1e-10
    # the bridge ends are continuous in the loops: moving b by 1e-7 moves them by ~1e-7
    b2 = b + [1e-7, 1e-7]
    p1 = bridge_loops(a, _no_material(40), b, _no_material(40))[0]
    p2 = bridge_loops(a, _no_material(40), b2, _no_material(40))[0]
    assert np.abs(p1 - p2).max() <= 1e-5



