"""Dead ends beyond a side patch (`fibres.slicing.harmonic_sections.dead_end_levels`): a tube
whose origin patch lies on its side halfway up, so that a third of it lies beyond the origin.
Without the bound the first slices are rings about the patch that sweep up the dead end and the
fibres climb 33 mm into it and turn back (44 degrees); with it they run from the patch
to the insertion cap, none above the patch."""
import warnings

import numpy as np
from test_decompose_analytic import cap_ring, straight, tube

from fibres import decompose, make_plan
from fibres.slicing.harmonic_sections import dead_end_levels

R, L = 0.015, 0.16


def _circle(th):
    return R * np.c_[np.cos(th), np.sin(th)]


def _side_patch(z0, z1):
    """Landmarks on the tube's +x side between heights z0 and z1 (a 70-degree strip)."""
    return np.array([[R * np.cos(a), R * np.sin(a), z] for a in np.linspace(-0.6, 0.6, 5)
                     for z in np.linspace(z0, z1, 4)])


def _decompose(v, f, o, i):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return decompose((v, f), o, i, template="parallel", n_fibres=50, resolution=15)


def _turns(points):
    seg = np.diff(points, axis=1)
    cos = np.einsum("npk,npk->np", seg[:, 1:], seg[:, :-1]) / (
        np.linalg.norm(seg[:, 1:], axis=2) * np.linalg.norm(seg[:, :-1], axis=2))
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def test_fibres_from_a_side_patch_stay_below_it_and_do_not_turn_back():
    v, f = tube(_circle, *straight(L), n_sect=40, n_path=65)
    o = _side_patch(0.08, 0.11)                                  # 50 mm of tube above it
    i = cap_ring(np.zeros(3), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), 0.005)
    b = _decompose(v, f, o, i)
    plan = b.plan
    top = plan.rest_vertices[plan.origin][:, 2].max()
    # no fibre point in the dead end: nothing above the patch's highest vertex
    assert b.points[..., 2].max() <= top + 1e-9
    # the fibres run down from the patch: no turn back (a straight tube: 13 degrees; 44 without the bound)
    assert _turns(b.points).max() < 30.0
    assert any("beyond the origin patch" in n for n in b.notes)
    lo, hi, notes = dead_end_levels(plan)
    assert 0.0 < lo < 0.5 and hi == 1.0 and len(notes) == 1
    # the dead end's share of the surface: the tube's side from `DEAD_END` (0.1) of the
    # farthest surface distance (the top cap's centre: 10 mm across the bottom cap from the
    # insertion ring, L up, R across the top) above the patch's top, and the top cap
    share = float(notes[0].split("%")[0]) / 100
    side = 2 * np.pi * R
    start = top + 0.1 * (R - 0.005 + L + R)
    expected = (side * (L - start) + np.pi * R * R) / (side * L + 2 * np.pi * R * R)
    assert abs(share - expected) < 0.02


def test_an_insertion_on_the_side_bounds_the_last_slices():
    """The mirror case: origin on the bottom cap, insertion on the side halfway up; the
    slices stop below the insertion's dead end (``hi`` < 1) and no fibre goes above it."""
    v, f = tube(_circle, *straight(L), n_sect=40, n_path=65)
    o = cap_ring(np.zeros(3), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), 0.005)
    b = _decompose(v, f, o, _side_patch(0.08, 0.11))
    plan = b.plan
    lo, hi, notes = dead_end_levels(plan)
    assert lo == 0.0 and 0.5 < hi < 1.0 and "beyond the insertion patch" in notes[0]
    assert b.points[..., 2].max() <= plan.rest_vertices[plan.insertion][:, 2].max() + 1e-9
    assert _turns(b.points).max() < 30.0


def test_patches_on_the_ends_have_no_dead_end():
    v, f = tube(_circle, *straight(L), n_sect=40, n_path=65)
    e1, e2 = np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    plan = make_plan((v, f), cap_ring(np.array([0, 0, L]), e1, e2, 0.005),
                     cap_ring(np.zeros(3), e1, e2, 0.005))
    assert dead_end_levels(plan) == (0.0, 1.0, [])


def _u_path(radius, leg):
    """A U in the xy plane: a leg down from (radius, 0) to (radius, -leg), a half circle over
    y >= 0 from (radius, 0) to (-radius, 0), and the other leg down, by arc length."""
    total = 2 * leg + np.pi * radius

    def path(s):
        t = s * total
        out = np.zeros((len(t), 3))
        a, b = t < leg, t > leg + np.pi * radius
        m = ~a & ~b
        out[a] = np.c_[np.full(a.sum(), radius), t[a] - leg, np.zeros(a.sum())]
        phi = (t[m] - leg) / radius
        out[m] = np.c_[radius * np.cos(phi), radius * np.sin(phi), np.zeros(m.sum())]
        out[b] = np.c_[np.full(b.sum(), -radius), -(t[b] - leg - np.pi * radius),
                       np.zeros(b.sum())]
        return out

    def tangent(s):
        t = s * total
        out = np.zeros((len(t), 3))
        a, b = t < leg, t > leg + np.pi * radius
        m = ~a & ~b
        out[a] = [0.0, 1.0, 0.0]
        phi = (t[m] - leg) / radius
        out[m] = np.c_[-np.sin(phi), np.cos(phi), np.zeros(m.sum())]
        out[b] = [0.0, -1.0, 0.0]
        return out

    return path, tangent


def test_a_muscle_bent_into_a_u_has_no_dead_end():
    # the bend's top is farther from the insertion in a straight line than the origin (102 vs
    # 40 mm) but nearer along the muscle: the surface distance keeps its slices
    radius, leg = 0.02, 0.08
    v, f = tube(lambda th: 0.008 * np.c_[np.cos(th), np.sin(th)], *_u_path(radius, leg),
                n_sect=24, n_path=120)
    e1, e2 = np.array([1.0, 0, 0]), np.array([0, 0, 1.0])
    o = cap_ring(np.array([radius, -leg, 0.0]), e1, e2, 0.004)
    i = cap_ring(np.array([-radius, -leg, 0.0]), e1, e2, 0.004)
    plan = make_plan((v, f), o, i)
    d = np.linalg.norm(plan.rest_vertices - i.mean(axis=0), axis=1)
    assert d.max() > np.linalg.norm(o.mean(axis=0) - i.mean(axis=0)) + 0.05   # straight line
    assert dead_end_levels(plan) == (0.0, 1.0, [])
