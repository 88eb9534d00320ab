"""The four LHDL hip muscles (Modenese & Kohout 2020 data set) into 100 fibres x 15 segments.

Landmarks: ``attachments/attachment_landmarks.csv``. Gluteus maximus insertion cloud 2 (the
iliotibial tract on the tibia, ~310 mm from the muscle mesh) is left out: the surface does
not reach it. The psoas origins lie on lumbar vertebrae missing from the data set, 5-10 mm
from the muscle; they are used as given (they still define the axis and the trimming
plane; reconstructed ends land on the surface nearest to them).

Measured with this code (mm), full chain (attachment filter + 5 smoothing steps, each point's
smoothing shift softly bounded by 1 mm) / morph only:

=========== ===================== ================= ================= ==================
muscle      most outside, full    most outside,     start -> origin   end -> insertion
            chain                 morph only        landmark (max)    landmark (max)
=========== ===================== ================= ================= ==================
glut_max_r  3.8                   0.03              10.9              18.1
glut_med_r  4.2                   1.50              12.8              9.2
iliacus_r   4.2                   1.50              11.5              9.6
psoas_r     4.1                   0.49              10.2              2.2
=========== ===================== ================= ================= ==================

The full chain does NOT reach "inside or within 1 mm": what remains outside comes from the
attachment filter itself (Kohout §3.4) -- the straight new end segment from the cut point to
the attachment-area surface point closest to the ray crosses concave parts of the surface (up to 4.3 mm, glut_med), and
the resampled points on the kept part lie on chords between morphed points (up to 3.4 mm,
iliacus). Smoothing without the bound added up to 4 mm more (psoas 8.1 mm).

Original and clean meshes give the same numbers (the repair makes them identical).
"""
import warnings

import numpy as np
import pytest
from scipy.spatial import cKDTree

from fibres import as_surface, decompose

MUSCLES = ("glut_max_r", "glut_med_r", "iliacus_r", "psoas_r")
# the measured worst values above with ~20 % margin (the end points come from the
# attachment filter: the area surface point closest to each fibre's end ray)
START_MM = {"glut_max_r": 13.0, "glut_med_r": 15.5, "iliacus_r": 14.0, "psoas_r": 12.5}
END_MM = {"glut_max_r": 22.0, "glut_med_r": 11.5, "iliacus_r": 13.0, "psoas_r": 3.5}
# full chain: at most 5.5 mm outside (measured 3.4-4.3 mm: the filter's straight end segments
# and chords, see above; ~25 % margin)
FULL_OUTSIDE_MM = 5.5


def _landmarks(lhdl_dir, muscle):
    import pandas as pd

    table = pd.read_csv(lhdl_dir / "attachments" / "attachment_landmarks.csv")
    rows = table[table.muscle == muscle]
    origin = rows[rows.type == "origin"][["x_mm", "y_mm", "z_mm"]].to_numpy()
    ins = rows[(rows.type == "insertion") & (rows.cloud == 1)][["x_mm", "y_mm", "z_mm"]]
    return origin, ins.to_numpy()


def _signed_distance_mm(surface, points_m):
    """Positive inside, mm (VTK's exact point-to-triangle distance)."""
    import pyvista as pv
    from vtkmodules.vtkFiltersCore import vtkImplicitPolyDataDistance

    imp = vtkImplicitPolyDataDistance()
    faces = np.c_[np.full(len(surface.faces), 3), surface.faces].ravel()
    imp.SetInput(pv.PolyData(np.asarray(surface.vertices) * 1e3, faces))
    return -np.array([imp.EvaluateFunction(p) for p in np.asarray(points_m).reshape(-1, 3) * 1e3])


@pytest.fixture(scope="module")
def decomposed(lhdl_dir):
    out = {}
    for muscle in MUSCLES:
        origin, insertion = _landmarks(lhdl_dir, muscle)
        for folder in ("muscles", "muscles_clean"):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")        # the originals are repaired (one warning)
                surface = as_surface(lhdl_dir / folder / f"{muscle}.vtk", units="mm")
            full = decompose(surface, origin, insertion, units="mm", n_fibres=100, resolution=15)
            core = decompose(surface, origin, insertion, units="mm", n_fibres=100, resolution=15,
                             filter_attachments=False, smoothing_iterations=0)
            out[muscle, folder] = surface, origin * 1e-3, insertion * 1e-3, full, core
    return out


@pytest.mark.parametrize("folder", ["muscles", "muscles_clean"])
@pytest.mark.parametrize("muscle", MUSCLES)
def test_lhdl_fibres_inside_and_between_the_attachments(decomposed, muscle, folder):
    surface, origin, insertion, full, core = decomposed[muscle, folder]
    assert full.points.shape == (100, 16, 3)
    assert np.isfinite(full.points).all()
    # the morph itself (Kohout §3.3): MVC on a non-convex contour may fold slightly
    # outside; measured <= 1.5 mm, and 99 % of the points are inside or within 1 mm
    sd_core = _signed_distance_mm(surface, core.points)
    assert sd_core.min() >= -2.0
    assert np.mean(sd_core >= -1.0) >= 0.99
    # the full chain: trimming + straight reconstruction cut the concave walls of curved
    # muscles; the smoothing shift is bounded by 1 mm. Pinned at the measured values:
    # 91.7 % (psoas) to 99.7 % (glut_max) of the points inside or within 1 mm
    sd = _signed_distance_mm(surface, full.points)
    assert sd.min() >= -FULL_OUTSIDE_MM
    assert np.mean(sd >= -1.0) >= 0.9
    # every fibre starts near its origin area and ends near its insertion area ...
    d_start = cKDTree(origin).query(full.points[:, 0])[0] * 1e3
    d_end = cKDTree(insertion).query(full.points[:, -1])[0] * 1e3
    assert d_start.max() <= START_MM[muscle] and d_end.max() <= END_MM[muscle]
    # ... and far from the other one (the fibres run the right way round)
    assert (cKDTree(insertion).query(full.points[:, 0])[0] * 1e3).min() > 3 * START_MM[muscle]
    assert (cKDTree(origin).query(full.points[:, -1])[0] * 1e3).min() > 3 * END_MM[muscle]


def test_lhdl_original_and_clean_agree(decomposed):
    for muscle in MUSCLES:
        a = decomposed[muscle, "muscles"][3].points
        b = decomposed[muscle, "muscles_clean"][3].points
        # the repaired original is the clean mesh up to vertex order: same fibres to rounding
        assert np.abs(a - b).max() <= 1e-9


def _bender(origin, insertion):
    """A smooth bend of the muscle by ``deg`` degrees about an axis through the origin
    centroid, perpendicular to the attachment line and to z: each point turns by
    ``deg * t``, t its position along the attachment line clipped to 0..1 (the origin end
    stays, the insertion end turns fully) -- a stand-in for a joint sweep."""
    a, b = origin.mean(axis=0), insertion.mean(axis=0)
    length = np.linalg.norm(b - a)
    ax = (b - a) / length
    n = np.cross(ax, [0.0, 0.0, 1.0])
    n /= np.linalg.norm(n)

    def bend(x, deg):
        t = np.clip((x - a) @ ax / length, 0.0, 1.0)
        c, s = np.cos(np.deg2rad(deg) * t)[:, None], np.sin(np.deg2rad(deg) * t)[:, None]
        rel = x - a
        return a + rel * c + np.cross(n, rel) * s + n * (rel @ n)[:, None] * (1 - c)
    return bend


# measured max over fibres of |d1 - d2| / max|d1| at 10 degrees (h = 0.05 degree), with the
# attachment filter's choices frozen in the plan: 1.5e-2, 5.6e-2, 4.0e-2, 5.2e-4; the rest
# is the morph's own (its end slices fell back to fresh start/split choices on this bend:
# morph only, no filter, gave 1e-2, 7.9, 38, 4.7e-3; with the smooth anchored
# correspondence now 3.5e-3, 7.2, 1.4e-2, 4.7e-3 -- glut_med's 7.2 is its end plane's
# section changing topology within 0.1 degree of 10, 0.11 with the plan passed on to
# anchored_maps, see test_lhdl_bend_sweep_with_the_whole_section)
FD_REL = {"glut_max_r": 0.03, "glut_med_r": 0.08, "iliacus_r": 0.06, "psoas_r": 0.01}
# measured largest 1-degree length step / median over the steps of the largest step:
# 1.7, 3.8, 2.2, 4.6 (morph only: 56, 8.7, 34, 7.4)
STEP_RATIO = {"glut_max_r": 3.0, "glut_med_r": 5.5, "iliacus_r": 3.5, "psoas_r": 6.0}


@pytest.mark.parametrize("muscle", MUSCLES)
def test_lhdl_bend_sweep_with_the_plan_gives_smooth_fibre_lengths(decomposed, muscle):
    surface, origin, insertion, full, _ = decomposed[muscle, "muscles_clean"]
    v, f = np.asarray(surface.vertices), np.asarray(surface.faces)
    bend = _bender(origin, insertion)

    def lengths(deg):
        return decompose((bend(v, deg), f), bend(origin, deg), bend(insertion, deg),
                         plan=full.plan, n_fibres=100, resolution=15).lengths()

    ls = np.array([lengths(d) for d in range(21)])          # 0..20 degrees, 1-degree steps
    steps = np.abs(np.diff(ls, axis=0))
    assert steps.max() <= STEP_RATIO[muscle] * np.median(steps.max(axis=1))
    h = 0.05
    d1 = (lengths(10 + h) - lengths(10 - h)) / (2 * h)
    d2 = (lengths(10 + 2 * h) - lengths(10 - 2 * h)) / (4 * h)
    assert np.abs(d1).max() > 1e-5                           # the bend does change lengths
    assert np.abs(d1 - d2).max() <= FD_REL[muscle] * np.abs(d1).max()


# Plan reused over a 0..20-degree bend in 1-degree steps, attachment filter on (with the
# default smoothing) and off (morph only). Measured (this code, plan path as decompose wires
# it): largest 1-degree length step / median of the per-step largest steps
#   filter on : 1.71, 3.79, 2.28, 4.53      filter off: 1.23, 8.87, 17.2, 6.45
# (before the plan's loops and correspondence points followed the anchors: filter off 56,
# 8.7, 34, 7.4); the remaining large steps are planes whose section changes topology (two
# loops merging: iliacus planes 1-2 at 15-17 degrees, glut_med plane 6). Bounds ~20 % above.
SWEEP_STEP_RATIO = {("glut_max_r", True): 2.1, ("glut_med_r", True): 4.6,
                    ("iliacus_r", True): 2.8, ("psoas_r", True): 5.5,
                    ("glut_max_r", False): 1.5, ("glut_med_r", False): 10.7,
                    ("iliacus_r", False): 20.6, ("psoas_r", False): 7.8}
# h / 2h central differences (h = 1e-4 rad) at 1..19 degrees: fraction of (fibre, angle)
# pairs whose derivatives agree within 5 % (of the fibre's own, floored at 5 % of the
# largest): measured filter on 0.998, 0.998, 1.0, 1.0; off 1.0, 1.0, 0.994, 1.0 (before:
# off 0.85, 0.97, 0.60, 0.93). The target is 95 %.
FD_AGREE = 0.95


@pytest.mark.parametrize("filt", [True, False], ids=["filter", "morph_only"])
@pytest.mark.parametrize("muscle", MUSCLES)
def test_lhdl_bend_sweep_plan_is_smooth(decomposed, muscle, filt):
    surface, origin, insertion, full, core = decomposed[muscle, "muscles_clean"]
    v, f = np.asarray(surface.vertices), np.asarray(surface.faces)
    bend = _bender(origin, insertion)
    plan = (full if filt else core).plan
    notes = set()

    def lengths(deg):
        b = decompose((bend(v, deg), f), bend(origin, deg), bend(insertion, deg), plan=plan,
                      n_fibres=100, resolution=15, filter_attachments=filt,
                      smoothing_iterations=5 if filt else 0)
        notes.update(b.notes)
        return b.lengths()

    ls = np.array([lengths(d) for d in range(21)])
    steps = np.abs(np.diff(ls, axis=0))
    assert steps.max() <= SWEEP_STEP_RATIO[muscle, filt] * np.median(steps.max(axis=1))
    h = np.rad2deg(1e-4)
    agree = []
    for d in range(1, 20):
        d1 = (lengths(d + h) - lengths(d - h)) / (2 * h)
        d2 = (lengths(d + 2 * h) - lengths(d - 2 * h)) / (4 * h)
        scale = np.maximum(np.abs(d1), 0.05 * np.abs(d1).max())
        agree.append(np.abs(d1 - d2) <= 0.05 * scale)
    assert np.mean(agree) >= FD_AGREE
    # no discrete choice re-made: no fresh start/split choice on any frame
    assert not any("afresh" in n for n in notes)


# With the plan passed on to `fibres.morph.anchored_maps` (``plan=``; decompose does not
# pass it yet, so the test wires it), planes that cut one loop at rest follow their whole
# section through splits, merges and islands (`fibres.contours.bridge_loops`). Measured,
# morph only: step ratios 1.12, 4.98, 14.5, 6.45 (glut_med 8.9 -> 5.0, iliacus 17.8 ->
# 14.5 against the unwired path), h/2h agreement 1.0, 0.9995, 0.970, 1.0; bounds ~20 %
# above the step ratios.
WIRED_STEP_RATIO = {"glut_max_r": 1.35, "glut_med_r": 6.0, "iliacus_r": 17.4, "psoas_r": 7.8}


@pytest.mark.parametrize("muscle", MUSCLES)
def test_lhdl_bend_sweep_with_the_whole_section(decomposed, muscle, monkeypatch):
    import functools
    import importlib

    from fibres.morph import anchored_maps

    surface, origin, insertion, _, core = decomposed[muscle, "muscles_clean"]
    monkeypatch.setattr(importlib.import_module("fibres.decompose"), "anchored_maps",
                        functools.partial(anchored_maps, plan=core.plan))
    v, f = np.asarray(surface.vertices), np.asarray(surface.faces)
    bend = _bender(origin, insertion)
    notes = set()

    def lengths(deg):
        b = decompose((bend(v, deg), f), bend(origin, deg), bend(insertion, deg),
                      plan=core.plan, n_fibres=100, resolution=15, filter_attachments=False,
                      smoothing_iterations=0)
        notes.update(b.notes)
        return b.lengths()

    ls = np.array([lengths(d) for d in range(21)])
    steps = np.abs(np.diff(ls, axis=0))
    assert steps.max() <= WIRED_STEP_RATIO[muscle] * np.median(steps.max(axis=1))
    h = np.rad2deg(1e-4)
    agree = []
    for d in range(1, 20):
        d1 = (lengths(d + h) - lengths(d - h)) / (2 * h)
        d2 = (lengths(d + 2 * h) - lengths(d - 2 * h)) / (4 * h)
        agree.append(np.abs(d1 - d2) <= 0.05 * np.maximum(np.abs(d1), 0.05 * np.abs(d1).max()))
    assert np.mean(agree) >= FD_AGREE
    assert not any("afresh" in n for n in notes)
