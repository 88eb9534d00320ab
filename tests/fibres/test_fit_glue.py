"""`fibres.fit.fitting.prepare`: the bounds and centroid that several stages share."""
import numpy as np

from fibres.fit import fitting


def test_prepare_bounds_with_zero_and_signed_zero_coordinates():
    # bounds and centroid by plain Python over the rows (independent of the transposed layout)
    v = np.array([[0.0, -0.0, 1.0], [-0.0, 0.0, 2.0], [1.0, 0.0, -0.0], [0.5, 0.5, 0.5]])
    got = fitting.prepare(v)
    cols = [[row[i] for row in v.tolist()] for i in range(3)]
    np.testing.assert_array_equal(got.lo, [min(c) for c in cols])
    np.testing.assert_array_equal(got.hi, [max(c) for c in cols])
    np.testing.assert_allclose(got.centroid, [sum(c) / 4 for c in cols], rtol=0, atol=1e-15)
    assert got.vt.shape == (3, 4) and got.vt.flags["C_CONTIGUOUS"]
