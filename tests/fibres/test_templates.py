"""fibres.template.templates: Blemker & Delp (2005) style Bézier fibre families in the unit cube."""
import numpy as np
import pytest

from fibres.template.bezier import bernstein, evaluate
from fibres.errors import InputError
from fibres.template.sampling import sobol_rs
from fibres.template.templates import DEFAULTS, TEMPLATES, get_template

RS = sobol_rs(512, seed=1)
T = np.linspace(0.0, 1.0, 41)
EPS = 1e-12  # round-off of a convex combination of numbers in [0, 1]


def _in_rects(pts, rects):
    inside = np.zeros(len(pts), bool)
    for r in rects:
        inside |= ((pts[:, 0] >= r[0] - EPS) & (pts[:, 0] <= r[1] + EPS)
                   & (pts[:, 1] >= r[2] - EPS) & (pts[:, 1] <= r[3] + EPS))
    return inside


@pytest.mark.parametrize("name", TEMPLATES)
def test_fibres_inside_cube_from_origin_to_insertion(name):
    tm = get_template(name)
    p = tm.fibre_points(RS, T)
    assert p.shape == (len(RS), len(T), 3)
    assert p.min() >= -EPS and p.max() <= 1 + EPS
    np.testing.assert_allclose(p[:, 0, 2], 0.0, atol=EPS)
    np.testing.assert_allclose(p[:, -1, 2], 1.0, atol=EPS)
    o_rects, i_rects = tm._rects
    assert _in_rects(p[:, 0], o_rects).all()
    assert _in_rects(p[:, -1], i_rects).all()
    # z rises monotonically along every fibre (z control ordinates are non-decreasing)
    assert (np.diff(p[..., 2], axis=1) > 0).all()
    # the area samples lie on the faces and inside the rectangles
    np.testing.assert_array_equal(tm.origin_area[:, 2], 0.0)
    np.testing.assert_array_equal(tm.insertion_area[:, 2], 1.0)
    assert _in_rects(tm.origin_area, o_rects).all() and _in_rects(tm.insertion_area, i_rects).all()


@pytest.mark.parametrize("name", TEMPLATES)
def test_degree_and_rational_structure(name):
    tm = get_template(name)
    ctrl, w = tm.control_points(RS[:7])
    assert ctrl.shape == (7, tm.degree + 1, 3)
    assert 2 <= tm.degree <= 4
    assert (w is not None) == tm.rational
    # the fibre points are exactly the Bernstein combination of the control points
    basis = bernstein(tm.degree, T)
    wt = np.ones(tm.degree + 1) if w is None else w
    ref = np.einsum("pd,d,ndk->npk", basis, wt, ctrl) / (basis @ wt)[None, :, None]
    np.testing.assert_allclose(tm.fibre_points(RS[:7], T), ref, atol=1e-14)


def test_parallel_fibres_are_straight_lines():
    p = get_template("parallel").fibre_points(RS, T)
    lin = p[:, :1] + (p[:, -1:] - p[:, :1]) * T[None, :, None]
    np.testing.assert_allclose(p, lin, atol=1e-14)
    # full faces by default: the fibre (r, s) starts at (r, s, 0) and ends at (r, s, 1)
    np.testing.assert_allclose(p[:, 0, :2], RS, atol=1e-14)
    np.testing.assert_allclose(p[:, -1, :2], RS, atol=1e-14)


def test_curved_centre_fibre_is_a_circular_arc():
    c = 0.6
    p = get_template("curved", curvature=c, origin_size=(1, 1), insertion_size=(1, 1)) \
        .fibre_points(np.array([[0.5, 0.5]]), T)[0]
    # circle in the xz plane through (0.5,0), (0.5,1) with tangent at the ends meeting at
    # (0.5 + c/2, 0.5): centre (0.5 - d, 0.5) with d = (1/2)^2 / (c/2) - ... solve analytically:
    # tangent from (0.5,0) to (0.5+h,0.5), h=c/2 -> radius direction is perpendicular to it.
    h = c / 2
    # centre x0 on the line z = 0.5 with (P0 - C) . (P1 - P0) = 0:  (0.5 - x0) h + (-0.5)(0.5) = 0
    x0 = 0.5 - 0.25 / h
    radius = np.hypot(0.5 - x0, 0.5)
    dist = np.hypot(p[:, 0] - x0, p[:, 2] - 0.5)
    np.testing.assert_allclose(dist, radius, rtol=1e-12)
    assert p[:, 0].max() > 0.5  # bulges towards +x


def test_fanned_converges_on_fan_centre():
    tm = get_template("fanned", fan_centre=(0.3, 0.7), insertion_size=(0.1, 0.1))
    p = tm.fibre_points(RS, T)
    np.testing.assert_allclose(p[:, -1, :2].mean(axis=0), [0.3, 0.7], atol=0.01)
    assert np.ptp(p[:, -1, 0]) <= 0.1 + EPS and np.ptp(p[:, 0, 0]) > 0.9


def test_bipennate_and_rectus_halves():
    p = get_template("bipennate").fibre_points(RS, T)
    left = RS[:, 0] < 0.5
    # left fibres start on the left band and run right to the central tendon, and vice versa
    assert (p[left, 0, 0] <= 0.25 + EPS).all() and (p[~left, 0, 0] >= 0.75 - EPS).all()
    assert (p[left, -1, 0] <= 0.5 + EPS).all() and (p[~left, -1, 0] >= 0.5 - EPS).all()
    q = get_template("rectus").fibre_points(RS, T)
    assert (q[left, -1, 0] <= 0.25 + EPS).all() and (q[~left, -1, 0] >= 0.75 - EPS).all()


@pytest.mark.parametrize("name", TEMPLATES)
def test_params_are_documented_and_applied(name):
    tm = get_template(name)
    assert set(tm.params) == set(DEFAULTS[name])
    smaller = get_template(name, origin_size=(0.2, 0.4))
    assert np.ptp(smaller.origin_area[:, 1]) == pytest.approx(0.4)


def test_parameter_validation():
    with pytest.raises(InputError, match="unknown template 'spiral'"):
        get_template("spiral")
    with pytest.raises(InputError, match="unknown parameter"):
        get_template("parallel", curvature=0.2)
    with pytest.raises(InputError, match="out of range"):
        get_template("curved", curvature=1.0)
    with pytest.raises(InputError, match="out of range"):
        get_template("pennate", tendon=-0.1)
    with pytest.raises(InputError, match="does not fit"):
        get_template("parallel", origin_centre=(0.9, 0.5), origin_size=(0.5, 0.5))
    with pytest.raises(InputError, match="in \\(0, 1\\]"):
        get_template("fanned", insertion_size=(0.0, 0.2))
    with pytest.raises(ValueError, match="rs"):
        get_template("parallel").fibre_points(np.array([[1.5, 0.2]]), T)


def test_template_is_frozen():
    tm = get_template("pennate")
    with pytest.raises(AttributeError):
        tm.name = "x"
    with pytest.raises(TypeError):
        tm.params["tendon"] = 0.1
    assert not tm.origin_area.flags.writeable


def test_bezier_evaluate_rational_reduces_to_polynomial_with_unit_weights():
    ctrl = np.random.default_rng(0).random((4, 4, 3))
    np.testing.assert_allclose(evaluate(ctrl, T, np.ones(4)), evaluate(ctrl, T), atol=1e-14)
    np.testing.assert_allclose(bernstein(3, T).sum(axis=1), 1.0, atol=1e-14)


def _unit_cube_mesh():
    import trimesh

    m = trimesh.creation.box(bounds=[[0, 0, 0], [1, 1, 1]]).subdivide_to_size(0.1)
    return np.asarray(m.vertices), np.asarray(m.faces)


@pytest.mark.parametrize("name", TEMPLATES)
def test_each_template_reproduces_itself_in_the_unit_cube(name):
    # (the planar method) decompose the unit cube with the template's own attachment areas: the fitted box IS the
    # cube, every slice is the unit square and the morph is the identity, so the fibres must
    # be the template's own curves (up to round-off of the MVC weights, 1e-9)
    decompose = pytest.importorskip("fibres.decompose").decompose
    tm = get_template(name)
    bundle = decompose(_unit_cube_mesh(), tm.origin_area, tm.insertion_area, template=name,
                       n_fibres=40, resolution=19, smoothing_iterations=0,
                       filter_attachments=False, slicing="planes")
    ref = tm.fibre_points(bundle.rs, np.linspace(0, 1, 20))
    np.testing.assert_allclose(bundle.points, ref, atol=1e-9)
    np.testing.assert_array_equal(bundle.rs, sobol_rs(40, seed=0))
    # with the attachment filter on nothing lies beyond the planes through the face landmarks
    filtered = decompose(_unit_cube_mesh(), tm.origin_area, tm.insertion_area, template=name,
                         n_fibres=40, resolution=19, smoothing_iterations=0, slicing="planes")
    assert not filtered.flags["trimmed"].any()
    np.testing.assert_allclose(filtered.points, ref, atol=1e-9)


from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_frac = st.floats(0.05, 1.0)


@settings(max_examples=60, deadline=None)
@given(name=st.sampled_from(TEMPLATES), ow=_frac, od=_frac, iw=_frac, idp=_frac,
       shape=st.floats(0.0, 0.5))
def test_any_valid_parameters_keep_fibres_inside_the_cube(name, ow, od, iw, idp, shape):
    params = {"origin_size": (ow, od), "insertion_size": (iw, idp)}
    extra = {"pennate": "tendon", "bipennate": "tendon", "curved": "curvature",
             "fanned": "spread", "rectus": "aponeurosis"}
    if name in extra:
        params[extra[name]] = shape
    tm = get_template(name, **params)
    p = tm.fibre_points(RS[:64], T)
    # convex-hull property: control points in the cube and positive weights
    assert p.min() >= -EPS and p.max() <= 1 + EPS
    np.testing.assert_allclose(p[:, 0, 2], 0.0, atol=EPS)
    np.testing.assert_allclose(p[:, -1, 2], 1.0, atol=EPS)


def test_pennation_sets_the_fibre_angle():
    # straight middle part: with tendon=0 the cubic's control points are collinear pairs, the
    # fibre is the straight line from (x_o, 0) to (x_i, 1); offset = pennation * (1 - w)
    w = 0.4
    for pen in (0.0, 0.5, 1.0):
        tm = get_template("pennate", pennation=pen, tendon=0.0, origin_size=(w, 1),
                          insertion_size=(w, 1))
        p = tm.fibre_points(np.array([[0.5, 0.5]]), T)[0]
        offset = p[-1, 0] - p[0, 0]
        assert offset == pytest.approx(pen * (1 - w), abs=1e-14)
    bi = get_template("bipennate", pennation=0.0, origin_size=(0.3, 1),
                      insertion_size=(0.3, 1)).fibre_points(RS, T)
    # pennation 0 and each origin band as wide as half the insertion band: fibres rise
    # vertically (x constant) onto the central tendon
    np.testing.assert_allclose(bi[:, -1, 0], bi[:, 0, 0], atol=1e-14)
    with pytest.raises(InputError, match="pennation"):
        get_template("pennate", pennation=1.5)



@pytest.mark.parametrize("name", TEMPLATES)
def test_offset_and_oblique_are_the_areas_centroid_shift(name):
    from fibres.fit.fitting import template_offset

    for tm in (get_template(name), get_template(name, **({"pennation": 0.3} if name in (
            "pennate", "bipennate") else {}))):
        want = (tm.insertion_area.mean(axis=0) - tm.origin_area.mean(axis=0))[:2]
        np.testing.assert_array_equal(tm.offset, want)
        np.testing.assert_array_equal(template_offset(tm), want)
        assert tm.oblique == bool(np.abs(want).max() > 1e-12)
        assert not tm.offset.flags.writeable
    assert get_template("pennate").oblique and not get_template("parallel").oblique
