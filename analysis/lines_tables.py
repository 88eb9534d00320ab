"""Action-line results as long (tidy) tables, the columns of INTERFACE.md.

Arrays in (frame axis first), pandas DataFrames out, built with ``np.repeat``/``np.tile`` (no
loop over frames). Rows are ordered frame-major: every body/muscle of frame 0, then frame 1 ...
Used by ``fibres lines`` and ``fibres run``.
"""
from __future__ import annotations

import numpy as np

__all__ = ["body_poses_table", "action_lines_table", "moment_arms_table", "POSE_COLUMNS"]

#: rotation columns, row-major: r_ij = R[i, j], v_ground = R v_body + t
POSE_COLUMNS = ("tx", "ty", "tz") + tuple(f"r{i}{j}" for i in range(3) for j in range(3))


def _per_frame(frames, time, key, names) -> dict:
    """frame, time and ``key`` columns of an (F, len(names)) array flattened in C order."""
    n = len(names)
    return {"frame": np.repeat(frames, n), "time": np.repeat(time, n),
            key: np.tile(np.asarray(names, dtype=object), len(time))}


def _shaped(values, shape, what, dims, dtype=float):
    """``values`` as an array of ``shape``; a ValueError naming ``what`` and its ``dims`` if not."""
    a = np.asarray(values, dtype=dtype)
    if a.shape != shape:
        raise ValueError(f"{what} must be {dims} = {shape}, got {a.shape}")
    return a


def _framed(time, frames, values, axes, what, dims):
    """(time (F,), frames (F,), values) with ``values`` checked to be (F, *axes): each axis a
    length or a sequence of names whose count is the length."""
    time = np.asarray(time, dtype=float).reshape(-1)
    frames = np.arange(time.shape[0]) if frames is None else np.asarray(frames).reshape(-1)
    if frames.shape != time.shape:
        raise ValueError(f"frames {frames.shape} and time {time.shape} differ")
    shape = (time.shape[0],) + tuple(a if isinstance(a, int) else len(a) for a in axes)
    return time, frames, _shaped(values, shape, what, dims)


def _add_action_lines(table, action_lines, n_muscles, n_frames, muscle_of=slice(None)):
    """The ``action_line`` column (names of ``muscle_of``, repeated per frame), if given."""
    if action_lines is not None:
        if len(action_lines) != n_muscles:
            raise ValueError("action_lines must have one name per muscle")
        table["action_line"] = np.tile(np.asarray(action_lines, dtype=object)[muscle_of], n_frames)


def body_poses_table(time, tf_ground_body, body_names, *, frames=None):
    """Body frames in ground: columns frame, time, body, tx, ty, tz, r00 ... r22.

    Parameters
    ----------
    time : (F,) float
    tf_ground_body : (F, B, 4, 4) float
        ``v_ground = R v_body + t`` with ``R = tf[:3, :3]``, ``t = tf[:3, 3]``.
    body_names : (B,) str
    frames : (F,) int, keyword-only
        Frame numbers to write (default 0 .. F-1).

    Returns
    -------
    pandas.DataFrame
        F * B rows.
    """
    import pandas as pd

    time, frames, tf = _framed(time, frames, tf_ground_body, (body_names, 4, 4), "tf_ground_body",
                               "(F, B, 4, 4)")
    table = _per_frame(frames, time, "body", body_names)
    flat = tf.reshape(-1, 4, 4)
    for k, axis in enumerate("xyz"):
        table[f"t{axis}"] = flat[:, k, 3]
    for i in range(3):
        for j in range(3):
            table[f"r{i}{j}"] = flat[:, i, j]
    return pd.DataFrame(table)


def action_lines_table(time, lengths, muscle_names, *, frames=None, action_lines=None):
    """Path lengths: columns frame, time, muscle, [action_line,] length.

    Parameters
    ----------
    time : (F,) float
    lengths : (F, M) float
        Whole-path lengths in metres.
    muscle_names : (M,) str
    frames : (F,) int, keyword-only
    action_lines : (M,) str, keyword-only
        If given, an ``action_line`` column after ``muscle`` (``fibres run``: the OpenSim path
        behind each fibre-model muscle).

    Returns
    -------
    pandas.DataFrame
        F * M rows.
    """
    import pandas as pd

    time, frames, lengths = _framed(time, frames, lengths, (muscle_names,), "lengths", "(F, M)")
    table = _per_frame(frames, time, "muscle", muscle_names)
    _add_action_lines(table, action_lines, len(muscle_names), len(time))
    table["length"] = lengths.reshape(-1)
    return pd.DataFrame(table)


def moment_arms_table(time, moment_arms, spanned, muscle_names, coordinate_names, *,
                      frames=None, action_lines=None):
    """Moment arms for the coordinates each path spans: frame, time, muscle, [action_line,]
    coordinate, moment_arm.

    Parameters
    ----------
    time : (F,) float
    moment_arms : (F, M, C) float
        r = -dL/dq in metres (per radian for rotational coordinates).
    spanned : (M, C) bool
        Which (muscle, coordinate) pairs to write; others are left out.
    muscle_names : (M,) str
    coordinate_names : (C,) str
    frames : (F,) int, keyword-only
    action_lines : (M,) str, keyword-only
        As in `action_lines_table`.

    Returns
    -------
    pandas.DataFrame
        F * spanned.sum() rows; within a frame, muscles in order, then coordinates in order.
    """
    import pandas as pd

    time, frames, arms = _framed(time, frames, moment_arms, (muscle_names, coordinate_names),
                                 "moment_arms", "(F, M, C)")
    n_frames, n_muscles = time.shape[0], len(muscle_names)
    spanned = _shaped(spanned, arms.shape[1:], "spanned", "(M, C)", dtype=bool)
    muscle_of, coord_of = np.nonzero(spanned)  # row-major: muscle order, then coordinate order
    n_pairs = muscle_of.shape[0]
    table = {
        "frame": np.repeat(frames, n_pairs),
        "time": np.repeat(time, n_pairs),
        "muscle": np.tile(np.asarray(muscle_names, dtype=object)[muscle_of], n_frames),
    }
    _add_action_lines(table, action_lines, n_muscles, n_frames, muscle_of)
    table["coordinate"] = np.tile(np.asarray(coordinate_names, dtype=object)[coord_of], n_frames)
    table["moment_arm"] = arms[:, muscle_of, coord_of].reshape(-1)
    return pd.DataFrame(table)
