"""`fibres.slicing.planes.mesh_topology` against independent properties (closedness, orientation,
connected pieces by scipy), on meshes that stress its edge pairing: shuffled faces and vertex numbers (unsorted buckets, large valences), edges used
once or three or four times, degenerate faces, inconsistent winding, several pieces."""
import numpy as np
import pytest
import trimesh

from fibres.slicing.planes import mesh_topology


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


