"""analysis.plots: PNG files of sane size, shape checks, atomic writes, NaN-safe percentiles."""
from __future__ import annotations

import struct

import numpy as np
import pytest

from analysis import plots

F, N, L = 27, 60, 2


def _png_size(path):
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


@pytest.fixture()
def synthetic():
    """Straight fibres across a pin joint: L = |R(q) (d, -b) - (d, a)|, r = -dL/dq analytic."""
    rng = np.random.default_rng(1)
    q = np.radians(np.linspace(0.0, 130.0, F))
    a = 0.2 + 0.02 * rng.random(N)
    b = 0.05 + 0.01 * rng.random(N)
    d = 0.01 + 0.01 * rng.random(N)

    def length(q, a, b, d):
        c, s = np.cos(q), np.sin(q)
        return np.hypot(d * c + b * s - d, d * s - b * c - a)

    h = 1e-6
    fl = length(q[:, None], a, b, d)
    fm = -(length(q[:, None] + h, a, b, d) - length(q[:, None] - h, a, b, d)) / (2 * h)
    ll = np.stack([length(q, 0.21, 0.055, 0.015), length(q, 0.2, 0.05, 0.02)], axis=1)
    lm = -(np.stack([length(q + h, 0.21, 0.055, 0.015), length(q + h, 0.2, 0.05, 0.02)], 1)
           - np.stack([length(q - h, 0.21, 0.055, 0.015), length(q - h, 0.2, 0.05, 0.02)], 1)
           ) / (2 * h)
    return dict(times=0.05 * np.arange(F), fibre_lengths=fl, line_lengths=ll,
                line_names=["A", "B"], coordinate_values=q, fibre_moment_arms=fm,
                line_moment_arms=lm, coordinate_names=["elbow_flexion"], rest_lengths=fl[0])


def test_plot_muscle_writes_three_pngs(synthetic, tmp_path):
    paths = plots.plot_muscle(tmp_path, "biceps", **synthetic)
    assert [p.name for p in paths] == ["biceps_lengths.png", "biceps_moment_arms.png",
                                       "biceps_length_histogram.png"]
    for p, (lo, hi) in zip(paths, ((8.0, 9.5), (8.0, 9.5), (7.0, 7.0))):
        w, h = _png_size(p)
        # figure size (width x 4.2 in) at 110 dpi, give or take a pixel of rounding; the 7-inch
        # figure is widened by its legend on the right (1-2.5 in for these labels)
        assert lo * 110 - 1 <= w <= hi * 110 + 1 and abs(h - 462) <= 1
        assert 10_000 < p.stat().st_size < 500_000
    assert sorted(x.name for x in tmp_path.iterdir()) == sorted(p.name for p in paths)


def test_moment_arms_one_panel_per_coordinate(synthetic, tmp_path):
    q = np.stack([synthetic["coordinate_values"], 0.01 * np.arange(F)], axis=1)
    fm = np.stack([synthetic["fibre_moment_arms"]] * 2, axis=2)
    lm = np.stack([synthetic["line_moment_arms"]] * 2, axis=2)
    p = plots.plot_moment_arms(tmp_path / "m.png", q, fm, lm, ["A", "B"], muscle="x",
                               coordinate_names=["flex", "slide"], rotational=[True, False])
    w, h = _png_size(p)
    assert 13 * 110 <= w <= 14.5 * 110 and abs(h - 462) <= 1     # two 6-inch panels + legend


def test_histogram_pooled_and_nan_frames(synthetic, tmp_path):
    fl = synthetic["fibre_lengths"].copy()
    fl[3] = np.nan                                          # a missing frame must not break it
    plots.plot_length_histogram(tmp_path / "h.png", fl, synthetic["rest_lengths"], muscle="m",
                                frames="all")
    plots.plot_fibre_lengths(tmp_path / "l.png", synthetic["times"], fl,
                             synthetic["line_lengths"], ["A", "B"], muscle="m")
    assert _png_size(tmp_path / "h.png")[0] > 0 and _png_size(tmp_path / "l.png")[0] > 0


def test_percentiles_match_numpy_and_skip_empty_frames():
    rng = np.random.default_rng(0)
    v = rng.random((5, 40))
    v[1, :10] = np.nan
    v[2] = np.nan
    p = plots._percentiles(v, [5.0, 50.0, 95.0])
    np.testing.assert_allclose(p[:, 0], np.percentile(v[0], [5, 50, 95]), rtol=1e-12)
    np.testing.assert_allclose(p[:, 1], np.percentile(v[1, 10:], [5, 50, 95]), rtol=1e-12)
    assert np.isnan(p[:, 2]).all()


@pytest.mark.parametrize("call", [
    lambda s, d: plots.plot_fibre_lengths(d / "x.png", s["times"][:-1], s["fibre_lengths"],
                                          s["line_lengths"], ["A", "B"], muscle="m"),
    lambda s, d: plots.plot_fibre_lengths(d / "x.png", s["times"], s["fibre_lengths"],
                                          s["line_lengths"], ["A"], muscle="m"),
    lambda s, d: plots.plot_fibre_lengths(d / "x.png", s["times"], s["fibre_lengths"][0],
                                          s["line_lengths"], ["A", "B"], muscle="m"),
    lambda s, d: plots.plot_moment_arms(d / "x.png", s["coordinate_values"],
                                        s["fibre_moment_arms"][:, :, None].repeat(2, 2),
                                        s["line_moment_arms"], ["A", "B"], muscle="m",
                                        coordinate_names=["q"]),
    lambda s, d: plots.plot_moment_arms(d / "x.png", s["coordinate_values"],
                                        s["fibre_moment_arms"], s["line_moment_arms"],
                                        ["A", "B"], muscle="m", coordinate_names=["q", "p"]),
    lambda s, d: plots.plot_length_histogram(d / "x.png", s["fibre_lengths"],
                                             s["rest_lengths"][1:], muscle="m"),
    lambda s, d: plots.plot_length_histogram(d / "x.png", s["fibre_lengths"],
                                             -s["rest_lengths"], muscle="m"),
    lambda s, d: plots.plot_length_histogram(d / "x.png", s["fibre_lengths"],
                                             s["rest_lengths"], muscle="m", frames=[F]),
])
def test_rejects_mismatched_shapes_and_writes_nothing(synthetic, tmp_path, call):
    with pytest.raises(ValueError):
        call(synthetic, tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_failed_save_leaves_no_file(synthetic, tmp_path, monkeypatch):
    from matplotlib.figure import Figure

    def boom(self, *a, **k):
        raise OSError("disk full")

    monkeypatch.setattr(Figure, "savefig", boom)
    with pytest.raises(OSError):
        plots.plot_fibre_lengths(tmp_path / "x.png", synthetic["times"],
                                 synthetic["fibre_lengths"], synthetic["line_lengths"],
                                 ["A", "B"], muscle="m")
    assert list(tmp_path.iterdir()) == []


def test_import_does_not_load_matplotlib():
    import subprocess
    import sys

    code = "import sys, analysis.plots; print('matplotlib' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_coordinate_axis_fits_the_motion():
    t = np.linspace(0, 1, 101)
    assert plots.coordinate_axis(np.radians(130) * t) == "sweep"
    assert plots.coordinate_axis(np.radians(130) * (1 - t)) == "sweep"            # downwards too
    assert plots.coordinate_axis(np.radians(30) * np.sin(2 * np.pi * t)) == "time"   # gait-like
    assert plots.coordinate_axis(np.full(101, 0.3)) == "constant"
    assert plots.coordinate_axis(0.3 + 1e-5 * t) == "constant"
    assert plots.coordinate_axis(0.02 * t, rotational=False) == "sweep"
    noisy = np.radians(100) * t + 1e-6 * np.sin(50 * t)       # float noise on a sweep
    assert plots.coordinate_axis(noisy) == "sweep"


def test_constant_coordinates_get_no_panel(synthetic, tmp_path):
    """Gait-like: one oscillating coordinate (against time), one constant (skipped)."""
    t = synthetic["times"]
    q = np.stack([np.radians(30) * np.sin(2 * np.pi * t / t[-1]), np.full(F, 0.2)], axis=1)
    fm = np.stack([synthetic["fibre_moment_arms"]] * 2, axis=2)
    lm = np.stack([synthetic["line_moment_arms"]] * 2, axis=2)
    p = plots.plot_moment_arms(tmp_path / "m.png", q, fm, lm, ["A", "B"], muscle="x",
                               coordinate_names=["hip", "fixed"], times=t)
    w, _ = _png_size(p)
    assert 8 * 110 <= w <= 9.5 * 110                           # one 7-inch panel + legend, not two
    # all constant: drawn against time rather than not at all
    p = plots.plot_moment_arms(tmp_path / "c.png", np.full(F, 0.2), synthetic["fibre_moment_arms"],
                               synthetic["line_moment_arms"], ["A", "B"], muscle="x", coordinate_names=["c"],
                               times=t)
    assert _png_size(p)[0] > 0


def test_long_titles_stay_inside_the_figure(synthetic, tmp_path, monkeypatch):
    """LHDL glut_med_r: one flexion panel and two constant coordinates made a title wider than the
    7-inch figure, cut off at both edges. It is wrapped, and the panel is lowered under it."""
    figures = []
    save = plots._save
    monkeypatch.setattr(plots, "_save", lambda fig, path: (figures.append(fig), save(fig, path))[1])
    t = synthetic["times"]
    q = np.stack([synthetic["coordinate_values"], np.zeros(F), np.zeros(F)], axis=1)
    fm = np.stack([synthetic["fibre_moment_arms"]] * 3, axis=2)
    lm = np.stack([synthetic["line_moment_arms"]] * 3, axis=2)
    names = ["hip_flexion_r", "hip_adduction_r", "hip_rotation_r"]
    for muscle in ("glut_med_r", "a_rather_long_muscle_name_" * 3):
        plots.plot_moment_arms(tmp_path / "m.png", q, fm, lm, ["A", "B"], muscle=muscle,
                               coordinate_names=names, times=t)
        fig = figures[-1]
        renderer = fig.canvas.get_renderer()
        box = fig._suptitle.get_window_extent(renderer)
        fig_w, fig_h = fig.bbox.width, fig.bbox.height
        assert box.x0 >= 0 and box.x1 <= fig_w and box.y1 <= fig_h, (box, fig_w)
        panel_title = fig.axes[0].title.get_window_extent(renderer)
        assert box.y0 >= panel_title.y1, (box, panel_title)     # no overlap with "about ..."
        assert "hip_rotation_r" in fig._suptitle.get_text()


@pytest.mark.parametrize("which", ["lengths", "normalized", "moment_arms", "moment_arms_2"])
def test_legends_cover_no_data(synthetic, tmp_path, monkeypatch, which):
    """The legend lies outside every panel (so over no band or line), inside the figure, and the
    panels keep their size in inches (7 or 6 in figure minus the fixed margins of `_figure`)."""
    figures = []
    save = plots._save
    monkeypatch.setattr(plots, "_save", lambda fig, path: (figures.append(fig), save(fig, path))[1])
    s = synthetic
    if which == "lengths":
        plots.plot_fibre_lengths(tmp_path / "l.png", s["times"], s["fibre_lengths"], s["line_lengths"],
                                 ["A", "WIDE_MW_CAPITALS_LINE_NAME"], muscle="m")
    elif which == "normalized":
        plots.plot_normalized_lengths(tmp_path / "n.png", s["times"], s["fibre_lengths"] / 0.2,
                                      s["line_lengths"] / 0.2, ["A", "B"], muscle="m")
    else:
        n_c = 1 if which == "moment_arms" else 2
        q = np.stack([s["coordinate_values"]] * n_c, axis=1)
        fm = np.stack([s["fibre_moment_arms"]] * n_c, axis=2)
        lm = np.stack([s["line_moment_arms"]] * n_c, axis=2)
        plots.plot_moment_arms(tmp_path / "m.png", q, fm, lm, ["A", "B"], muscle="m",
                               coordinate_names=[f"c{k}" for k in range(n_c)])
    fig = figures[-1]
    renderer = fig.canvas.get_renderer()
    legends = fig.legends + [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    assert len(legends) == 1
    box = legends[0].get_window_extent(renderer)
    assert box.x0 >= 0 and box.x1 <= fig.bbox.width and box.y0 >= 0 and box.y1 <= fig.bbox.height
    for ax in fig.axes:
        panel = ax.get_window_extent(renderer)
        assert not box.overlaps(panel), (box, panel)
        # the data area is as wide as without a legend: figure width minus the 0.75 + 0.15 in margins
        panel_in = panel.width / fig.dpi
        n = len(fig.axes)
        expected = 7.0 - 0.9 if n == 1 else (6.0 * n - 0.9) / (n + (n - 1) * 0.9 / 6.0)
        assert abs(panel_in - expected) < 0.02, (panel_in, expected)
