"""Numpy oracle of the seams of `fibres.slicing.harmonic_sections` (tests only): the loops'
seams carried loop by loop (`seam_chain`, the order of `_slices`), each registered by an FFT
circular cross-correlation (`registered_seam`), against which the compiled chain
(`_seam_chain`: direct sums) is compared."""
import numpy as np

from fibres.slicing.harmonic_sections import _FINE, SAMPLES


def _position_point(points, pos):
    m = len(points)
    i = int(np.floor(pos)) % m
    f = pos - np.floor(pos)
    return (1.0 - f) * points[i] + f * points[(i + 1) % m]


def _closest_position(points, q) -> float:
    """Fractional loop position (node + fraction) of the closed polyline's point nearest q."""
    a = points
    b = np.roll(points, -1, axis=0)
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", q - a, ab) / np.maximum(
        np.einsum("ij,ij->i", ab, ab), 1e-300), 0.0, 1.0)
    d = np.linalg.norm(a + t[:, None] * ab - q, axis=1)
    k = int(np.argmin(d))
    return k + float(t[k])


def _arc_positions(seg, start, k):
    """(k,) fractional loop positions (node + fraction) that divide the closed loop with
    segment lengths ``seg`` into k equal arcs from the position ``start``."""
    m = len(seg)
    i0 = int(np.floor(start)) % m
    f0 = start - np.floor(start)
    # segment lengths in loop order from the start, the first one split there
    seg = np.concatenate([seg[i0:], seg[:i0]])
    head = seg[0] * (1.0 - f0)
    cum = np.empty(m + 2)
    cum[0], cum[1] = 0.0, head
    np.cumsum(seg[1:], out=cum[2:m + 1])
    cum[2:m + 1] += head
    cum[m + 1] = cum[m] + seg[0] * f0                            # back at the start
    pos = np.arange(-1.0, m + 1.0) + (i0 + 1.0)
    pos[0], pos[-1] = start, start + m
    cum += 1e-15 * cum[-1] * np.arange(cum.size)                 # strictly increasing
    target = np.arange(k) / k * cum[-1]
    return np.interp(target, cum, pos) % m


def _loop_samples(p, seam, k, seg=None):
    """(k,) positions and (k, 3) points of the closed polyline ``p`` at k equal arcs from
    ``seam``; ``seg``: its segment lengths (`_loop_frame`), when at hand."""
    if seg is None:
        seg = np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1)
    pos = _arc_positions(seg, seam, k)
    i0 = np.floor(pos).astype(np.int64) % len(p)
    f = (pos - np.floor(pos))[:, None]
    return pos, (1.0 - f) * p[i0] + f * p[(i0 + 1) % len(p)]


def registered_seam(prev_pts, prev_seam, pts, guess, prev_seg=None, seg=None, ref=None):
    """The seam (fractional position) of loop ``pts`` whose `SAMPLES` arc-length samples lie
    nearest the previous loop's, in the least-squares sense with both sample sets centred
    (the loops move along the muscle; only the cyclic shift is sought): the shifts searched
    are `_FINE` per sample spacing, all round the loop, starting from ``guess``.

    Shift ``t = q F + r`` (F = `_FINE`) takes every F-th fine sample from r, rolled by q:
    its centred sum of squares depends on r only, and the cross term with the reference is
    a circular cross-correlation over q, computed for all q at once by FFT. ``prev_seg``,
    ``seg``: the loops' segment lengths, and ``ref``: the previous loop's samples
    (`_loop_samples` at ``prev_seam``), when at hand."""
    k = SAMPLES
    if ref is None:
        _, ref = _loop_samples(prev_pts, prev_seam, k, prev_seg)
    pos, fine = _loop_samples(pts, guess, k * _FINE, seg)
    ref = ref - ref.mean(axis=0)
    sub = fine.reshape(k, _FINE, 3).transpose(1, 0, 2)                # (F, K, 3): [r, k]
    sub = sub - sub.mean(axis=1, keepdims=True)
    power = np.einsum("rkd,rkd->r", sub, sub)
    # corr[r, q] = sum_k sub[r, (k + q) mod K] . ref[k]
    corr = np.fft.irfft(np.fft.rfft(sub, axis=1) * np.conj(np.fft.rfft(ref, axis=0))[None],
                        n=k, axis=1).sum(axis=2)
    cost = power[:, None] - 2.0 * corr                                # (F, K)
    r, q = np.unravel_index(int(np.argmin(cost)), cost.shape)
    return float(pos[(q * _FINE + r) % len(pos)])


def seam_chain(pts, mid, mid_seam):
    """(L, SAMPLES) sample positions of the loops ``pts`` from their seams, carried from loop
    ``mid`` (seam ``mid_seam``) outwards: the guess is the nearest point to the previous
    seam's point, then `registered_seam`."""
    segs = [np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1) for p in pts]
    seams = [0.0] * len(pts)
    seams[mid] = float(mid_seam)
    samples = [None] * len(pts)
    samples[mid] = _loop_samples(pts[mid], seams[mid], SAMPLES, segs[mid])
    for rng in (range(mid + 1, len(pts)), range(mid - 1, -1, -1)):
        prev = mid
        for j in rng:
            q = _position_point(pts[prev], seams[prev])
            seams[j] = _closest_position(pts[j], q)
            seams[j] = registered_seam(pts[prev], seams[prev], pts[j], seams[j],
                                       segs[prev], segs[j], ref=samples[prev][1])
            samples[j] = _loop_samples(pts[j], seams[j], SAMPLES, segs[j])
            prev = j
    return np.stack([smp[0] for smp in samples])
