"""The seam chain of `fibres.slicing.harmonic_sections._registered_seam` (its registration on
a renumbered loop: tests/fibres/test_harmonic.py)."""
import numpy as np

from fibres.slicing.harmonic_sections import SAMPLES, _registered_seam


def test_samples_are_at_equal_arc_lengths_from_the_seam():
    """On a regular polygon the k-th sample lies k / SAMPLES of the way round from the seam."""
    m = 100
    th = np.arange(m) / m * 2 * np.pi
    p = np.c_[np.cos(th), np.sin(th), np.zeros(m)]
    seg = np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1)
    pos = _registered_seam(p, seg, [0], [m], 0, 12.25)[0]
    np.testing.assert_allclose((pos - 12.25) % m, np.arange(SAMPLES) * m / SAMPLES, atol=1e-9)
