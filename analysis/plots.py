"""Per-muscle plots of a run: fibre-length distributions, moment arms, normalised fibre lengths.

Inputs are plain arrays (frame axis first, SI units); the plots show millimetres and degrees for
readability. Each function writes one PNG atomically (``analysis.output_files.atomic_path``) and
returns its path. matplotlib is imported inside the functions (object API with the Agg canvas, no
pyplot global state), so importing this module is cheap and thread-safe to use.

Dimension letters: F frames, N fibres, L action lines, C coordinates.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .output_files import atomic_path

__all__ = ["plot_fibre_lengths", "plot_normalized_lengths", "plot_moment_arms", "plot_length_histogram",
           "plot_muscle"]

_BANDS = ((5.0, 95.0, 0.25, "fibres 5–95 %"), (25.0, 75.0, 0.45, "fibres 25–75 %"))
_FIBRE_COLOUR = "tab:blue"
_LINE_COLOURS = ("tab:red", "tab:orange", "tab:green", "tab:purple", "tab:brown", "tab:pink",
                 "tab:olive", "tab:cyan")
_DPI = 110


# --------------------------------------------------------------------------- validation
def _array(value, name, ndim):
    a = np.asarray(value, dtype=float)
    if a.ndim != ndim:
        raise ValueError(f"{name} must be a {ndim}-D array, got shape {a.shape}")
    return a


def _check_rows(a, name, frames, frames_name):
    if a.shape[0] != frames:
        raise ValueError(f"{name} has {a.shape[0]} frames (axis 0) but {frames_name} has {frames}")


def _names(names, count, what):
    names = [str(n) for n in names]
    if len(names) != count:
        raise ValueError(f"{what} has {len(names)} names for {count} columns")
    return names


def _percentiles(values, qs):
    """Percentiles over axis 1 ignoring NaN; frames with no finite value give NaN, silently."""
    out = np.full((len(qs), values.shape[0]), np.nan)
    ok = np.isfinite(values).any(axis=1)
    if ok.any():
        out[:, ok] = np.nanpercentile(values[ok], qs, axis=1)
    return out


# --------------------------------------------------------------------------- figure plumbing
def _figure(ncols=1, width=7.0, height=4.2):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width * ncols if ncols > 1 else width, height), dpi=_DPI,
                 layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, ncols, squeeze=False)[0]
    return fig, axes


def _save(fig, path) -> Path:
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", metadata={"Software": None})
    return path


def _band(ax, x, values, scale, *, median_label="fibres median"):
    """Percentile bands and the median of ``values`` (F, N) against ``x`` (F,)."""
    qs = [q for lo, hi, *_ in _BANDS for q in (lo, hi)] + [50.0]
    p = _percentiles(values, qs) * scale
    for k, (_lo, _hi, alpha, label) in enumerate(_BANDS):
        ax.fill_between(x, p[2 * k], p[2 * k + 1], color=_FIBRE_COLOUR, alpha=alpha,
                        linewidth=0, label=label)
    ax.plot(x, p[-1], color=_FIBRE_COLOUR, linewidth=2.0, label=median_label)


def _lines(ax, x, values, names, scale):
    for j, name in enumerate(names):
        ax.plot(x, values[:, j] * scale, color=_LINE_COLOURS[j % len(_LINE_COLOURS)],
                linestyle="--", linewidth=1.8, label=f"action line {name}")


# --------------------------------------------------------------------------- the plots
def plot_fibre_lengths(path, times, fibre_lengths, line_lengths, line_names, *, muscle: str,
                       title: str | None = None) -> Path:
    """Fibre-length distribution over time with the action lines on top.

    Parameters
    ----------
    path : str or Path
        The PNG to write.
    times : (F,) float
        Seconds.
    fibre_lengths : (F, N) float
        Metres; NaN marks a missing value.
    line_lengths : (F, L) float
        Metres, the action lines' (OpenSim path) lengths.
    line_names : sequence of L str
    muscle : str
        Used in the title.

    Returns
    -------
    Path
    """
    t = _array(times, "times", 1)
    fl = _array(fibre_lengths, "fibre_lengths", 2)
    ll = _array(line_lengths, "line_lengths", 2)
    _check_rows(fl, "fibre_lengths", len(t), "times")
    _check_rows(ll, "line_lengths", len(t), "times")
    names = _names(line_names, ll.shape[1], "line_names")
    fig, (ax,) = _figure()
    _band(ax, t, fl, 1e3)
    _lines(ax, t, ll, names, 1e3)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("length (mm)")
    ax.set_title(title or f"{muscle}: fibre lengths ({fl.shape[1]} fibres) and action lines")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    return _save(fig, path)


def plot_normalized_lengths(path, times, normalized_lengths, line_normalized, line_names, *, muscle: str,
                            title: str | None = None) -> Path:
    """Normalized fibre lengths l / l_opt over time (fibre band), with the action lines' rigid-tendon
    values (L_path - tendon_slack_length) / optimal_fiber_length where known.

    Parameters
    ----------
    path : str or Path
    times : (F,) float
    normalized_lengths : (F, N) float
    line_normalized : (F, L) float
        NaN columns are not drawn.
    line_names : sequence of L str
    muscle : str

    Returns
    -------
    Path
    """
    t = _array(times, "times", 1)
    nl = _array(normalized_lengths, "normalized_lengths", 2)
    ln = _array(line_normalized, "line_normalized", 2)
    _check_rows(nl, "normalized_lengths", len(t), "times")
    _check_rows(ln, "line_normalized", len(t), "times")
    names = _names(line_names, ln.shape[1], "line_names")
    fig, (ax,) = _figure()
    _band(ax, t, nl, 1.0)
    keep = [j for j in range(ln.shape[1]) if np.isfinite(ln[:, j]).any()]
    _lines(ax, t, ln[:, keep], [names[j] for j in keep], 1.0)
    ax.axhline(1.0, color="0.4", linewidth=0.8, linestyle=":")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("normalized length l / l_opt")
    ax.set_title(title or f"{muscle}: normalized fibre lengths ({nl.shape[1]} fibres)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    return _save(fig, path)


def plot_moment_arms(path, coordinate_values, fibre_moment_arms, line_moment_arms, line_names, *,
                     muscle: str, coordinate_names, rotational=None,
                     title: str | None = None) -> Path:
    """Moment arm against each coordinate: the fibre band and the action lines, one panel each.

    Frames are sorted by the panel's coordinate value (a sweep reads as a curve; in a motion
    where other coordinates also change, the band at one value pools those frames).

    Parameters
    ----------
    path : str or Path
    coordinate_values : (F, C) or (F,) float
        Radians (rotational) or metres.
    fibre_moment_arms : (F, N, C) or (F, N) float
        Metres (rotational coordinates; -dL/dq is dimensionless for translational ones).
    line_moment_arms : (F, L, C) or (F, L) float
    line_names : sequence of L str
    muscle : str
    coordinate_names : sequence of C str
    rotational : sequence of C bool, optional
        Default: all rotational (x in degrees, y in mm).

    Returns
    -------
    Path
    """
    q = np.asarray(coordinate_values, dtype=float)
    fm = np.asarray(fibre_moment_arms, dtype=float)
    lm = np.asarray(line_moment_arms, dtype=float)
    if q.ndim == 1:
        q, fm, lm = q[:, None], fm[..., None], lm[..., None]
    q = _array(q, "coordinate_values", 2)
    fm = _array(fm, "fibre_moment_arms", 3)
    lm = _array(lm, "line_moment_arms", 3)
    _check_rows(fm, "fibre_moment_arms", len(q), "coordinate_values")
    _check_rows(lm, "line_moment_arms", len(q), "coordinate_values")
    n_c = q.shape[1]
    if fm.shape[2] != n_c or lm.shape[2] != n_c:
        raise ValueError(f"moment arms have {fm.shape[2]} (fibres) and {lm.shape[2]} (lines) "
                         f"coordinates but coordinate_values has {n_c}")
    cnames = _names(coordinate_names, n_c, "coordinate_names")
    lnames = _names(line_names, lm.shape[1], "line_names")
    rot = [True] * n_c if rotational is None else [bool(r) for r in rotational]
    if len(rot) != n_c:
        raise ValueError(f"rotational has {len(rot)} flags for {n_c} coordinates")
    fig, axes = _figure(ncols=n_c, width=6.0 if n_c > 1 else 7.0)
    for c, ax in enumerate(axes):
        order = np.argsort(q[:, c], kind="stable")
        x = q[order, c] * (180.0 / np.pi if rot[c] else 1.0)
        scale = 1e3 if rot[c] else 1.0
        _band(ax, x, fm[order, :, c], scale)
        _lines(ax, x, lm[order, :, c], lnames, scale)
        ax.axhline(0.0, color="0.4", linewidth=0.8)
        ax.set_xlabel(f"{cnames[c]} ({'deg' if rot[c] else 'm'})")
        ax.set_ylabel("moment arm (mm)" if rot[c] else "−dL/dq (m/m)")
        ax.set_title(f"about {cnames[c]}", fontsize="medium")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize="small")
    fig.suptitle(title or f"{muscle}: moment arms, r = −dL/dq ({fm.shape[1]} fibres)")
    return _save(fig, path)


def plot_length_histogram(path, fibre_lengths, rest_lengths, *, muscle: str, times=None,
                          frames=None, bins: int = 30, title: str | None = None) -> Path:
    """Histograms of normalised fibre length L / L_rest at a few frames.

    Parameters
    ----------
    path : str or Path
    fibre_lengths : (F, N) float
        Metres.
    rest_lengths : (N,) float
        Each fibre's length at the rest pose (metres, > 0).
    times : (F,) float, optional
        Used in the legend.
    frames : sequence of int, optional
        Frames to show; default the first, middle and last. ``"all"`` pools every frame.
    bins : int

    Returns
    -------
    Path
    """
    fl = _array(fibre_lengths, "fibre_lengths", 2)
    rest = _array(rest_lengths, "rest_lengths", 1)
    if rest.shape[0] != fl.shape[1]:
        raise ValueError(f"rest_lengths has {rest.shape[0]} fibres but fibre_lengths has "
                         f"{fl.shape[1]}")
    if not np.all(rest[np.isfinite(rest)] > 0):
        raise ValueError("rest_lengths must be positive")
    n_f = fl.shape[0]
    t = None if times is None else _array(times, "times", 1)
    if t is not None:
        _check_rows(fl, "fibre_lengths", len(t), "times")
    ratio = fl / rest[None, :]
    if isinstance(frames, str):
        if frames != "all":
            raise ValueError(f"frames must be a sequence of ints or 'all', got {frames!r}")
        groups = [("all frames", ratio.ravel())]
    else:
        sel = sorted(set([0, n_f // 2, n_f - 1])) if frames is None else [int(f) for f in frames]
        if any(not -n_f <= f < n_f for f in sel):
            raise ValueError(f"frames {sel} out of range for {n_f} frames")
        groups = [(f"frame {f % n_f}" + ("" if t is None else f" (t = {t[f]:.3g} s)"), ratio[f])
                  for f in sel]
    finite = np.concatenate([g[1][np.isfinite(g[1])] for g in groups])
    lo, hi = (finite.min(), finite.max()) if finite.size else (0.9, 1.1)
    if hi - lo < 1e-6:
        lo, hi = lo - 0.01, hi + 0.01
    edges = np.linspace(lo, hi, int(bins) + 1)
    fig, (ax,) = _figure()
    for k, (label, values) in enumerate(groups):
        ax.hist(values[np.isfinite(values)], bins=edges, histtype="step", linewidth=1.8,
                color=_LINE_COLOURS[k % len(_LINE_COLOURS)] if k else _FIBRE_COLOUR, label=label)
    ax.axvline(1.0, color="0.4", linewidth=0.8, linestyle=":")
    ax.set_xlabel("normalised fibre length L / L_rest (–)")
    ax.set_ylabel("fibres")
    ax.set_title(title or f"{muscle}: normalised fibre lengths ({fl.shape[1]} fibres)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    return _save(fig, path)


def plot_muscle(out_dir, muscle: str, *, times, fibre_lengths, line_lengths, line_names,
                coordinate_values, fibre_moment_arms, line_moment_arms, coordinate_names,
                rest_lengths=None, rotational=None, normalized_lengths=None, line_normalized=None) -> list:
    """All plots of one muscle into ``out_dir``; returns the written paths.

    Files: ``<muscle>_lengths.png``, ``<muscle>_moment_arms.png``, when ``rest_lengths`` is
    given ``<muscle>_length_histogram.png``, and when ``normalized_lengths`` (F, N) has values
    ``<muscle>_normalized_lengths.png``. Shapes as in the individual functions.
    """
    out = Path(out_dir)
    paths = [plot_fibre_lengths(out / f"{muscle}_lengths.png", times, fibre_lengths,
                                line_lengths, line_names, muscle=muscle),
             plot_moment_arms(out / f"{muscle}_moment_arms.png", coordinate_values,
                              fibre_moment_arms, line_moment_arms, line_names, muscle=muscle,
                              coordinate_names=coordinate_names, rotational=rotational)]
    if rest_lengths is not None:
        paths.append(plot_length_histogram(out / f"{muscle}_length_histogram.png", fibre_lengths,
                                           rest_lengths, muscle=muscle, times=times))
    if normalized_lengths is not None and np.isfinite(np.asarray(normalized_lengths, dtype=float)).any():
        line_norm = (np.full(np.shape(line_lengths), np.nan) if line_normalized is None else line_normalized)
        paths.append(plot_normalized_lengths(out / f"{muscle}_normalized_lengths.png", times, normalized_lengths,
                                             line_norm, line_names, muscle=muscle))
    return paths
