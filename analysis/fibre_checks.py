"""Normalized fibre lengths and the moment-arm consistency warning of `analysis.run`.

Normalized length l / l_opt (``normalized_length`` in ``fibre_lengths.csv`` and ``summary.csv``),
so fibre lengths can feed a force-length curve:

- l_opt of a muscle is its OpenSim muscle's ``optimal_fiber_length`` (the mean over its action
  lines that have one; `motion.osim.muscle_parameters`); NaN when none has (a PathActuator).
- Generated surface (no mesh; its belly spans the fibre part of the path, L - tendon slack
  length): every fibre's l_opt is the muscle's, so l / l_opt is the Hill model's normalized
  fibre length (rigid tendon).
- User mesh: fibre k's optimal length is the muscle's l_opt scaled by its rest length over the
  median rest length, ``l_opt,k = l_opt * l_rest,k / median(l_rest)``: fibres of different
  lengths in one muscle have the same number of sarcomeres per length, and at the rest pose
  (the pose the mesh was acquired in) every fibre has the same normalized length,
  ``median(l_rest) / l_opt``. A mesh whose fibres include tendon shows values above 1 there.
- Action lines: ``(L_path - tendon_slack_length) / optimal_fiber_length`` of each line's
  muscle (the rigid-tendon normalized fibre length; pennation not applied).

The warning: for every coordinate, in the frames where an action line's moment arm exceeds
5 mm, the median fibre moment arm should lie in the action lines' range [min, max] widened by
``max(MARGIN_RELATIVE * max |r_line|, MARGIN_ABSOLUTE)``. Where it does not, the muscle gets a
note (run.json) starting with ``warning:`` and `analysis.run` issues a `FibreWarning`
(``fibres run`` prints it on stderr): a user never meets a silent discrepancy between fibres
and lines (a mesh registered to the wrong pose, attachments on the wrong body, a wrap object
the surface does not follow).
"""
from __future__ import annotations

import numpy as np

__all__ = ["optimal_lengths", "line_normalized_lengths", "short_path_notes", "moment_arm_notes",
           "MARGIN_RELATIVE", "MARGIN_ABSOLUTE", "MIN_LINE_ARM"]

#: the warning's margin around the action lines' moment-arm range: relative part, absolute (m)
MARGIN_RELATIVE = 0.2
MARGIN_ABSOLUTE = 5e-3
#: frames where no action line's |moment arm| exceeds this (m) are not checked
MIN_LINE_ARM = 5e-3


def _parameters(model, names):
    from motion.osim.muscle_parameters import muscle_parameters

    return [muscle_parameters(model, n) for n in names]


def optimal_lengths(model, action_lines, rest_lengths, *, generated: bool) -> np.ndarray:
    """(N,) per-fibre optimal lengths (module docstring), NaN when the model has none."""
    rest = np.asarray(rest_lengths, dtype=float)
    values = [p.optimal_fiber_length for p in _parameters(model, action_lines)
              if p.optimal_fiber_length and p.optimal_fiber_length > 0]
    if not values:
        return np.full(rest.shape, np.nan)
    l_opt = float(np.mean(values))
    if generated:
        return np.full(rest.shape, l_opt)
    return l_opt * rest / max(float(np.median(rest)), 1e-300)


def line_normalized_lengths(model, action_lines, line_lengths) -> np.ndarray:
    """(F, L) ``(L_path - tendon_slack_length) / optimal_fiber_length`` per action line."""
    lengths = np.asarray(line_lengths, dtype=float)
    out = np.full(lengths.shape, np.nan)
    for k, p in enumerate(_parameters(model, action_lines)):
        if p.optimal_fiber_length and p.optimal_fiber_length > 0:
            out[:, k] = (lengths[:, k] - (p.tendon_slack_length or 0.0)) / p.optimal_fiber_length
    return out


def short_path_notes(model, action_lines, line_lengths) -> tuple:
    """A ``"warning: ..."`` note (one for the muscle, or none) naming the action lines whose path
    is not longer than their muscle's ``tendon_slack_length`` in some frame: their normalized
    length ``(L - l_ts) / l_opt`` is zero or negative there, which no fibre can be (a generated
    muscle says so through its belly's own warning; this one is for muscles with a mesh, whose
    surface ignores the tendon)."""
    lengths = np.asarray(line_lengths, dtype=float)
    parts = []
    for k, (name, p) in enumerate(zip(action_lines, _parameters(model, action_lines))):
        slack = p.tendon_slack_length
        if not slack or slack <= 0 or not (p.optimal_fiber_length and p.optimal_fiber_length > 0):
            continue
        short = lengths[:, k] <= slack
        if short.any():
            parts.append(f"{name} ({1e3 * lengths[short, k].min():.1f}-{1e3 * lengths[short, k].max():.1f} mm, "
                         f"l_ts {1e3 * slack:.1f} mm, {int(short.sum())} of {len(short)} frames)")
    if not parts:
        return ()
    return (f"warning: action line paths not longer than their tendon slack length l_ts: {', '.join(parts)}; "
            "their normalized length (L - l_ts) / l_opt is <= 0 there; check the model's "
            "tendon_slack_length and optimal_fiber_length",)


def moment_arm_notes(coordinates, fibre_moment_arms, line_moment_arms, *, mixed_passes=False) -> tuple:
    """Warnings (module docstring) for one muscle.

    Parameters
    ----------
    coordinates : sequence of C str
    fibre_moment_arms : (F, N, C) float
    line_moment_arms : (F, L, C) float
    mixed_passes : bool
        An action line's OpenSim length mixes wrapping passes (``ActionLines.drawn_lengths``,
        warned about when the lines are made); the hint then says so rather than point at the
        mesh.

    Returns
    -------
    tuple of str
        One ``"warning: ..."`` note per coordinate that fails, with the worst excess.
    """
    fibre = np.asarray(fibre_moment_arms, dtype=float)
    line = np.asarray(line_moment_arms, dtype=float)
    notes = []
    if fibre.size == 0 or line.size == 0:
        return ()
    median = np.median(fibre, axis=1)                                   # (F, C)
    lo, hi = line.min(axis=1), line.max(axis=1)                         # (F, C)
    big = np.abs(line).max(axis=1)
    margin = np.maximum(MARGIN_RELATIVE * big, MARGIN_ABSOLUTE)
    excess = np.maximum(lo - median, median - hi) - margin
    checked = big > MIN_LINE_ARM
    for c, name in enumerate(coordinates):
        bad = checked[:, c] & (excess[:, c] > 0)
        if not bad.any():
            continue
        f = int(np.argmax(np.where(bad, excess[:, c], -np.inf)))
        notes.append(f"warning: the median fibre moment arm about {name} leaves the action lines' range "
                     f"[{1e3 * lo[f, c]:.1f}, {1e3 * hi[f, c]:.1f}] mm by more than max({MARGIN_RELATIVE:.0%}, "
                     f"{1e3 * MARGIN_ABSOLUTE:.0f} mm) in {int(bad.sum())} of {int(checked[:, c].sum())} frames "
                     f"(worst: frame {f}, median {1e3 * median[f, c]:.1f} mm); "
                     + ("the action line's -dL/dq is that of OpenSim's length over wrap objects in series, which "
                        "keeps the first wrapping pass; the fibres follow the drawn path (compare OpenSim's "
                        "computeMomentArm)" if mixed_passes else
                        "check the mesh's rest pose, its attachments and the wrap objects"))
    return tuple(notes)
