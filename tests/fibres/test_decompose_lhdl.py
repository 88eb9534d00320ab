"""The four LHDL hip muscles (Modenese & Kohout 2020 data set) into 100 fibres x 15 segments.

Landmarks: ``attachments/attachment_landmarks.csv``. Gluteus maximus insertion cloud 2 (the
iliotibial tract on the tibia, ~310 mm from the muscle mesh) is left out: the surface does
not reach it. The psoas origins lie on lumbar vertebrae missing from the data set, 5-10 mm
from the muscle; they are used as given (they still define the axis and the trimming
plane; reconstructed ends land on the surface nearest to them).

Measured with this code (mm), full chain (attachment filter + 5 smoothing steps) / morph only:

=========== ===================== ================= ================= ==================
muscle      most outside, full    most outside,     start -> origin   end -> insertion
            chain                 morph only        landmark (max)    landmark (max)
=========== ===================== ================= ================= ==================
glut_max_r  3.6                   0.34              10.9              18.1
glut_med_r  4.9                   1.50              12.8              9.3
iliacus_r   4.2                   1.50              11.7              10.6
psoas_r     8.1                   0.49              10.2              2.6
=========== ===================== ================= ================= ==================

Original and clean meshes give the same numbers (the repair makes them identical).
"""
import warnings

import numpy as np
import pytest
from scipy.spatial import cKDTree

from fibres import as_surface, decompose

MUSCLES = ("glut_max_r", "glut_med_r", "iliacus_r", "psoas_r")
# the measured worst values above with ~20 % margin (the end points come from the
# attachment filter, whose surface regions are sampled at mesh vertices)
START_MM = {"glut_max_r": 13.0, "glut_med_r": 15.5, "iliacus_r": 14.0, "psoas_r": 12.5}
END_MM = {"glut_max_r": 22.0, "glut_med_r": 11.5, "iliacus_r": 13.0, "psoas_r": 3.5}
# full chain: at most 10 mm outside (measured 3.6-8.1 mm: filter + smoothing, see above)
FULL_OUTSIDE_MM = 10.0


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
    # the full chain: trimming + straight reconstruction + smoothing cut the concave
    # walls of curved muscles (psoas around the pelvic brim): pinned at the measured values
    sd = _signed_distance_mm(surface, full.points)
    assert sd.min() >= -FULL_OUTSIDE_MM
    assert np.mean(sd >= -1.0) >= 0.75
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
