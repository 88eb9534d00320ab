"""`fibres.attachments.patch._pieces` (holes filled, small pieces dropped) against a fresh
component search of the filled patch (the oracle below)."""
import numpy as np
import trimesh

from fibres.attachments.patch import MIN_PIECE, _components, _pieces, edge_graph
from fibres.slicing.harmonic_field import mesh_edges


def _oracle(patch, graph, rows, vertex_area):
    """The rule of `_pieces` (holes under half the patch's area filled, never the largest
    region of the rest; then pieces under `MIN_PIECE` of the patch's area dropped) with a
    fresh search of the whole surface after filling."""
    def search(mask):
        n, label, _ = _components(mask, graph, rows)
        return label, np.bincount(label, vertex_area, n)

    label, area = search(patch)
    rest = np.unique(label[~patch])
    largest = rest[np.argmax(area[rest])]
    holes = [c for c in rest if c != largest and area[c] < 0.5 * vertex_area[patch].sum()]
    if holes:
        patch = patch | np.isin(label, holes)
        label, area = search(patch)
    pieces = np.unique(label[patch])
    small = [c for c in pieces if area[c] < MIN_PIECE * area[pieces].sum()]
    return patch & ~np.isin(label, small) if len(pieces) > 1 else patch


def test_filled_holes_and_pieces_match_a_fresh_search():
    sphere = trimesh.creation.icosphere(subdivisions=4)
    v, f = np.asarray(sphere.vertices), np.asarray(sphere.faces, dtype=np.int64)
    edges = mesh_edges(f, len(v))
    edges = edges[0] if isinstance(edges, tuple) else edges
    graph, rows, _ = edge_graph(v, edges)
    vertex_area = np.bincount(f.reshape(-1), np.repeat(sphere.area_faces / 3.0, 3), len(v))
    rng = np.random.default_rng(3)
    filled = 0
    for _ in range(40):
        # a cap with random holes (small caps removed) and random stray specks
        axis = rng.standard_normal(3)
        axis /= np.linalg.norm(axis)
        patch = v @ axis > rng.uniform(-0.2, 0.6)
        for _ in range(rng.integers(0, 4)):
            c = rng.standard_normal(3)
            c /= np.linalg.norm(c)
            patch &= np.linalg.norm(v - c, axis=1) > rng.uniform(0.05, 0.3)
        for _ in range(rng.integers(0, 3)):
            c = rng.standard_normal(3)
            c /= np.linalg.norm(c)
            patch |= np.linalg.norm(v - c, axis=1) < rng.uniform(0.05, 0.2)
        n, label, _ = _components(patch, graph, rows)
        filled += int(len(np.unique(label[~patch])) > 1)
        got = _pieces(patch, graph, rows, vertex_area, "origin", [])
        assert np.array_equal(got, _oracle(patch, graph, rows, vertex_area))
    assert filled >= 10                 # the hole-filling branch was exercised
