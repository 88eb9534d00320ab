"""The compiled wrapping (`motion.wrapping.wrapped_rows` and the wrap lines `cylinder_line`,
`sphere_torus_line`, `ellipsoid_line`) against the numpy implementation of the same algorithm on
dual numbers (``tests/motion/wrap_oracle``), the oracle here.

Both run the same steps on the same numbers, so values agree to rounding: 1e-12 m on lengths,
tangent points and reported nodes (paths ~0.1-1 m, ~1e3 floating-point steps of 1e-16 relative
error), the current path's node order exactly. Derivatives: the complex-step derivative equals
the dual number's up to rounding (moment arms are 1e-3-1e-1 m: 1e-9 absolute on paths; on
random segments relative to 1 + |d|, see the bounds at the ends).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import warnings

import numpy as np
import pytest

from motion.osim.kinematics import body_pose_derivatives
from motion.osim.motion_file import load_motion
from motion.osim.reader import load_model
from motion.wrapping.action_lines import spanned_coordinates
from motion.wrapping.batch import _all_kinds, _signature, group_rows
from motion.wrapping.cylinder_line import STEP, wrap_line
from motion.wrapping.ellipsoid_line import ellipsoid_line, new_fan_memo
from motion.wrapping.path_points import path_points
from motion.wrapping.sphere_torus_line import sphere_line, torus_line
from motion.wrapping.cylinder_line import ELLIPSOID_METHODS, quadrant_axis_sign
from motion.wrapping.wrapped_rows import CYLINDER, wrap_compiled_rows

from wrap_oracle.cylinder import cylinder_wrap_line     # tests/motion (rootdir-relative import)
from wrap_oracle.dual import Dual
from wrap_oracle.ellipsoid import ellipsoid_wrap_line
from wrap_oracle.path import wrap_rows
from wrap_oracle.sphere import sphere_wrap_line
from wrap_oracle.torus import torus_wrap_line
from tests.conftest import ROOT

MODELS = [
    ("MomentArmTests/WrapPathCustomJointMomentArmTest.osim",
     "MomentArmTests/WrapPathCustomJointMomentArmTest_sweep.mot", 1),
    ("Arm26/arm26.osim", "Arm26/arm26_InverseKinematics.mot", 2),
    ("RajagopalLaiUhlrich2023/RajagopalLaiUhlrich2023.osim", "RajagopalLaiUhlrich2023/walk_from_gait2392.mot", 3),
]


def _groups(opensim_dir, model_rel, motion_rel, step):
    """Every group of wrapped paths of a model, as `wrap_paths` forms them."""
    model = load_model(opensim_dir / model_rel)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        q = load_motion(opensim_dir / motion_rel, model).q[::step]
    tf, dtf, q_used, jac = body_pose_derivatives(model, q)
    groups = {}
    for path in model.paths:
        if path.wraps:
            groups.setdefault(_signature(model, path), []).append(path)
    out = []
    for paths in groups.values():
        pps = [path_points(p, model, q_used, tf, jac=jac, d_tf_ground_body=dtf) for p in paths]
        cols = [np.flatnonzero(spanned_coordinates(model, p)) for p in paths]
        out.append(group_rows(paths, model, [pp.points for pp in pps], [pp.active for pp in pps],
                              [pp.d_points for pp in pps], tf, dtf, cols))
    return out


@pytest.mark.parametrize("model_rel, motion_rel, step", MODELS, ids=["wrap-pin", "arm26", "rajagopal"])
def test_rows_equal_numpy(opensim_dir, model_rel, motion_rel, step):
    groups = _groups(opensim_dir, model_rel, motion_rel, step)
    assert groups, "the model must have wrapped paths"
    for pts, act, dpts, n_dirs, slots in groups:
        length, d_length, order, mask, seen, arc, _ = wrap_compiled_rows(pts, act, dpts, n_dirs, slots)
        ref_len, ref_order, ref_mask, ref_seen, ref_arcs = wrap_rows(pts, act, dpts, slots)
        ref_d = np.broadcast_to(ref_len.d, d_length.shape)
        assert np.array_equal(order, ref_order)
        assert np.array_equal(mask, ref_mask)
        np.testing.assert_allclose(length, ref_len.v, rtol=0, atol=1e-12)
        np.testing.assert_allclose(d_length, ref_d, rtol=0, atol=1e-9)
        ref_pts = np.stack([n.v for n in ref_seen], axis=1)
        np.testing.assert_allclose(np.where(mask[..., None], seen, 0.0), np.where(mask[..., None], ref_pts, 0.0),
                                   rtol=0, atol=1e-12)
        n_points = pts.shape[1]
        for w, ref in enumerate(ref_arcs):
            np.testing.assert_allclose(arc[:, w], np.where(mask[:, n_points + 2 * w], ref.v, 0.0), rtol=0, atol=1e-12)


@pytest.mark.parametrize("model_rel, motion_rel, step", MODELS[:2], ids=["wrap-pin", "arm26"])
def test_cylinder_variant_equals_all_kinds(opensim_dir, model_rel, motion_rel, step):
    """The kernel compiled for cylinders only and the one for every kind run the same
    cylinder code on the same numbers: equal to rounding (1e-14 m, the values ~0.1-1 m)."""
    model = load_model(opensim_dir / model_rel)
    assert _all_kinds(model) == (model_rel.startswith("Arm26"))     # Arm26 has ellipsoids
    checked = 0
    for pts, act, dpts, n_dirs, slots in _groups(opensim_dir, model_rel, motion_rel, step):
        if any(s.kind != CYLINDER for s in slots):
            with pytest.raises(ValueError, match="no cylinder"):
                wrap_compiled_rows(pts, act, dpts, n_dirs, slots, all_kinds=False)
            continue
        cyl = wrap_compiled_rows(pts, act, dpts, n_dirs, slots, all_kinds=False)
        every = wrap_compiled_rows(pts, act, dpts, n_dirs, slots, all_kinds=True)
        for a, b in zip(cyl, every):
            if a.dtype.kind in "bi":
                assert np.array_equal(a, b)
            else:
                np.testing.assert_allclose(a, b, rtol=0, atol=1e-14)
        checked += 1
    assert checked


_ONLY_CYLINDERS = r"""
import json, sys, numpy as np, motion
from motion.osim.kinematics import body_pose_derivatives
from motion.wrapping import wrapped_rows
from motion.wrapping.batch import wrap_path
from motion.wrapping.path_points import path_points
model = motion.load_model(sys.argv[1])
mot = motion.load_motion(sys.argv[2], model)
motion.action_lines(model, mot)                                   # wrap_paths
tf, dtf, q, jac = body_pose_derivatives(model, mot.q[:3])
for path in model.paths:                                          # wrap_path (the surfaces' call)
    if path.wraps:
        pp = path_points(path, model, q, tf, jac=jac, d_tf_ground_body=dtf)
        wrap_path(path, model, pp.points, pp.active, pp.d_points, tf, dtf)
print(json.dumps([str(s[8]) for s in wrapped_rows._rows_kernel.signatures]))   # the type of wkind
"""


def test_a_cylinder_model_runs_only_the_cylinder_kernel():
    """The bundled example (one WrapCylinder): in a fresh process its action lines and its
    surfaces' wrapped paths (`wrap_path`) run only the kernel variant typed with ``wkind`` None,
    whose `_line` is the cylinder's alone (the other kinds' functions are not compiled for it)."""
    example = ROOT / "models" / "arm_example.osim"
    if not example.exists():
        pytest.skip("bundled example model not generated")
    mot = ROOT / "models" / "elbow_flexion.mot"
    out = subprocess.run([sys.executable, "-c", _ONLY_CYLINDERS, str(example), str(mot)],
                         cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT)), capture_output=True, text=True,
                         check=True)
    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert res == ["none"]


@pytest.mark.parametrize("quadrant", ["all", "x", "-x", "y", "-y"])
@pytest.mark.parametrize("adjust", [False, True])
def test_wrap_line_equals_numpy(quadrant, adjust):
    """Random segments around a cylinder (radius 0.03, length 0.2), every code, both variants:
    codes equal, tangent points and arc to 1e-12 m, derivatives along a random direction
    relative to 1 + |d| (see the bound at the end)."""
    rng = np.random.default_rng(7)
    n = 400
    p1 = rng.uniform(-0.12, 0.12, (n, 3))
    p2 = rng.uniform(-0.12, 0.12, (n, 3))
    dp1, dp2 = rng.normal(size=(n, 3, 1)), rng.normal(size=(n, 3, 1))
    with np.errstate(all="ignore"):       # segments that do not wrap compute NaN tangents
        code, r1, r2, arc = cylinder_wrap_line(Dual(p1, dp1), Dual(p2, dp2), radius=0.03, length=0.2,
                                               quadrant=quadrant, adjust_tangents=adjust)
    axis, sign = quadrant_axis_sign(quadrant)
    seen_codes = set()
    worst = 0.0
    for i in range(n):
        a = tuple(complex(p1[i, k], STEP * dp1[i, k, 0]) for k in range(3))
        b = tuple(complex(p2[i, k], STEP * dp2[i, k, 0]) for k in range(3))
        c, s1, s2, s_arc = wrap_line(a, b, 0.03, 0.2, axis, sign, adjust)
        assert c == code[i]
        seen_codes.add(c)
        if c >= 2:
            got = np.array([[x.real for x in s1], [x.real for x in s2]])
            np.testing.assert_allclose(got, np.stack([r1.v[i], r2.v[i]]), rtol=0, atol=1e-12)
            d_got = np.array([[x.imag / STEP for x in s1], [x.imag / STEP for x in s2], [s_arc.imag / STEP] * 3])
            d_ref = np.stack([r1.d[i, :, 0], r2.d[i, :, 0], [arc.d[i, 0]] * 3])
            worst = max(worst, float(np.max(np.abs(d_got - d_ref) / (1.0 + np.abs(d_ref)))))
            assert abs(s_arc.real - arc.v[i]) < 1e-12
    assert {0, 1, 3} <= seen_codes
    # relative to 1 + |d|: rounding alone without the re-adjustment; with it, up to 100 slides
    # of 1.5x amplify rounding on near-degenerate random segments (derivatives of order 1e6)
    assert worst < (1e-4 if adjust else 1e-12)


def _compare_lines(compiled, oracle, p1, p2, dp1, dp2, d_bound):
    """Codes equal; tangent points and arcs (where wrapped) to 1e-12; derivatives along the
    random direction relative to 1 + |d| below ``d_bound``; returns the codes seen."""
    with np.errstate(all="ignore"):       # segments that do not wrap compute NaN tangents
        code, r1, r2, arc = oracle(Dual(p1, dp1), Dual(p2, dp2))
    seen_codes = set()
    worst = 0.0
    for i in range(len(p1)):
        a = tuple(complex(p1[i, k], STEP * dp1[i, k, 0]) for k in range(3))
        b = tuple(complex(p2[i, k], STEP * dp2[i, k, 0]) for k in range(3))
        c, s1, s2, s_arc = compiled(a, b)
        assert c == code[i], f"segment {i}"
        seen_codes.add(c)
        if c >= 2:
            got = np.array([[x.real for x in s1], [x.real for x in s2]])
            np.testing.assert_allclose(got, np.stack([r1.v[i], r2.v[i]]), rtol=0, atol=1e-12)
            np.testing.assert_allclose(s_arc.real, arc.v[i], rtol=0, atol=1e-12)   # NaN (degenerate) alike
            d_got = np.array([[x.imag / STEP for x in s1], [x.imag / STEP for x in s2], [s_arc.imag / STEP] * 3])
            d_ref = np.stack([r1.d[i, :, 0], r2.d[i, :, 0], [arc.d[i, 0]] * 3])
            assert np.array_equal(np.isnan(d_got), np.isnan(d_ref))
            if np.isfinite(d_ref).any():
                worst = max(worst, float(np.nanmax(np.abs(d_got - d_ref) / (1.0 + np.abs(d_ref)))))
    assert worst < d_bound
    return seen_codes


def _segments(seed, n, half):
    rng = np.random.default_rng(seed)
    return (rng.uniform(-half, half, (n, 3)), rng.uniform(-half, half, (n, 3)),
            rng.normal(size=(n, 3, 1)), rng.normal(size=(n, 3, 1)))


@pytest.mark.parametrize("quadrant", ["all", "x", "-y", "z"])
def test_sphere_line_equals_numpy(quadrant):
    """Random segments around a sphere of radius 0.04: every code; derivatives to rounding."""
    axis, sign = quadrant_axis_sign(quadrant)
    codes = _compare_lines(lambda a, b: sphere_line(a, b, 0.04, axis, sign),
                           lambda a, b: sphere_wrap_line(a, b, radius=0.04, quadrant=quadrant),
                           *_segments(11, 400, 0.12), d_bound=1e-10)
    assert {0, 1} <= codes and codes & {2, 3}


@pytest.mark.parametrize("method", ELLIPSOID_METHODS)
@pytest.mark.parametrize("quadrant", ["all", "-y", "z"])
def test_ellipsoid_line_equals_numpy(method, quadrant):
    """Random segments around an ellipsoid (0.03, 0.02, 0.05): every code; derivatives to
    rounding, amplified by up to 50 Gauss-Newton steps with damped 4 x 4 solves (relative 1e-9)."""
    axis, sign = quadrant_axis_sign(quadrant)
    m = ELLIPSOID_METHODS.index(method)
    dims = np.array([0.03, 0.02, 0.05])
    memo = new_fan_memo()
    codes = _compare_lines(lambda a, b: ellipsoid_line(a, b, 0.03, 0.02, 0.05, axis, sign, m, *memo),
                           lambda a, b: ellipsoid_wrap_line(a, b, dimensions=dims, quadrant=quadrant, method=method),
                           *_segments(5, 150, 0.1), d_bound=1e-9)
    assert {0, 1, 3} <= codes


def test_ellipsoid_fan_on_a_coordinate_plane_and_from_its_memo():
    """The hybrid fan where every chord sample lies on the plane y = 0 (segments with y = 0 at both
    ends: `closest_point`'s 2-D case, whose Jacobian the fan takes by complex steps) equals the
    oracle as the random segments do; and a second direction on the same segment, answered from
    the memo, gives what a fresh memo computes (the same operations: equal to the last bit)."""
    dims = np.array([0.03, 0.02, 0.05])
    p1, p2, dp1, dp2 = _segments(7, 150, 0.1)
    p1[:, 1] = 0.0
    p2[:, 1] = 0.0
    memo = new_fan_memo()
    codes = _compare_lines(lambda a, b: ellipsoid_line(a, b, 0.03, 0.02, 0.05, -1, 0, 0, *memo),
                           lambda a, b: ellipsoid_wrap_line(a, b, dimensions=dims, quadrant="all", method="hybrid"),
                           p1, p2, dp1, dp2, d_bound=1e-9)
    assert 3 in codes
    rng = np.random.default_rng(8)
    hits = 0
    for i in range(len(p1)):
        a = tuple(complex(p1[i, k], STEP * dp1[i, k, 0]) for k in range(3))
        b = tuple(complex(p2[i, k], STEP * dp2[i, k, 0]) for k in range(3))
        first = ellipsoid_line(a, b, 0.03, 0.02, 0.05, -1, 0, 0, *memo)
        if first[0] != 3:
            continue
        d = rng.normal(size=6)
        a2 = tuple(complex(p1[i, k], STEP * d[k]) for k in range(3))
        b2 = tuple(complex(p2[i, k], STEP * d[3 + k]) for k in range(3))
        count = memo[1][0]
        again = ellipsoid_line(a2, b2, 0.03, 0.02, 0.05, -1, 0, 0, *memo)
        hits += memo[1][0] == count          # answered from the memo: nothing stored
        fresh = ellipsoid_line(a2, b2, 0.03, 0.02, 0.05, -1, 0, 0, *new_fan_memo())
        assert again[0] == fresh[0]
        for got, ref in zip(again[1] + again[2] + (again[3],), fresh[1] + fresh[2] + (fresh[3],)):
            assert got == ref or (np.isnan(got.real) and np.isnan(ref.real))
    assert hits > 0


@pytest.mark.parametrize("quadrant", ["all", "x", "-z"])
def test_torus_line_equals_numpy(quadrant):
    """Random segments around a torus (inner 0.02, outer 0.06): both codes; derivatives as the
    cylinder's with its tangent re-adjustment (relative 1e-4, see `test_wrap_line_equals_numpy`)."""
    axis, sign = quadrant_axis_sign(quadrant)
    codes = _compare_lines(lambda a, b: torus_line(a, b, 0.02, 0.06, axis, sign),
                           lambda a, b: torus_wrap_line(a, b, inner_radius=0.02, outer_radius=0.06, quadrant=quadrant),
                           *_segments(3, 300, 0.12), d_bound=1e-4)
    assert {0, 2} <= codes
