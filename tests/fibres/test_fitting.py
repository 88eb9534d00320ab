"""fibres.fit.fitting: principal axis and OBB fit after Kohout 2012 §3.2."""
import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from fibres.errors import InputError
from fibres.fit.fitting import Box, fit_box, principal_frame
from fibres.template.templates import get_template

# an asymmetric template whose two area centroids lie on one z line (so the attachment axis is
# the box's z axis): off-centre rectangles of the parallel template
TM = get_template("parallel", origin_size=(0.4, 0.4), insertion_size=(0.4, 0.4),
                  origin_centre=(0.3, 0.4), insertion_centre=(0.3, 0.4))
EXT = np.array([0.04, 0.06, 0.2])


def _true_box(theta_deg, centre=np.array([0.1, -0.2, 0.3]), z_dir=(1.0, 2.0, 0.5)):
    u = np.asarray(z_dir, float) / np.linalg.norm(z_dir)
    # the reference frame fit_box derives for this axis (independent of the attachments)
    ref = np.eye(3)[int(np.argmin(np.abs(u)))]
    v0 = ref - (ref @ u) * u
    v0 /= np.linalg.norm(v0)
    w0 = np.cross(u, v0)
    th = np.deg2rad(theta_deg)
    x = np.cos(th) * v0 + np.sin(th) * w0
    axes = np.stack([x, np.cross(u, x), u], axis=1)
    corner = centre - axes @ (EXT / 2)
    return Box(corner, axes, EXT, 0)


def _box_mesh(box):
    m = trimesh.creation.box(bounds=[[0, 0, 0], [1, 1, 1]])
    return box.to_world(np.asarray(m.vertices))


@pytest.mark.parametrize("theta", [0.0, 35.0, 180.0, 275.0])
def test_recovers_a_known_box(theta):
    true = _true_box(theta)
    v = _box_mesh(true)
    o = true.to_world(TM.origin_area)
    i = true.to_world(TM.insertion_area)
    box = fit_box(v, o, i, TM)
    assert box.angle_index == round(theta / 5.0) % 72
    np.testing.assert_allclose(box.axes, true.axes, atol=1e-12)
    np.testing.assert_allclose(box.extents, EXT, atol=1e-12)
    np.testing.assert_allclose(box.corner, true.corner, atol=1e-12)
    assert box.scores[box.angle_index] == pytest.approx(0.0, abs=1e-12)
    assert box.method == "attachments"
    # round trip of the maps
    p = np.random.default_rng(0).random((10, 3))
    np.testing.assert_allclose(box.to_unit(box.to_world(p)), p, atol=1e-12)


def test_rigid_motion_equivariance_exact_with_reference():
    true = _true_box(35.0)
    v, o, i = _box_mesh(true), true.to_world(TM.origin_area), true.to_world(TM.insertion_area)
    # a lumpy non-box surface: perturb radially so the minimal boxes differ per angle
    rng = np.random.default_rng(3)
    v = np.vstack([v, true.to_world(rng.random((200, 3)))])
    b1 = fit_box(v, o, i, TM, v_ref=[1.0, 0.0, 0.0])
    rot = Rotation.from_euler("xyz", [20, -50, 110], degrees=True).as_matrix()
    shift = np.array([1.0, 2.0, -3.0])
    move = lambda p: p @ rot.T + shift  # noqa: E731
    b2 = fit_box(move(v), move(o), move(i), TM, v_ref=rot @ [1.0, 0.0, 0.0])
    assert b2.angle_index == b1.angle_index
    np.testing.assert_allclose(b2.axes, rot @ b1.axes, atol=1e-10)
    np.testing.assert_allclose(b2.corner, move(b1.corner), atol=1e-10)
    np.testing.assert_allclose(b2.extents, b1.extents, atol=1e-12)


def test_rotation_off_the_grid_costs_at_most_the_half_step():
    # true box 2.5 deg off the 5-degree grid: the fitted frame is within 2.5 deg, and each
    # cross-section extent grows by at most a(cos d - 1) + b sin d <= b sin(2.5 deg)
    true = _true_box(37.5)
    v, o, i = _box_mesh(true), true.to_world(TM.origin_area), true.to_world(TM.insertion_area)
    box = fit_box(v, o, i, TM)
    cosang = np.clip(box.axes[:, 0] @ true.axes[:, 0], -1, 1)
    assert np.rad2deg(np.arccos(cosang)) <= 2.5 + 1e-9
    bound = EXT[[1, 0]] * np.sin(np.deg2rad(2.5)) + 1e-12
    assert (box.extents[:2] - EXT[:2] <= bound).all() and (box.extents[:2] >= EXT[:2] - 1e-12).all()


def _ellipsoid(radii, rot):
    m = trimesh.creation.icosphere(subdivisions=3)
    return (np.asarray(m.vertices) * radii) @ rot.T


def test_covariance_fallback_when_attachments_are_close():
    rot = Rotation.from_euler("zyx", [30, 20, -10], degrees=True).as_matrix()
    v = _ellipsoid(np.array([0.02, 0.03, 0.15]), rot)
    long_axis = rot[:, 2]
    side = rot[:, 0] * 0.02
    # both attachments on the same side, 2 mm apart along the long axis: centroids too close
    o = side + 0.0 * long_axis
    i = side + 0.002 * long_axis + 0.001 * rot[:, 1]
    f = principal_frame(v, [o], [i], axis="auto")
    assert f.method == "covariance"
    # icosphere vertices are symmetric under the coordinate reflections, so the covariance is
    # diagonal in the ellipsoid frame and its main eigenvector is the long axis exactly
    np.testing.assert_allclose(f.axis, long_axis, atol=1e-9)  # oriented origin -> insertion
    f2 = principal_frame(v, [i], [o], axis="covariance")
    np.testing.assert_allclose(f2.axis, -long_axis, atol=1e-9)
    fa = principal_frame(v, [o], [i], axis="attachments")
    np.testing.assert_allclose(fa.axis, (i - o) / np.linalg.norm(i - o), atol=1e-12)
    # frame is orthonormal and right-handed
    m = np.stack([f.v0, f.w0, f.axis], axis=1)
    np.testing.assert_allclose(m.T @ m, np.eye(3), atol=1e-12)
    assert np.linalg.det(m) == pytest.approx(1.0)
    # far-apart attachments: auto uses them
    fe = principal_frame(v, [-0.15 * long_axis], [0.15 * long_axis + side], axis="auto")
    assert fe.method == "attachments"


def test_bad_landmarks():
    true = _true_box(0.0)
    v = _box_mesh(true)
    o, i = true.to_world(TM.origin_area), true.to_world(TM.insertion_area)
    with pytest.raises(InputError, match="origin landmark set is empty"):
        fit_box(v, np.zeros((0, 3)), i, TM)
    with pytest.raises(InputError, match="same centroid"):
        fit_box(v, o, o, TM)
    with pytest.raises(InputError, match="NaN"):
        fit_box(v, o, np.full((2, 3), np.nan), TM)
    # surface in mm read as metres; landmarks in metres -> unit mistake named
    with pytest.raises(InputError, match="millimetres") as err:
        fit_box(v * 1000, o, i, TM)
    assert "same units" in str(err.value)
    with pytest.raises(InputError, match="millimetres"):
        fit_box(v, o * 1000, i * 1000, TM)
    with pytest.raises(InputError, match="lie"):
        fit_box(v, o + 100.0, i, TM)


def test_lhdl_landmarks_are_accepted(lhdl_dir):
    # real data: gluteus maximus insertion 2 lies ~310 mm off the muscle (README) and must pass
    import pandas as pd

    from fibres.mesh.surface import as_surface

    s = as_surface(lhdl_dir / "muscles_clean" / "glut_max_r.vtk", units="mm")
    tab = pd.read_csv(lhdl_dir / "attachments" / "attachment_landmarks.csv")
    sel = tab[tab.muscle == "glut_max_r"]
    pts = lambda kind: sel[sel.type == kind][["x_mm", "y_mm", "z_mm"]].to_numpy() / 1000  # noqa
    box = fit_box(s.vertices, pts("origin"), pts("insertion"), "parallel")
    # every vertex inside the fitted box (it is a bounding box)
    unit = box.to_unit(s.vertices)
    assert unit.min() > -1e-9 and unit.max() < 1 + 1e-9
    assert box.scores.shape == (72,)


@pytest.mark.parametrize("theta", [0.0, 35.0])
def test_oblique_template_recovers_the_box(theta):
    # pennate: the attachment centroids are offset across the box (0.5 of its width), so the
    # landmark direction is NOT the box axis; the fixed-point correction must recover it
    pen = get_template("pennate")
    true = _true_box(theta)
    v = _box_mesh(true)
    o, i = true.to_world(pen.origin_area), true.to_world(pen.insertion_area)
    d = i.mean(axis=0) - o.mean(axis=0)
    assert np.degrees(np.arccos(d @ true.axes[:, 2] / np.linalg.norm(d))) > 5  # truly oblique
    box = fit_box(v, o, i, pen)
    # the iteration stops when the axis moves < 1e-12; geometric convergence -> ~1e-11 slack
    np.testing.assert_allclose(box.axes, true.axes, atol=1e-9)
    np.testing.assert_allclose(box.extents, EXT, atol=1e-9)
    np.testing.assert_allclose(box.corner, true.corner, atol=1e-9)
    # re-deriving the frame at the found rotation gives the same axis (what a plan does)
    f = principal_frame(v, o, i, template=pen, angle_index=box.angle_index)
    np.testing.assert_allclose(f.axis, box.axes[:, 2], atol=1e-9)


SHAPES = ["disc", "ellipse", "square", "duplicates", "line", "blob", "polygon", "circle",
          "crescent", "few", "spindle"]


def _shape_points(shape, rng, n=5000):
    t = rng.uniform(0, 2 * np.pi, n)
    r = np.sqrt(rng.uniform(0, 1, n))
    if shape == "polygon":  # many points exactly on the edges of a hexagon (collinear runs)
        k = rng.integers(0, 6, n)
        s = rng.uniform(0, 1, n)
        c0, c1 = np.exp(2j * np.pi * k / 6), np.exp(2j * np.pi * (k + 1) / 6)
        z = c0 + s * (c1 - c0)
        return z.real, z.imag
    if shape == "crescent":  # a thin arc: its mean lies outside the hull's interior band
        a = rng.uniform(0, np.pi, n)
        rr = 1 + 0.01 * rng.uniform(0, 1, n)
        return rr * np.cos(a) + 0.3, rr * np.sin(a) - 0.2
    if shape == "spindle":  # vertices of a bent, twisted tube seen along its axis
        v, _, _ = _bent_spindle(n_z=40, n_t=60)
        return v[:, 0], v[:, 1]
    return {
        "disc": (r * np.cos(t), r * np.sin(t)),
        "ellipse": (0.03 * np.cos(t), 0.01 * np.sin(t)),           # all on the boundary
        "square": (np.round(rng.uniform(-1, 1, n), 1), np.round(rng.uniform(-1, 1, n), 1)),
        "duplicates": (np.repeat(np.cos(t[:50]), 100), np.repeat(np.sin(t[:50]), 100)),
        "line": (np.linspace(-1, 1, n), 0.5 * np.linspace(-1, 1, n)),
        "blob": (rng.normal(size=n) * 0.02 + 0.1, rng.normal(size=n) * 0.05 - 0.3),
        "circle": (np.cos(np.arange(n) * 2 * np.pi / n), np.sin(np.arange(n) * 2 * np.pi / n)),
        "few": (rng.normal(size=5), rng.normal(size=5)),
    }[shape]


@pytest.mark.parametrize("shape", SHAPES)
def test_support_screen_keeps_every_extreme_point(shape):
    # the screened box search must give bit-identical boxes: every vertex that attains a
    # minimum or maximum of some projection survives the screen (brute force over all)
    from fibres.fit.fitting import _boxes, _support_candidates, _thetas

    rng = np.random.default_rng(3)
    a, b = _shape_points(shape, rng)
    n = a.size
    keep = _support_candidates(a, b)
    assert np.all(np.diff(keep) > 0)
    theta = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    for c_off in (np.zeros(2), np.array([a.mean(), b.mean()])):   # as given, centred
        aa, bb = a - c_off[0], b - c_off[1]
        keep = _support_candidates(aa, bb)
        px = np.cos(theta)[:, None] * aa + np.sin(theta)[:, None] * bb
        extreme = np.union1d(np.flatnonzero((px == px.min(axis=1, keepdims=True)).any(axis=0)),
                             np.flatnonzero((px == px.max(axis=1, keepdims=True)).any(axis=0)))
        assert np.isin(extreme, keep).all()
        if shape in ("disc", "blob", "spindle"):
            assert keep.size < n / 5                   # the screen does drop the interior
    # the boxes equal the unscreened search exactly
    v = np.c_[a, b, rng.uniform(0, 0.2, n)]
    c, u, v0, w0 = v.mean(axis=0), np.eye(3)[2], np.eye(3)[0], np.eye(3)[1]
    axes, corner, ext = _boxes(v, c, u, v0, w0, _thetas(5.0))
    d = v - c
    th = _thetas(5.0)
    da, db = [(d[:, 0] * e[0] + d[:, 1] * e[1]) + d[:, 2] * e[2] for e in (v0, w0)]
    pa = np.cos(th)[:, None] * da + np.sin(th)[:, None] * db
    pb = -np.sin(th)[:, None] * da + np.cos(th)[:, None] * db
    np.testing.assert_array_equal(ext[:, 0], pa.max(axis=1) - pa.min(axis=1))
    np.testing.assert_array_equal(ext[:, 1], pb.max(axis=1) - pb.min(axis=1))




def _bent_spindle(n_z=24, n_t=32, length=0.2):
    """Closed spindle (elliptic sections, twisted, bowed to +x) and two rings of 8 landmarks
    around its tips: the landmarks are symmetric about the tip line (the z axis), so the
    pennate template's first rotation search has two exactly tied rotations 180 degrees apart."""
    u = np.linspace(0.0, 1.0, n_z + 2)[1:-1]
    th = np.linspace(0.0, 2 * np.pi, n_t, endpoint=False)
    r = 0.02 * np.sin(np.pi * u) ** 0.8 + 0.002
    a, b = r[:, None] * 1.4 * np.cos(th), r[:, None] * 0.8 * np.sin(th)
    tw = 0.6 * u[:, None]
    x = np.cos(tw) * a - np.sin(tw) * b + 0.02 * np.sin(np.pi * u)[:, None]
    y = np.sin(tw) * a + np.cos(tw) * b
    z = np.broadcast_to(length * (u - 0.5)[:, None], x.shape)
    v = np.vstack([np.stack([x, y, z], -1).reshape(-1, 3), [0, 0, -length / 2],
                   [0, 0, length / 2]])
    ring = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    spread = 0.004 * np.c_[np.cos(ring), np.sin(ring), np.zeros(8)]
    return v, v[-2] + spread + [0, 0, 0.004], v[-1] + spread - [0, 0, 0.004]


def test_pennate_tie_is_broken_by_the_shape_not_by_rounding():
    # Rotations within ROTATION_TIE of the best score are tied and broken towards the
    # muscle's bulk (module docstring). Without the rule the rounding of the two equal scores
    # (~1e-16 apart) chose the side: a rigid motion flipped the axis by ~2 x 11 degrees.
    v, o, i = _bent_spindle()
    ref = np.array([1.0, 0.3, 0.1])
    frame = principal_frame(v, o, i, template="pennate", v_ref=ref)
    # rule (1): the template's insertion band is shifted towards the bulk (+x here: the
    # spindle is bowed to +x), so the axis = attachment vector - shift tilts to -x
    assert frame.axis[0] < -0.1
    for rot in Rotation.random(8, random_state=3):
        r, t = rot.as_matrix(), np.array([0.3, -1.2, 0.7])
        moved = principal_frame(v @ r.T + t, o @ r.T + t, i @ r.T + t, template="pennate",
                                v_ref=r @ ref)
        # the same rotation grid relative to the muscle: equal up to rounding (1e-9 is
        # ~1e6 x the double precision of unit vectors; a flip would be ~0.38 away)
        assert np.abs(moved.axis - r @ frame.axis).max() <= 1e-9
    rng = np.random.default_rng(0)
    for _ in range(4):  # perturbations of 1e-12 m break the exact tie by ~1e-10 relative
        nudged = principal_frame(v, o + 1e-12 * rng.standard_normal(o.shape), i,
                                 template="pennate", v_ref=ref)
        assert np.abs(nudged.axis - frame.axis).max() <= 1e-8



@pytest.mark.parametrize("template", ["parallel", "pennate"])
@pytest.mark.parametrize("axis", ["auto", "covariance", "attachments"])
def test_prepared_vertices_give_the_same_frame_and_box_bit_for_bit(template, axis):
    # fitting.prepare makes the transposed vertices, bounds and centroid once
    # for the stages of a decomposition: the frame and box must be exactly those made
    # without it (the same functions on the same vertices; prepared arrays read-only
    # inputs), and its arrays exactly numpy's (transpose, min/max, mean)
    from fibres.fit import fitting

    v, o, i = _bent_spindle(n_z=30, n_t=40)
    rot = Rotation.from_euler("xyz", [0.2, -0.7, 0.4]).as_matrix()
    v, o, i = v @ rot.T - 0.3, o @ rot.T - 0.3, i @ rot.T - 0.3
    prep = fitting.prepare(v)
    np.testing.assert_array_equal(prep.vt, v.T)
    np.testing.assert_array_equal(prep.lo, v.min(axis=0))
    np.testing.assert_array_equal(prep.hi, v.max(axis=0))
    np.testing.assert_array_equal(prep.centroid, v.mean(axis=0))
    ref_dir = np.array([1.0, 0.3, 0.1])
    f1 = principal_frame(v, o, i, axis=axis, template=template, v_ref=ref_dir)
    f2 = principal_frame(v, o, i, axis=axis, template=template, v_ref=ref_dir, prepared=prep)
    for x, y in zip(f1[:4], f2[:4]):
        np.testing.assert_array_equal(x, y)
    b1 = fit_box(v, o, i, template, axis=axis, v_ref=ref_dir)
    b2 = fit_box(v, o, i, template, axis=axis, v_ref=ref_dir, prepared=prep)
    b3 = fit_box(v, o, i, template, axis=axis, v_ref=ref_dir, prepared=prep, frame=f2)
    for b in (b2, b3):
        for name in ("corner", "axes", "extents", "scores"):
            np.testing.assert_array_equal(getattr(b1, name), getattr(b, name))
        assert b.angle_index == b1.angle_index



def test_auto_axis_without_covariance_decides_as_the_extent(monkeypatch):
    # axis="auto" skips the covariance where the landmark centroids are at least 1/4 of the
    # bounding-box diagonal apart (the extent along any unit axis is at most the diagonal):
    # the method must be exactly the rule's on the covariance extent, also just around the
    # shortcut's threshold and the rule's own
    from fibres.fit import fitting

    rng = np.random.default_rng(11)
    calls = []
    real = fitting._covariance_axis
    monkeypatch.setattr(fitting, "_covariance_axis",
                        lambda *a: calls.append(1) or real(*a))
    for k in range(12):
        rot = Rotation.random(random_state=k).as_matrix()
        v = _ellipsoid(np.array([0.02, 0.03, 0.15]) * rng.uniform(0.5, 2.0, 3), rot) + 0.2
        d = v - v.mean(axis=0)
        length = float(np.ptp(d @ real(v, v.mean(axis=0))))
        diag = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
        for dist in (0.25 * length * (1 - 1e-12), 0.25 * length, 0.25 * length * (1 + 1e-12),
                     0.25 * diag * (1 - 1e-12), 0.25 * diag, 0.25 * diag * (1 + 1e-8),
                     0.3 * diag):
            step = rng.normal(size=3)
            o = v.mean(axis=0) + 0.01 * rng.normal(size=3)
            i = o + dist * step / np.linalg.norm(step)
            calls.clear()
            f = principal_frame(v, [o], [i], axis="auto")
            got_dist = float(np.linalg.norm(np.asarray([i]).mean(axis=0)
                                            - np.asarray([o]).mean(axis=0)))
            want = "covariance" if got_dist < 0.25 * length else "attachments"
            assert f.method == want
            assert length <= diag
            if dist >= 0.25 * diag * (1 + 1e-8):
                assert not calls                  # the covariance was not needed



def test_norm_is_numpys_bit_for_bit():
    from fibres.fit.fitting import _norm

    rng = np.random.default_rng(13)
    m = rng.normal(size=(200, 3, 3)) * 10.0 ** rng.integers(-8, 8, size=(200, 1, 1))
    for x in m:
        for v in (x[0], x[:, 1], x.ravel(), x[::-1, 2]):      # contiguous and strided
            assert _norm(v) == np.linalg.norm(v)


def test_landmarks_in_the_box_are_accepted_without_measuring():
    from fibres.fit.fitting import _check_in_box

    lo, hi = np.zeros(3), np.ones(3)
    _check_in_box(lo, hi, np.array([[5.0, 5.0, 5.0], [1.0, 0.0, 0.5]]), name="origin")
    with pytest.raises(InputError):
        _check_in_box(lo, hi, np.array([[50.0, 5.0, 5.0], [1.0, 0.0, 8.5]]), name="origin")
