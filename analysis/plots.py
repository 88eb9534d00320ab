"""Per-muscle plots of a run: fibre-length distributions, moment arms, normalised fibre lengths.

Inputs are plain arrays (frame axis first, SI units); the plots show millimetres and degrees for
readability. Each function writes one PNG atomically (``analysis.output_files.atomic_path``) and
returns its path. matplotlib is imported inside the functions (object API with the Agg canvas, no
pyplot global state), so importing this module is cheap and thread-safe to use.

The x axis of a moment-arm panel fits the motion (`coordinate_axis`): the coordinate where it
sweeps monotonically, time otherwise (gait), no panel for a constant coordinate. Figures use fixed
margins, at most 6 ticks per axis and fast PNG compression: constrained layout, tick objects and
zlib level 6 were most of the plotting time of a gait run.

Legends sit outside the axes, right of the panels (`_legend_right`): the figure is widened by the
legend's width, so the panels keep their size and no band or line is hidden behind a legend
(``loc="best"`` counts where outlines cross the legend, not the area a band covers, and put
legends on bands and lines).

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
    finite = np.isfinite(values)
    if finite.all():          # one vectorised call (nanpercentile goes row by row)
        return np.percentile(values, qs, axis=1)
    out = np.full((len(qs), values.shape[0]), np.nan)
    ok = finite.any(axis=1)
    if ok.any():
        out[:, ok] = np.nanpercentile(values[ok], qs, axis=1)
    return out


# --------------------------------------------------------------------------- figure plumbing
def _figure(ncols=1, width=7.0, height=4.2):
    """A figure of ``ncols`` panels. Margins are fixed fractions (matplotlib's constrained layout
    cost more than the drawing itself: about half of the plotting time of a gait run)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    total = width * ncols if ncols > 1 else width
    fig = Figure(figsize=(total, height), dpi=_DPI)
    FigureCanvasAgg(fig)
    left = 0.75 / total
    fig.subplots_adjust(left=left, right=1 - 0.15 / total, bottom=0.12, top=0.86,
                        wspace=0.9 / width if ncols > 1 else 0.2)
    axes = fig.subplots(1, ncols, squeeze=False)[0]
    from matplotlib.ticker import MaxNLocator

    for ax in axes:     # fewer ticks: tick objects and their labels are most of the drawing time
        ax.xaxis.set_major_locator(MaxNLocator(nbins=6))
        ax.yaxis.set_major_locator(MaxNLocator(nbins=6))
    return fig, axes


#: legend text width per character at the "small" font (8.3 pt DejaVu Sans: lower case and digits
#: about 0.5 em, capitals up to 0.75 em) and the width of the handle, its gaps, the frame and the
#: margin right of it (inches); the example's legends measure 1.5-1.7 in
_LEGEND_CHAR_IN, _LEGEND_CAPITAL_IN, _LEGEND_PAD_IN = 0.06, 0.088, 0.6


def _legend_right(fig, ax):
    """The legend of ``ax``'s artists outside the panels, right of them, top-aligned with them.

    The figure is widened by the legend's width, estimated from its longest label (no text is
    measured: that would cost a render), and the margins are rescaled so that every panel keeps
    its size in inches."""
    handles, labels = ax.get_legend_handles_labels()
    if not handles:
        return
    width_in, height_in = fig.get_size_inches()
    extra = _LEGEND_PAD_IN + max(sum(_LEGEND_CAPITAL_IN if c.isupper() else _LEGEND_CHAR_IN for c in t)
                                 for t in labels)
    total = width_in + extra
    sp = fig.subplotpars
    left_in, right_in = sp.left * width_in, sp.right * width_in
    fig.set_size_inches(total, height_in)
    fig.subplots_adjust(left=left_in / total, right=right_in / total)
    fig.legend(handles, labels, loc="upper left", bbox_to_anchor=((right_in + 0.1) / total, sp.top),
               fontsize="small", framealpha=0.7, borderaxespad=0.0)


def _save(fig, path) -> Path:
    path = Path(path)
    with atomic_path(path) as tmp:
        # zlib level 1: a third of the encoding time of the default level 6, files ~20 % larger
        fig.savefig(tmp, format="png", metadata={"Software": None}, pil_kwargs={"compress_level": 1})
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
    fl = _array(fibre_lengths, "fibre_lengths", 2)
    return _over_time(path, times, fl, line_lengths, line_names, names=("fibre_lengths", "line_lengths"),
                      scale=1e3, ylabel="length (mm)",
                      title=title or f"{muscle}: fibre lengths ({fl.shape[1]} fibres) and action lines")


#: a coordinate whose range over the frames is below this is constant: not drawn (rad; m)
CONSTANT_RANGE = {True: np.radians(0.05), False: 5e-5}


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
    nl = _array(normalized_lengths, "normalized_lengths", 2)
    return _over_time(path, times, nl, line_normalized, line_names,
                      names=("normalized_lengths", "line_normalized"), scale=1.0,
                      ylabel="normalized length l / l_opt", reference=1.0,
                      title=title or f"{muscle}: normalized fibre lengths ({nl.shape[1]} fibres)")


def _over_time(path, times, fibres, lines, line_names, *, names, scale, ylabel, title, reference=None) -> Path:
    """The fibres' band (F, N) and the action lines (F, L) over time; line columns without a
    finite value are not drawn; ``reference``: a dotted horizontal line there."""
    t = _array(times, "times", 1)
    lv = _array(lines, names[1], 2)
    _check_rows(fibres, names[0], len(t), "times")
    _check_rows(lv, names[1], len(t), "times")
    lnames = _names(line_names, lv.shape[1], "line_names")
    fig, (ax,) = _figure()
    _band(ax, t, fibres, scale)
    keep = [j for j in range(lv.shape[1]) if np.isfinite(lv[:, j]).any()]
    _lines(ax, t, lv[:, keep], [lnames[j] for j in keep], scale)
    if reference is not None:
        ax.axhline(reference, color="0.4", linewidth=0.8, linestyle=":")
    ax.set_xlabel("time (s)")
    ax.set_ylabel(ylabel)
    ax.set_title(title, y=1.01)
    ax.grid(True, alpha=0.3)
    _legend_right(fig, ax)
    return _save(fig, path)


def coordinate_axis(values, rotational=True) -> str:
    """How a coordinate's moment arm is drawn: ``"constant"`` (range below `CONSTANT_RANGE`: not
    drawn, it would be a vertical stroke), ``"sweep"`` (monotonic over the frames, steps back
    smaller than 0.1 % of its range allowed: against the coordinate) or ``"time"`` (anything
    else, e.g. gait: against time, since frames joined in coordinate order make a sawtooth)."""
    q = np.asarray(values, dtype=float)
    q = q[np.isfinite(q)]
    if q.size < 2:
        return "constant"
    span = float(q.max() - q.min())
    if span < CONSTANT_RANGE[bool(rotational)]:
        return "constant"
    d = np.diff(q)
    tol = 1e-3 * span
    return "sweep" if (d >= -tol).all() or (d <= tol).all() else "time"


def plot_moment_arms(path, coordinate_values, fibre_moment_arms, line_moment_arms, line_names, *,
                     muscle: str, coordinate_names, rotational=None, times=None,
                     title: str | None = None) -> Path:
    """Moment arm about each coordinate: the fibre band and the action lines, one panel each.

    A panel's x axis fits the motion (`coordinate_axis`): the coordinate itself where it sweeps
    monotonically, time (``times``; the frame index without it) otherwise; a coordinate held
    constant gets no panel (named in the title). If every coordinate is constant, all are drawn
    against time.

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
    times : (F,) float, optional
        Seconds, the x axis of non-monotonic coordinates.

    Returns
    -------
    Path
    """
    q = np.asarray(coordinate_values, dtype=float)
    fm, lm = fibre_moment_arms, line_moment_arms
    if q.ndim == 1:                    # one coordinate, given without its axis
        q, fm, lm = q[:, None], np.expand_dims(fm, -1), np.expand_dims(lm, -1)
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
    if times is None:
        t, t_label = np.arange(len(q), dtype=float), "frame"
    else:
        t = _array(times, "times", 1)
        _check_rows(q, "coordinate_values", len(t), "times")
        t_label = "time (s)"
    kinds = [coordinate_axis(q[:, c], rot[c]) for c in range(n_c)]
    shown = [c for c in range(n_c) if kinds[c] != "constant"]
    if not shown:
        shown, kinds = list(range(n_c)), ["time"] * n_c
    skipped = [cnames[c] for c in range(n_c) if c not in shown]
    fig, axes = _figure(ncols=len(shown), width=6.0 if len(shown) > 1 else 7.0)
    for ax, c in zip(axes, shown):
        scale = 1e3 if rot[c] else 1.0
        if kinds[c] == "sweep":
            x = q[:, c] * (180.0 / np.pi if rot[c] else 1.0)
            ax.set_xlabel(f"{cnames[c]} ({'deg' if rot[c] else 'm'})")
        else:
            x = t
            ax.set_xlabel(t_label)
        _band(ax, x, fm[:, :, c], scale)
        _lines(ax, x, lm[:, :, c], lnames, scale)
        ax.axhline(0.0, color="0.4", linewidth=0.8)
        ax.set_ylabel("moment arm (mm)" if rot[c] else "−dL/dq (m/m)")
        ax.set_title(f"about {cnames[c]}", fontsize="medium", y=1.01)
        ax.grid(True, alpha=0.3)
    _legend_right(fig, axes[0])
    text = title or f"{muscle}: moment arms, r = −dL/dq ({fm.shape[1]} fibres)"
    if skipped and title is None:
        text += f"; constant, not drawn: {', '.join(skipped)}"
    _suptitle(fig, text)
    return _save(fig, path)


def _suptitle(fig, text):
    """The figure title wrapped to the figure's width (a long list of constant coordinates was
    cut off at both edges), the panels lowered by the extra lines. The width per character is a
    bound for DejaVu Sans at the medium size (about 0.6 em on average, here 0.085 in), so no text
    has to be measured (drawing it twice would cost a render)."""
    import textwrap

    width_in, height_in = fig.get_size_inches()
    lines = textwrap.wrap(text, width=max(20, int((width_in - 0.3) / 0.085)),
                          break_on_hyphens=False) or [text]
    if len(lines) > 1:
        line_h = 1.25 * 10.0 / 72.0 / height_in      # one 10 pt line in figure fractions
        fig.subplots_adjust(top=fig.subplotpars.top - line_h * (len(lines) - 1))
    sp = fig.subplotpars      # centred over the panels (a legend may sit right of them)
    fig.suptitle("\n".join(lines), fontsize="medium", x=0.5 * (sp.left + sp.right))


def plot_length_histogram(path, fibre_lengths, rest_lengths, *, muscle: str, times=None,
                          frames=None, bins: int = 30, title: str | None = None) -> Path:
    """Histograms of normalised fibre length L / L_rest at a few frames: each frame's fibres about
    their own median (the legend gives it), with their own bins over their own range.

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
    fig, (ax,) = _figure()
    for k, (label, values) in enumerate(groups):
        v = values[np.isfinite(values)]
        # each frame about its own median, with its own bins over its own range: on one shared
        # axis and shared bins, frames whose fibres are all alike fill one to three bins
        med = float(np.median(v)) if v.size else 1.0
        d = 100.0 * (v - med)
        lo, hi = (float(d.min()), float(d.max())) if v.size else (-1.0, 1.0)
        if hi - lo < 1e-4:
            lo, hi = lo - 0.05, hi + 0.05
        n_bins = min(max(int(bins), 1), max(5, v.size // 3))
        ax.hist(d, bins=np.linspace(lo, hi, n_bins + 1), histtype="step", linewidth=1.8,
                color=_LINE_COLOURS[(k - 1) % len(_LINE_COLOURS)] if k else _FIBRE_COLOUR,
                label=f"{label}: median {med:.3f}")
    ax.axvline(0.0, color="0.4", linewidth=0.8, linestyle=":")
    ax.set_xlabel("L / L_rest − its frame's median (% of L_rest)")
    ax.set_ylabel("fibres per bin")
    ax.set_title(title or f"{muscle}: spread of normalised fibre lengths ({fl.shape[1]} fibres)", y=1.01)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small", framealpha=0.7)
    return _save(fig, path)


def plot_muscle(out_dir, muscle: str, *, times, fibre_lengths, line_lengths, line_names,
                coordinate_values, fibre_moment_arms, line_moment_arms, coordinate_names,
                rest_lengths=None, rotational=None, normalized_lengths=None, line_normalized=None,
                stem=None) -> list:
    """All plots of one muscle into ``out_dir``; returns the written paths.

    Files: ``<stem>_lengths.png``, ``<stem>_moment_arms.png``, when ``rest_lengths`` is
    given ``<stem>_length_histogram.png``, and when ``normalized_lengths`` (F, N) has values
    ``<stem>_normalized_lengths.png``. ``stem`` (default: the muscle name) is the safe file stem of
    the muscle (`analysis.file_names`); the titles show the muscle name itself. Shapes as in the
    individual functions.
    """
    out = Path(out_dir)
    stem = muscle if stem is None else stem
    paths = [plot_fibre_lengths(out / f"{stem}_lengths.png", times, fibre_lengths,
                                line_lengths, line_names, muscle=muscle),
             plot_moment_arms(out / f"{stem}_moment_arms.png", coordinate_values,
                              fibre_moment_arms, line_moment_arms, line_names, muscle=muscle,
                              coordinate_names=coordinate_names, rotational=rotational, times=times)]
    if rest_lengths is not None:
        paths.append(plot_length_histogram(out / f"{stem}_length_histogram.png", fibre_lengths,
                                           rest_lengths, muscle=muscle, times=times))
    if normalized_lengths is not None and np.isfinite(np.asarray(normalized_lengths, dtype=float)).any():
        line_norm = (np.full(np.shape(line_lengths), np.nan) if line_normalized is None else line_normalized)
        paths.append(plot_normalized_lengths(out / f"{stem}_normalized_lengths.png", times, normalized_lengths,
                                             line_norm, line_names, muscle=muscle))
    return paths
