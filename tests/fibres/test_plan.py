"""DecompositionPlan: reapplying the choices to the same and to deformed copies of a mesh."""
import functools

import numpy as np
import pytest
import trimesh

from fibres import DecompositionPlan, decompose, make_plan
from fibres.plan import kabsch_rotation

# the decomposition plan of the planar method (Kohout et al. 2012)
decompose = functools.partial(decompose, slicing="planes")
make_plan = functools.partial(make_plan, slicing="planes")


@pytest.fixture(scope="module")
def muscle():
    """A fusiform muscle-like ellipsoid (60 mm long) with landmarks at both tips."""
    m = trimesh.creation.icosphere(subdivisions=4)
    v, f = np.array(m.vertices), np.array(m.faces)
    z = v[:, 2]
    verts = np.c_[v[:, 0] * 0.0144, v[:, 1] * 0.0096, z * 0.06]
    return verts, f, verts[z < -0.9], verts[z > 0.9]


def deform(x, e):
    """A smooth bend + twist + stretch of amplitude e (e = 0: identity)."""
    zz = x[:, 2] / 0.06
    bx = x[:, 0] + e * 0.01 * np.sin(np.pi * zz)
    c, s = np.cos(e * zz), np.sin(e * zz)
    return np.c_[c * bx - s * x[:, 1], s * bx + c * x[:, 1], x[:, 2] + e * 0.002 * zz**2]


def test_plan_on_same_mesh_reproduces_bundle_exactly(muscle):
    v, f, o, i = muscle
    b = decompose((v, f), o, i)
    again = decompose((v, f), o, i, plan=b.plan)
    assert np.array_equal(again.points, b.points)
    assert np.array_equal(again.plan.choice, b.plan.choice)
    # make_plan makes the same choices as decompose
    p = make_plan((v, f), o, i)
    assert p.angle_index == b.plan.angle_index and np.array_equal(p.choice, b.plan.choice)
    assert isinstance(p, DecompositionPlan) and p.n_slices == 20
    assert not p.choice.flags.writeable


def test_small_deformations_move_fibres_smoothly(muscle):
    v, f, o, i = muscle
    b0 = decompose((v, f), o, i)

    def fib(e):
        return decompose((deform(v, e), f), deform(o, e), deform(i, e), plan=b0.plan).points

    h = 1e-4
    p1, m1, p2, m2 = fib(h), fib(-h), fib(2 * h), fib(-2 * h)
    d1 = (p1 - m1) / (2 * h)
    d2 = (p2 - m2) / (4 * h)
    # central differences at two step sizes agree to O(h^2): the map is smooth there (a
    # flipped choice would make them differ by the size of a jump / h, i.e. > 1e-2 m)
    scale = np.abs(d1).max()
    assert 1e-4 < scale < 1.0
    assert np.abs(d1 - d2).max() <= 1e-3 * scale
    # and the motion is small: |dp| <= |dp/de| h with the measured derivative
    assert np.abs(p1 - b0.points).max() <= 1.01 * scale * h


def test_morph_continuous_over_a_large_sweep(muscle):
    # 60 steps up to a bend of 3 mm, a 17-degree twist and a stretch: with the plan the
    # start/split points are material points carried along (no vertex snapping, no
    # re-minimised split), so the fibres move by the same small amount at every step
    v, f, o, i = muscle
    b0 = decompose((v, f), o, i, filter_attachments=False)
    prev, steps = b0.points, []
    for e in np.linspace(0, 0.3, 61)[1:]:
        b = decompose((deform(v, e), f), deform(o, e), deform(i, e), plan=b0.plan,
                      filter_attachments=False)
        assert b.notes == ()          # no fallback to fresh choices
        steps.append(np.abs(b.points - prev).max())
        prev = b.points
    steps = np.array(steps)
    # a smooth path sampled uniformly: consecutive steps within a factor 1.5 of the median
    # (a flipped start vertex or split would give a step of a contour segment, ~1 mm,
    # against a median of ~0.06 mm)
    assert steps.max() <= 1.5 * np.median(steps)


def test_plan_refuses_another_mesh(muscle):
    v, f, o, i = muscle
    b = decompose((v, f), o, i)
    other = trimesh.creation.icosphere(subdivisions=3)
    with pytest.raises(ValueError, match="topology"):
        decompose((np.array(other.vertices) * 0.05, np.array(other.faces)), o, i, plan=b.plan)


def test_kabsch_recovers_a_rotation():
    rng = np.random.default_rng(2)
    x = rng.normal(size=(50, 3))
    ang = 0.9
    rot = np.array([[np.cos(ang), -np.sin(ang), 0], [np.sin(ang), np.cos(ang), 0], [0, 0, 1]])
    assert np.abs(kabsch_rotation(x, x @ rot.T + 3.0) - rot).max() <= 1e-12


def test_plan_fast_path_in_millimetres(muscle):
    # a frame given as a (vertices, faces) tuple in mm with the plan's faces skips the
    # surface repair; the result must equal the metre version to rounding of the scaling
    v, f, o, i = muscle
    b = decompose((v, f), o, i)
    mm = decompose((deform(v, 0.01) * 1e3, f), deform(o, 0.01) * 1e3, deform(i, 0.01) * 1e3,
                   units="mm", plan=b.plan)
    m = decompose((deform(v, 0.01), f), deform(o, 0.01), deform(i, 0.01), plan=b.plan)
    assert np.abs(mm.points - m.points).max() <= 1e-12


def test_plan_and_bundle_pickle(muscle):
    # runs with --jobs send plans and bundles to worker processes
    import pickle

    v, f, o, i = muscle
    b = decompose((v, f), o, i, template="fanned", template_params={"spread": 0.3})
    b2 = pickle.loads(pickle.dumps(b))
    assert np.array_equal(b2.points, b.points) and b2.template.name == b.template.name
    assert dict(b2.template.params) == dict(b.template.params)
    assert np.array_equal(b2.flags["trimmed"], b.flags["trimmed"]) and b2.notes == b.notes
    again = decompose((deform(v, 0.01), f), deform(o, 0.01), deform(i, 0.01), template="fanned",
                      template_params={"spread": 0.3}, plan=b2.plan)
    ref = decompose((deform(v, 0.01), f), deform(o, 0.01), deform(i, 0.01), template="fanned",
                    template_params={"spread": 0.3}, plan=b.plan)
    assert np.array_equal(again.points, ref.points)


def test_clean_tuple_skips_repair_with_the_same_result(muscle):
    import warnings

    from fibres import as_surface
    from fibres.decompose import _clean_tuple

    v, f, o, i = muscle
    assert _clean_tuple((v, f), "m") is not None
    direct = decompose((v, f), o, i)
    via = decompose(as_surface((v, f)), o, i)
    assert np.array_equal(direct.points, via.points)
    # inside-out faces are not "clean": as_surface flips them (one warning) and the
    # contours are oriented geometrically, so the fibres are the same to rounding
    assert _clean_tuple((v, f[:, ::-1]), "m") is None
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        flipped = decompose((v, f[:, ::-1]), o, i)
    assert np.abs(flipped.points - direct.points).max() <= 1e-12


# --- the attachment filter with a plan (Kohout §3.4 choices frozen on the rest pose) -----

@pytest.fixture(scope="module")
def wide(muscle):
    """The same muscle with wide attachment areas: landmarks on the caps up to 30 % of the
    half-length from the tips, so the cutting planes trim the converging fibre ends."""
    v, f, _, _ = muscle
    z = v[:, 2] / 0.06
    return v, f, v[z < -0.7][::3], v[z > 0.7][::3]


def test_filter_choices_recorded_and_reused_at_rest(wide):
    v, f, o, i = wide
    b = decompose((v, f), o, i)
    fc = b.plan.filter_choice
    assert fc is not None and fc.n_fibres == 100 and fc.n_points == 20
    assert b.flags["trimmed"].sum() >= 50            # the filter does act on this muscle
    assert np.array_equal(fc.cut.any(axis=1), b.flags["trimmed"])
    again = decompose((v, f), o, i, plan=b.plan)
    assert np.array_equal(again.points, b.points)
    # a plan from make_plan has no filter record: the choices are made once on its rest
    # pose (the same as decompose's) and reused
    p = make_plan((v, f), o, i)
    assert p.filter_choice is None
    moved = (deform(v, 0.1), f), deform(o, 0.1), deform(i, 0.1)
    via_make = decompose(*moved, plan=p)
    assert any("rest pose" in n for n in via_make.notes)
    assert np.array_equal(via_make.points, decompose(*moved, plan=b.plan).points)


def test_filter_with_plan_is_smooth_under_deformation(wide):
    # fibre LENGTHS with the filter on are smooth in the deformation parameter: central
    # differences at h and 2h agree to O(h^2) (a flipped trim / target vertex would change a
    # length by ~1 mm, i.e. d1 - d2 ~ 1e-3 / h = 10 m per unit e)
    v, f, o, i = wide
    b0 = decompose((v, f), o, i)

    def lengths(e):
        return decompose((deform(v, e), f), deform(o, e), deform(i, e), plan=b0.plan).lengths()

    for e0 in (0.05, 0.15):        # (lengths are even in e: d/de = 0 at e = 0)
        h = 1e-4
        d1 = (lengths(e0 + h) - lengths(e0 - h)) / (2 * h)
        d2 = (lengths(e0 + 2 * h) - lengths(e0 - 2 * h)) / (4 * h)
        scale = np.abs(d1).max()
        assert scale > 1e-4
        assert np.abs(d1 - d2).max() <= 1e-3 * scale


def test_filter_with_plan_continuous_over_a_large_sweep(wide):
    # 60 steps of the bend/twist/stretch: every fibre length changes by a similar amount at
    # every step (without frozen choices the target vertices snap: steps of ~ an edge)
    v, f, o, i = wide
    b0 = decompose((v, f), o, i)
    ls = np.array([decompose((deform(v, e), f), deform(o, e), deform(i, e), plan=b0.plan).lengths()
                   for e in np.linspace(0, 0.3, 61)])
    steps = np.abs(np.diff(ls, axis=0))                     # (60, N)
    second = np.abs(np.diff(ls, n=2, axis=0))               # curvature of the length curves
    # smooth curves sampled at 60 steps: second differences far below the first
    assert second.max() <= 0.2 * steps.max()
    assert steps.max() <= 3.0 * np.median(steps.max(axis=1))
