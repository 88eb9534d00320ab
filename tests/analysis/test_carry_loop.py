"""`analysis.fibre_transport._ends_ride_their_bodies` (the compiled `_carry_loop`) against a numpy
oracle of the same formula (module docstring of `analysis.fibre_transport`), written out here."""
import numpy as np
import pytest

from analysis.fibre_transport import _ends_ride_their_bodies, fibre_lengths


def _oracle(carried, rest, origin_ends, insertion_ends, frames=None):
    """Frame-major numpy: carried (F, N, Q, 3), frames (F, N, Q, 3, 3) -> corrected (F, N, Q, 3)."""
    seg = np.linalg.norm(np.diff(rest, axis=1), axis=-1)
    u = np.concatenate([np.zeros((rest.shape[0], 1)), np.cumsum(seg, axis=1)], axis=1)
    u = u / u[:, -1:]
    e0 = origin_ends - carried[:, :, 0]
    e1 = insertion_ends - carried[:, :, -1]
    if frames is None:
        return carried + e0[:, :, None] + u[None, :, :, None] * (e1 - e0)[:, :, None]
    local0 = np.einsum("fnji,fnj->fni", frames[:, :, 0], e0)
    local1 = np.einsum("fnji,fnj->fni", frames[:, :, -1], e1)
    mix = local0[:, :, None] + u[None, :, :, None] * (local1 - local0)[:, :, None]
    out = carried + np.einsum("fnpij,fnpj->fnpi", frames, mix)
    out[:, :, 0], out[:, :, -1] = origin_ends, insertion_ends
    return out


def _rotations(rng, shape):
    q, _ = np.linalg.qr(rng.normal(size=shape + (3, 3)))
    return q


@pytest.mark.parametrize("with_frames", [False, True])
def test_compiled_pass_equals_the_numpy_formula(with_frames):
    rng = np.random.default_rng(7)
    n_f, n_n, n_q, keep, every = 9, 5, 7, 4, 2
    rest = np.cumsum(rng.random((n_n, n_q, 3)), axis=1)
    carried = rest[None] + 0.05 * rng.normal(size=(n_f, n_n, n_q, 3))
    o_ends = carried[:, :, 0] + 0.01 * rng.normal(size=(n_f, n_n, 3))
    i_ends = carried[:, :, -1] + 0.01 * rng.normal(size=(n_f, n_n, 3))
    frames = _rotations(rng, (n_f, n_n, n_q)) if with_frames else None
    want = _oracle(carried, rest, o_ends, i_ends, frames)
    # the compiled pass takes rider-major arrays: (N, Q, F, 3) and (N, Q, F, 3, 3)
    lengths, points = _ends_ride_their_bodies(
        np.ascontiguousarray(carried.transpose(1, 2, 0, 3)), rest, o_ends, i_ends,
        None if frames is None else np.ascontiguousarray(frames.transpose(1, 2, 0, 3, 4)), keep=keep, every=every)
    # sums of the same products in another order: a few ulps
    np.testing.assert_allclose(lengths, fibre_lengths(want), rtol=1e-13, atol=0)
    np.testing.assert_allclose(points, want[:keep, :, ::every], rtol=0, atol=1e-13)
    assert points.shape == (keep, n_n, (n_q - 1) // every + 1, 3)
    np.testing.assert_array_equal(points[:, :, 0], o_ends[:keep])       # the ends exactly
