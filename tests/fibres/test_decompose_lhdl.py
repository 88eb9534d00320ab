"""The four LHDL hip muscles (Modenese & Kohout 2020 data set) into 100 fibres x 15 segments.

Landmarks: ``attachments/attachment_landmarks.csv``. Gluteus maximus insertion cloud 2 (the
iliotibial tract on the tibia, ~310 mm from the muscle mesh) is left out: the surface does
not reach it. The psoas origins lie on lumbar vertebrae missing from the data set, 5-10 mm
from the muscle; they are used as given (they still define the axis and the trimming
plane; reconstructed ends land on the surface nearest to them).

Measured with this code (mm, 100 fibres x 16 points, parallel template, default chain:
attachment filter, 5 smoothing steps with each shift softly bounded by 1 mm, then the
containment pull `fibres.finishing.containment`); "outside" is VTK's exact distance to the surface,
start/end is the distance from each fibre's first/last point to the nearest origin/insertion
landmark (the landmarks lie on bone, a few mm off the muscle surface), "gap" is the largest
distance from an origin landmark to the nearest fibre start (how much of the area is left
without fibres):

=========== ========= ============= ================= =============== ===========
muscle      most      morph only    start -> origin   end -> insert.  origin gap
            outside   (no pull)     max / median      max / median    (before)
=========== ========= ============= ================= =============== ===========
glut_max_r  0.20      0.03          10.9 / 6.1        18.1 / 14.6     44.6 (58.4)
glut_med_r  0.20      1.50          12.8 / 6.8        9.2 / 5.7       15.8 (22.5)
iliacus_r   0.20      1.50          11.7 / 6.9        9.7 / 6.3       19.3 (19.3)
psoas_r     0.20      0.49          10.2 / 8.3        2.2 / 2.2       11.4 (11.1)
=========== ========= ============= ================= =============== ===========

Every fibre point is inside the surface or less than 0.2 mm outside it (before the pull: up
to 4.2 mm outside, 92-99.8 % within 1 mm: the straight reconstructed end segments and the
resampling chords of Kohout §3.4 cut the concave walls; smoothing without its bound added up
to 4 mm more). The "before" gaps are those of the paper's rays alone: the new ends now follow
the template's own direction where that ray meets the area (`fibres.attachments.filtering`, "Rays"),
which spreads gluteus medius' fibres over the left end of the iliac crest.

Original and clean meshes give the same numbers (the repair makes them identical).
"""
import functools
import warnings

import numpy as np
import pytest
from scipy.spatial import cKDTree

from fibres import as_surface, decompose

# these tests pin the planar method of Kohout et al. 2012 (tests/fibres/test_harmonic.py has the
# harmonic-field slicing on the same muscles)
decompose = functools.partial(decompose, slicing="planes")

MUSCLES = ("glut_max_r", "glut_med_r", "iliacus_r", "psoas_r")
# the measured values above (max, median) with ~20 % margin (the end points come from the
# attachment filter: a point of the area's surface on or nearest to each fibre's end ray)
START_MM = {"glut_max_r": (13.5, 7.5), "glut_med_r": (15.5, 8.5), "iliacus_r": (14.0, 8.0),
            "psoas_r": (12.5, 10.0)}
END_MM = {"glut_max_r": (22.0, 18.0), "glut_med_r": (11.5, 7.0), "iliacus_r": (11.5, 7.5),
          "psoas_r": (3.0, 3.0)}
# the largest origin landmark -> nearest fibre start distance, measured +~20 %
ORIGIN_GAP_MM = {"glut_max_r": 53.0, "glut_med_r": 19.0, "iliacus_r": 23.0, "psoas_r": 13.5}
# the containment pull leaves a point at most m = 0.2 mm outside (fibres.finishing.containment:
# s' = m (1 - exp(-s / m)) < m, by the exact point-triangle distance that VTK also uses;
# 0.05 mm for the soft blend over ties and rounding); the acceptance asks for 1 mm
OUTSIDE_MM = 0.25


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
                             filter_attachments=False, smoothing_iterations=0, contain=False)
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
    # the full chain, ending with the containment pull: every point inside or within 1 mm
    # (the acceptance), in fact within the pull's margin
    sd = _signed_distance_mm(surface, full.points)
    assert sd.min() >= -1.0
    assert sd.min() >= -OUTSIDE_MM
    # every fibre starts near its origin area and ends near its insertion area ...
    d_start = cKDTree(origin).query(full.points[:, 0])[0] * 1e3
    d_end = cKDTree(insertion).query(full.points[:, -1])[0] * 1e3
    assert d_start.max() <= START_MM[muscle][0] and np.median(d_start) <= START_MM[muscle][1]
    assert d_end.max() <= END_MM[muscle][0] and np.median(d_end) <= END_MM[muscle][1]
    # ... and far from the other one (the fibres run the right way round)
    assert (cKDTree(insertion).query(full.points[:, 0])[0] * 1e3).min() > 3 * START_MM[muscle][0]
    assert (cKDTree(origin).query(full.points[:, -1])[0] * 1e3).min() > 3 * END_MM[muscle][0]
    # the starts spread over the origin area: no landmark far from every fibre start
    assert cKDTree(full.points[:, 0]).query(origin)[0].max() * 1e3 <= ORIGIN_GAP_MM[muscle]


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
# Filter on now includes the containment pull (off for the morph-only runs, which measure the
# morph itself); glut_max 1.71 -> 2.23 came with the template-direction rays: fibre 11's
# longer insertion segment lengthens by 0.32 mm per 0.1 degree at 13-14 degrees, steadily
# (checked in 0.1-degree steps: 0.316-0.336 mm), not a jump.
# (with the box's reference oriented by the muscle's shape, not the vertex numbering,
# gluteus maximus takes the other of two boxes half a turn apart that score the same:
# morph only 1.09 -> 2.06, fibre 21 shortening steadily by 0.23-0.50 mm per 0.1 degree at
# 15-18 degrees (checked in 0.1-degree steps), not a jump; docs/decisions.md)
SWEEP_STEP_RATIO = {("glut_max_r", True): 2.7, ("glut_med_r", True): 4.6,
                    ("iliacus_r", True): 2.8, ("psoas_r", True): 5.5,
                    ("glut_max_r", False): 2.5, ("glut_med_r", False): 10.7,
                    ("iliacus_r", False): 20.6, ("psoas_r", False): 11.0}
# (with the continuous start/split points of fibres.slicing.correspondence: filter on 1.36, 1.43,
# 1.11, 4.53 (was 2.21, 1.48, 2.43, 4.72), off 1.09, 5.38, 16.2, 9.17 (was 1.12, 4.98,
# 14.5, 6.45); psoas off is the same event, plane 6's horn merging with its second loop
# at 2-3 degrees)
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
                      smoothing_iterations=5 if filt else 0, contain=filt)
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


# With the plan passed on to `fibres.slicing.morph.anchored_maps` (``plan=``; decompose does not
# pass it yet, so the test wires it), planes that cut one loop at rest follow their whole
# section through splits, merges and islands (`fibres.slicing.contours.bridge_loops`). Measured,
# morph only: step ratios 1.12, 4.98, 14.5, 6.45 (glut_med 8.9 -> 5.0, iliacus 17.8 ->
# 14.5 against the unwired path), h/2h agreement 1.0, 0.9995, 0.970, 1.0; bounds ~20 %
# above the step ratios.
# (with the continuous start/split points: iliacus 14.5 -> 16.2, psoas 6.45 -> 9.17; since
# decompose passes the plan itself these equal the morph-only ratios above)
# (gluteus maximus 2.06 with the other tied box, as above)
WIRED_STEP_RATIO = {"glut_max_r": 2.5, "glut_med_r": 6.0, "iliacus_r": 19.4, "psoas_r": 11.0}


@pytest.mark.parametrize("muscle", MUSCLES)
def test_lhdl_bend_sweep_with_the_whole_section(decomposed, muscle, monkeypatch):
    import functools
    import importlib

    from fibres.slicing.morph import anchored_maps

    surface, origin, insertion, _, core = decomposed[muscle, "muscles_clean"]
    monkeypatch.setattr(importlib.import_module("fibres.decompose"), "anchored_maps",
                        functools.partial(anchored_maps, plan=core.plan))
    v, f = np.asarray(surface.vertices), np.asarray(surface.faces)
    bend = _bender(origin, insertion)
    notes = set()

    def lengths(deg):
        b = decompose((bend(v, deg), f), bend(origin, deg), bend(insertion, deg),
                      plan=core.plan, n_fibres=100, resolution=15, filter_attachments=False,
                      smoothing_iterations=0, contain=False)
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


def _winding_numbers(v, f, points, chunk=64):
    """Generalised winding numbers of points about a closed mesh (van Oosterom & Strackee's
    solid angle of each triangle, summed / 4 pi): 1 inside, 0 outside, exactly."""
    out = []
    for a0 in range(0, len(points), chunk):
        p = points[a0:a0 + chunk, None, None]                      # (n, 1, 1, 3)
        a, b, c = (v[f][None, :, k] - p[:, 0] for k in range(3))   # (n, T, 3)
        la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
        num = np.einsum("ntk,ntk->nt", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("ntk,ntk->nt", a, b) * lc
               + np.einsum("ntk,ntk->nt", b, c) * la + np.einsum("ntk,ntk->nt", c, a) * lb)
        out.append(2 * np.arctan2(num, den).sum(axis=1) / (4 * np.pi))
    return np.concatenate(out)


def test_containment_inside_test_agrees_with_the_winding_number(decomposed):
    # the containment pull skips points deeper than its band that are inside by ray parity
    # (fibres.mesh.surface_distance.SurfaceGrid.inside). The sign of the blended distance (a
    # unit-weight normal vote) put inside points of the psoas bent by 10.2 degrees outside,
    # and the pull then skipped a fibre point 1.7 mm outside (a jump of its length between
    # 10.1 and 10.2 degrees): parity must match the winding number on a lattice through it
    from fibres.mesh.surface_distance import SurfaceGrid

    surface, origin, insertion, _, _ = decomposed["psoas_r", "muscles_clean"]
    v, f = np.asarray(surface.vertices), np.asarray(surface.faces)
    vb = _bender(origin, insertion)(v, 10.2)
    grid = SurfaceGrid(vb, f, reach=8e-3)
    lo, hi = vb.min(axis=0) - 2e-3, vb.max(axis=0) + 2e-3
    axes = [np.linspace(lo[k], hi[k], n) for k, n in enumerate((14, 14, 40))]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    wind = _winding_numbers(vb, f, pts)
    inside = grid.inside(pts)
    assert inside.sum() > 150 and (~inside).sum() > 1000
    np.testing.assert_array_equal(inside, wind > 0.5)
