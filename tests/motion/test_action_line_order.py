"""ActionLines.ordered_points is the current path in path order: its polyline length is the path length.

Where a path wraps, the straight segments plus the wrap arcs make the length, so for wrapped paths the
ordered polyline through the tangent points is shorter than the path by exactly the arc lengths (each
arc is longer than its chord) and longer than the straight line between the end points; for unwrapped
paths it is the path length to rounding.
"""
import numpy as np
import pytest

import motion
from tests.conftest import ROOT

EXAMPLE = ROOT / "models" / "arm_example.osim"


@pytest.fixture(scope="module")
def lines():
    if not EXAMPLE.exists():
        pytest.skip("bundled example model not generated")
    model = motion.load_model(EXAMPLE)
    mot = motion.load_motion(ROOT / "models" / "elbow_flexion.mot", model)
    return motion.action_lines(model, mot)


def _polyline_lengths(lines, m):
    pts = lines.ordered_points[:, m]
    seg = np.linalg.norm(np.diff(pts, axis=1), axis=-1)
    return np.nansum(seg, axis=1)


def test_unwrapped_paths_polyline_is_the_length(lines):
    for m, name in enumerate(lines.muscle_names):
        if not any(":" in lab for lab in lines.point_labels[m]):
            np.testing.assert_allclose(_polyline_lengths(lines, m), lines.lengths[:, m], rtol=0, atol=1e-12)


def test_wrapped_paths_are_in_path_order(lines):
    checked = 0
    for m, name in enumerate(lines.muscle_names):
        labels = lines.point_labels[m]
        if not any(":" in lab for lab in labels):
            continue
        for f, path in enumerate(lines.polyline(name)):
            n_active = int(lines.point_mask[f, m].sum())
            assert len(path) == n_active
            chord = np.linalg.norm(path[-1] - path[0])
            poly = np.linalg.norm(np.diff(path, axis=0), axis=1).sum()
            # the first and last current points are the path's own end points
            order = lines.point_order[f, m]
            assert ":" not in labels[order[0]] and ":" not in labels[order[n_active - 1]]
            # tangent points, when present, sit between the end points and come as :1 then :2
            tangent = [labels[i] for i in order[:n_active] if ":" in labels[i]]
            if tangent:
                wrap = tangent[0].split(":")[0]
                assert tangent == [wrap + ":1", wrap + ":2"]
            assert chord - 1e-12 <= poly <= lines.lengths[f, m] + 1e-12
            checked += 1
    assert checked > 0
