"""`fibres.slicing.mesh_topology` against independent properties (closedness, orientation,
connected pieces by scipy), on meshes that stress its edge pairing: shuffled faces and vertex numbers (unsorted buckets, large valences), edges used
once or three or four times, degenerate faces, inconsistent winding, several pieces."""
import numpy as np
import pytest
import trimesh

from fibres.slicing import mesh_topology


def _meshes():
    rng = np.random.default_rng(11)
    m = trimesh.creation.icosphere(subdivisions=3)
    f0 = np.asarray(m.faces)
    nv = len(m.vertices)
    out = {"sphere": (f0, nv)}
    perm = rng.permutation(nv)                                # vertex numbers shuffled
    out["shuffled"] = (perm[f0][rng.permutation(len(f0))], nv)
    cone = trimesh.creation.cone(radius=1.0, height=1.0, sections=200)   # valence 200
    out["fan"] = (np.asarray(cone.faces), len(cone.vertices))
    flipped = f0.copy()
    flipped[::7] = flipped[::7, ::-1]
    out["flipped"] = (flipped, nv)
    out["two pieces"] = (np.vstack([f0, f0 + nv])[rng.permutation(2 * len(f0))], 2 * nv)
    out["open"] = (f0[:-1], nv)                                # edges used once
    out["tripled"] = (np.vstack([f0, f0[:1]]), nv)             # edges used three times
    out["doubled"] = (np.vstack([f0, f0[:1], f0[:1, ::-1]]), nv)   # four times
    bowtie = np.vstack([f0, f0 + nv])
    bowtie = np.where(bowtie == nv + f0[0, 0], f0[0, 0], bowtie)   # pieces share a vertex
    out["one shared vertex"] = (bowtie, 2 * nv)
    out["unused vertex"] = (f0, nv + 1)
    return out


@pytest.mark.parametrize("case", list(_meshes()))
def test_topology_of_closed_and_open_meshes(case):
    faces, nv = _meshes()[case]
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    try:
        top = mesh_topology(faces, nv)
    except ValueError:
        top = None
    assert (top is None) == (case in ("open", "tripled", "doubled"))
    if top is None:
        return
    assert top.oriented == (case != "flipped")
    # every face has three neighbours across its three edges, and neighbourhood is symmetric
    nb = np.asarray(top.neighbours)
    assert nb.shape == (len(faces), 3) and (nb >= 0).all()
    assert all(i in nb[j] for i in range(0, len(faces), 37) for j in nb[i])


@pytest.mark.parametrize("m", [4, 6, 8])
def test_sorting_networks_sort(m):
    # 0-1 principle (Knuth §5.3.4): a comparator network sorts every input iff it sorts
    # every 0/1 input; and the compiled networks sort random distinct int64 keys in place
    pytest.importorskip("numba")
    import itertools

    import numba

    from fibres.sort_networks import NETWORKS, _sort_small

    for bits in itertools.product((0, 1), repeat=m):
        a = list(bits)
        for i, j in NETWORKS[m]:
            a[i], a[j] = min(a[i], a[j]), max(a[i], a[j])
        assert a == sorted(bits)
    run = numba.njit(_sort_small)
    rng = np.random.default_rng(m)
    for _ in range(200):
        key = rng.choice(1 << 40, size=m + 5, replace=False).astype(np.int64)
        want = key.copy()
        want[2:2 + m] = np.sort(want[2:2 + m])
        assert run(key, 2, m)
        np.testing.assert_array_equal(key, want)
    assert not run(np.zeros(10, np.int64), 0, m + 1)
