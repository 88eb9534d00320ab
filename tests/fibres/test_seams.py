"""The compiled seam chain (`fibres.slicing.harmonic_sections._registered_seam`) against the
numpy oracle (tests/fibres/seam_oracle.py: FFT cross-correlations, np.interp)."""
import numpy as np
from seam_oracle import seam_chain

from fibres.slicing.harmonic_sections import SAMPLES, _registered_seam


def _wobbly_loops(rng, n_loops):
    """Closed loops round the z axis, each a wobbly ellipse numbered from its own start, with
    uneven point spacing and its own point count."""
    loops = []
    for j in range(n_loops):
        m = int(rng.integers(40, 220))
        th = np.sort(rng.uniform(0.0, 2 * np.pi, m))
        r = 1.0 + 0.2 * np.sin(3 * th + j) + 0.05 * rng.standard_normal(m)
        p = np.c_[(2.0 + 0.1 * j) * r * np.cos(th), r * np.sin(th), 0.3 * j + 0.02 * np.cos(th)]
        loops.append(np.roll(p, int(rng.integers(m)), axis=0))
    return loops


def test_compiled_seam_chain_matches_the_numpy_oracle():
    rng = np.random.default_rng(7)
    for n_loops, mid in ((9, 4), (2, 0), (5, 4), (1, 0)):
        pts = _wobbly_loops(rng, n_loops)
        segs = [np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1) for p in pts]
        seam = float(rng.integers(len(pts[mid])))
        size = np.array([len(p) for p in pts])
        got = _registered_seam(np.concatenate(pts), np.concatenate(segs), np.cumsum(size) - size,
                               size, mid, seam)
        want = seam_chain(pts, mid, seam)
        assert got.shape == (n_loops, SAMPLES)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)


def test_samples_are_at_equal_arc_lengths_from_the_seam():
    """On a regular polygon the k-th sample lies k / SAMPLES of the way round from the seam."""
    m = 100
    th = np.arange(m) / m * 2 * np.pi
    p = np.c_[np.cos(th), np.sin(th), np.zeros(m)]
    seg = np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1)
    pos = _registered_seam(p, seg, [0], [m], 0, 12.25)[0]
    np.testing.assert_allclose((pos - 12.25) % m, np.arange(SAMPLES) * m / SAMPLES, atol=1e-9)
