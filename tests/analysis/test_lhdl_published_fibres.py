"""The LHDL hip fibres' flexion moment arms against published finite-element results.

Blemker & Delp, "Three-dimensional representation of complex muscle architectures and
geometries", Ann. Biomed. Eng. 33:661-673 (2005), modelled psoas, iliacus and the glutei as
finite-element muscles; Modenese & Kohout 2020 (Ann. Biomed. Eng. 48:1793-1804, Table 2) digitised
the peaks of their fibres' hip flexion moment arms. Theirs is another subject and another method,
so the check is one of plausibility, with the tolerance Modenese & Kohout's own fibres meet: the
overlap (intersection over union) of our fibres' min..max over the dataset's flexion motion with
Blemker & Delp's peaks is at least 0.4 (Modenese & Kohout's: 0.43-0.71; ours 0.46-0.87), and our
mean lies within their peaks (ours: 2.1, 3.0, -5.0 and -1.4 cm for psoas, iliacus, gluteus
maximus and medius).
"""
from __future__ import annotations

from pathlib import Path

import pytest

TOML = Path(__file__).resolve().parents[1] / "data" / "lhdl_hip.toml"
#: Blemker & Delp 2005 via Modenese & Kohout 2020, Table 2: hip flexion moment arm peaks (cm)
BLEMKER_FLEXION_CM = {"psoas_r": (1.7, 3.0), "iliacus_r": (1.9, 5.1),
                      "glut_max_r": (-7.2, -0.9), "glut_med_r": (-1.7, 2.1)}


@pytest.fixture(scope="module")
def flexion(lhdl_dir):
    from analysis.run import run

    return run(TOML, lhdl_dir / "model" / "motions" / "hip_flexion.mot", keep_points=False)


@pytest.mark.parametrize("muscle", sorted(BLEMKER_FLEXION_CM))
def test_flexion_moment_arms_overlap_the_finite_element_muscles(flexion, muscle):
    m = flexion.muscle(muscle)
    r = m.fibre_moment_arms[:, :, m.coordinates.index("hip_flexion_r")] * 100.0   # cm
    lo, hi = BLEMKER_FLEXION_CM[muscle]
    inter = max(0.0, min(r.max(), hi) - max(r.min(), lo))
    union = max(r.max(), hi) - min(r.min(), lo)
    assert inter / union >= 0.4, f"{muscle}: {r.min():.2f}..{r.max():.2f} cm against {lo}..{hi}"
    assert lo <= r.mean() <= hi
