"""Fibre moment arms of `analysis.run`: central differences of the whole chain.

Per-fibre moment arms r = -dL/dq about every coordinate the muscle's action lines span, by
central differences of the WHOLE chain (wrap + decompose with the frozen plan + length):
``r = -(L(q + h e_c) - L(q - h e_c)) / (2 h)``. All perturbed poses are extra frames of ONE
batch (the motion is stacked ``[q; q + h e_1; q - h e_1; ...]``, chunk by chunk of frames), so
the wrapping of all poses of a chunk is one call.

The step h (``FD_STEP``: 1e-4 rad for rotational, 1e-5 m for translational coordinates). The
central difference has truncation error h^2/6 * L''' and round-off error ~ eps * L / h. For a
muscle path L''' is of the order of L (a rotation by q changes a point's position with
derivatives of order its lever arm ~ L), so with L ~ 0.1 m the truncation error is ~1e-10 m,
four orders below the 1e-6 m resolution that matters for a moment arm of ~1e-2 m; the round-off
error of double precision is ~1e-16 * 0.1 / 1e-4 ~ 1e-13 m, and even if the chain's own
numerical noise were 1e-9 relative (iterative steps in wrapping), it contributes ~1e-6 m. The
step is also far below the 1-2 degree scale on which wrapping contact or the path geometry
change, so the quotient is a derivative, not a secant (checked by the smoothness test against a
2-degree difference quotient). Where the +h or -h pose switches a ConditionalPathPoint of the
muscle's action lines on or off (a step in the path, as in OpenSim), the quotient is one-sided on
the side that keeps the frame's own path (error ~ h/2 * L'' instead of a spike of the step / 2h).
"""
from __future__ import annotations

import numpy as np

from motion.osim.kinematics import clipped_coordinates

__all__ = ["FD_STEP", "stacked_motion", "active_set_changes", "range_limits", "clamped", "difference_quotients"]

#: central-difference step per motion type (SI): see the module docstring.
FD_STEP = {"rotational": 1e-4, "translational": 1e-5, "coupled": 1e-4}


def stacked_motion(model, q, source, coord_idx, step):
    """The base motion ``q`` (F, C) followed by +h and -h perturbations of each coordinate of
    ``coord_idx`` (K,): a `motion.Motion` of F (1 + 2K) frames, the steps (K,) and F. ``step``
    maps a motion type to its h (`FD_STEP`). Clamped coordinates are clamped first (module
    docstring)."""
    import motion as motion_pkg

    q = clamped(model, q)
    n_f = len(q)
    coords = model.coordinates
    steps = np.array([step[coords[c].motion_type] for c in coord_idx], dtype=float)
    blocks = [q]
    for k, c in enumerate(coord_idx):
        for sign in (1.0, -1.0):
            qp = q.copy()
            qp[:, c] += sign * steps[k]
            blocks.append(qp)
    q_all = np.concatenate(blocks, axis=0)
    t_all = np.arange(len(q_all), dtype=float)   # a placeholder clock: poses do not depend on time
    stacked = motion_pkg.Motion.from_array(model, t_all, q_all, source=source)
    return stacked, steps, n_f


def clamped(model, q):
    """``q`` (F, C) with clamped coordinates clipped to their range where posing clips them
    (`motion.osim.kinematics.clipped_coordinates`, the rule posing follows)."""
    q = np.array(q, dtype=float)
    for i, lo, hi in clipped_coordinates(model):
        q[:, i] = np.clip(q[:, i], lo, hi)
    return q


def range_limits(model, q_stacked, n_f, coord_idx):
    """(K, F) bool masks: the +h (-h) pose of coordinate k leaves the range of a clamped
    coordinate (it would be clamped back: the quotient must not use it)."""
    q = np.asarray(q_stacked, dtype=float)
    n_k = len(coord_idx)
    blocks = q.reshape(1 + 2 * n_k, n_f, -1)
    plus = np.zeros((n_k, n_f), dtype=bool)
    minus = np.zeros((n_k, n_f), dtype=bool)
    limits = {i: (lo, hi) for i, lo, hi in clipped_coordinates(model)}
    for k, c in enumerate(coord_idx):
        if c in limits:
            lo, hi = limits[c]
            plus[k] = (blocks[1 + 2 * k, :, c] > hi) | (blocks[1 + 2 * k, :, c] < lo)
            minus[k] = (blocks[2 + 2 * k, :, c] > hi) | (blocks[2 + 2 * k, :, c] < lo)
    return plus, minus


def active_set_changes(model, mspec, q_stacked, n_f):
    """(K, F) bool masks: the +h (-h) pose switches a ConditionalPathPoint of the muscle's action
    lines on or off relative to the frame's own pose (OpenSim's rule: active when
    ``range_min - 1e-5 <= q <= range_max + 1e-5``)."""
    q = np.asarray(q_stacked, dtype=float)
    n_k = q.shape[0] // n_f // 2
    blocks = q.reshape(1 + 2 * n_k, n_f, -1)
    plus = np.zeros((n_k, n_f), dtype=bool)
    minus = np.zeros((n_k, n_f), dtype=bool)
    for name in mspec.action_lines:
        for pt in model.path(name).points:
            if pt.kind != "conditional" or pt.coordinate not in model.coordinate_names:
                continue
            c = model.coordinate_index(pt.coordinate)
            lo, hi = pt.range[0] - 1e-5, pt.range[1] + 1e-5
            active = (blocks[..., c] >= lo) & (blocks[..., c] <= hi)      # (1 + 2K, F)
            plus |= active[1::2] != active[0]
            minus |= active[2::2] != active[0]
    return plus, minus


def difference_quotients(base, plus, minus, steps, plus_switch, minus_switch):
    """r = -dL/dq per fibre: central differences, one-sided where the +h or -h pose switches a
    conditional path point (a step in the path, as in OpenSim, that a central difference would
    turn into a spike; the exact action-line derivative is likewise one-sided there).

    base (F, N), plus/minus (K, F, N), steps (K,), switches (K, F) -> (F, N, K)."""
    h = steps[:, None, None]
    central = -(plus - minus) / (2.0 * h)
    forward = -(plus - base[None]) / h
    backward = -(base[None] - minus) / h
    r = np.where(plus_switch[..., None] & ~minus_switch[..., None], backward, central)
    r = np.where(minus_switch[..., None] & ~plus_switch[..., None], forward, r)
    return np.moveaxis(r, 0, -1)
