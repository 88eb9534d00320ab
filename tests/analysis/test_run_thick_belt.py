"""A thick belt over a pulley, end to end (`analysis.run`): the wrap object guides the centre line,
the tissue keeps its cross-section around it and lies partly inside the wrap radius (issue 12).

The belt: a straight tube of rectangular cross-section (thickness ``t`` towards the pulley axis,
width ``W`` along it) whose centre line is tangent to an OpenSim WrapCylinder of radius R at the
rest pose; the insertion body turns about the cylinder axis, so the line wraps q radians. No
bone mesh is given: the tool's bone is the wrap cylinder moved inwards by the belt's local
half-thickness, radius R - t / 2 (README "Wrap objects and bones").

Closed forms: a fibre lying on the pulley at radius rho lengthens by rho dq, so its moment arm
is -rho (the line's is -R); the surface never enters the bone, and keeps its volume.
"""
from __future__ import annotations

import textwrap

import numpy as np
import pytest

pytest.importorskip("motion.surface.thickness", reason="issue 12 not in this checkout")

from analysis.run import run  # noqa: E402

R = 0.02                   # wrap radius
A, B = 0.2, 0.2            # origin / insertion distance from the tangent point along the line
W = 0.016                  # belt width along the pulley axis


def belt_mesh(x0, thickness, *, n_along=120, n_t=6, n_w=8):
    """Closed tube from (x0, A, 0) to (x0, -B, 0), rectangular cross-section (thickness along x,
    width along z), flat caps fanned from their centres; outward faces."""
    ht, hw = 0.5 * thickness, 0.5 * W
    # the rectangle's perimeter, counter-clockwise in (x, z)
    sides = [np.stack([np.full(n_t, ht), np.linspace(-hw, hw, n_t, endpoint=False)], 1),
             np.stack([np.linspace(ht, -ht, n_w, endpoint=False), np.full(n_w, hw)], 1),
             np.stack([np.full(n_t, -ht), np.linspace(hw, -hw, n_t, endpoint=False)], 1),
             np.stack([np.linspace(-ht, ht, n_w, endpoint=False), np.full(n_w, -hw)], 1)]
    ring = np.concatenate(sides)                                     # (K, 2)
    k = len(ring)
    y = np.linspace(A, -B, n_along + 1)
    verts = np.zeros((n_along + 1, k, 3))
    verts[..., 0] = x0 + ring[None, :, 0]
    verts[..., 1] = y[:, None]
    verts[..., 2] = ring[None, :, 1]
    verts = np.vstack([verts.reshape(-1, 3), [x0, A, 0.0], [x0, -B, 0.0]])
    c0, c1 = len(verts) - 2, len(verts) - 1
    i, j = np.meshgrid(np.arange(n_along), np.arange(k), indexing="ij")
    a = i * k + j
    b = i * k + (j + 1) % k
    faces = np.concatenate([np.stack([a, b, b + k], -1).reshape(-1, 3),
                            np.stack([a, b + k, a + k], -1).reshape(-1, 3)])
    jj = np.arange(k)
    top = n_along * k
    faces = np.concatenate([faces, np.stack([np.full(k, c0), (jj + 1) % k, jj], -1),
                            np.stack([np.full(k, c1), top + jj, top + (jj + 1) % k], -1)])
    import trimesh

    if trimesh.Trimesh(verts, faces, process=False).volume < 0:
        faces = faces[:, ::-1]
    return verts, faces


def cap_landmarks(x0, y, thickness):
    """A 5 x 3 grid over 0.7 of the cap."""
    xs = x0 + 0.35 * thickness * np.linspace(-1, 1, 5)
    zs = 0.35 * W * np.linspace(-1, 1, 3)
    return np.array([[x, y, z] for x in xs for z in zs])


def build(tmp_path, thickness, q_deg, *, fibres=24, resolution=60):
    import trimesh

    from motion import write_sto
    from motion.osim.builder import ModelBuilder

    x0 = -R                         # the rest line is tangent to the cylinder at (-R, 0, 0)
    mb = (ModelBuilder("belt").add_body("upper").add_weld_joint("fix", "ground", "upper")
          .add_body("lower").add_pin_joint("pin", "upper", "lower", "q", range=(-3.0, 3.0)))
    mb.add_wrap_cylinder("upper", "pulley", radius=R, length=0.2, quadrant="-x")
    mb.add_muscle("belt", [("upper", (x0, A, 0.0)), ("lower", (x0, -B, 0.0))], wraps=("pulley",))
    mb.write(tmp_path / "belt.osim")
    verts, faces = belt_mesh(x0, thickness)
    trimesh.Trimesh(verts, faces, process=False).export(tmp_path / "belt.ply")
    q = np.deg2rad(np.asarray(q_deg, float))
    write_sto(tmp_path / "sweep.mot", np.arange(len(q)) * 0.01, {"q": q})
    (tmp_path / "belt.toml").write_text(textwrap.dedent(f"""
        model = "belt.osim"
        motion = "sweep.mot"
        [muscles.belt]
        action_lines = ["belt"]
        mesh = "belt.ply"
        frame = "ground"
        rest_pose = {{ q = 0.0 }}
        template = "parallel"
        fibres = {fibres}
        resolution = {resolution}
        origin = {{ body = "upper", points = {cap_landmarks(x0, A, thickness).tolist()} }}
        insertion = {{ body = "lower", points = {cap_landmarks(x0, -B, thickness).tolist()} }}
        """))
    return tmp_path / "belt.toml"


def wrapped_sector_radius(points, q):
    """Per frame and fibre: the median distance from the pulley axis of the fibre points lying in
    the middle 80 % of the wrapped sector (polar angle from the -x axis in [0.1 q, 0.9 q]), and
    how many points that is."""
    psi = np.arctan2(-points[..., 1], -points[..., 0])             # (F, N, P)
    rad = np.hypot(points[..., 0], points[..., 1])
    inside = (psi > 0.1 * q[:, None, None]) & (psi < 0.9 * q[:, None, None])
    med = np.where(inside.any(-1), np.nanmedian(np.where(inside, rad, np.nan), axis=-1), np.nan)
    return med, inside.sum(-1)


@pytest.mark.filterwarnings("ignore:All-NaN slice")
@pytest.mark.parametrize("ratio", [0.2, 0.4, 0.6])
def test_thick_belt_fibres_follow_their_own_radius(tmp_path, ratio):
    from motion.surface.volume import mesh_volume

    thickness = ratio * R
    bone = R - 0.5 * thickness
    q_deg = np.arange(0, 121, 15)
    res = run(build(tmp_path, thickness, q_deg), keep_surfaces=True)
    m = res.muscle("belt")
    q = res.coordinate_values("q")
    # the action line wraps by q: r = -R exactly
    np.testing.assert_allclose(m.action_line_moment_arms[q > 0, 0, 0], -R, rtol=1e-6)
    pts = m.fibre_points                                            # (F, N, P, 3)
    rad = np.hypot(pts[..., 0], pts[..., 1])
    # no fibre point inside the bone, in any frame
    assert rad.min() >= bone, f"a fibre point is {1e3 * (bone - rad.min()):.3f} mm inside the bone"
    # the surface keeps out of the bone too (0.05 mm: its push-out shell holds it above)
    srad = np.hypot(m.surface_vertices[..., 0], m.surface_vertices[..., 1])
    assert srad.min() >= bone - 5e-5
    # the tissue lies inside the wrap radius: the inner face reaches the bone while wrapped
    assert srad[-1].min() < bone + 0.25 * thickness
    # volume within 0.5 %
    vol = np.array([mesh_volume(v, m.surface_faces) for v in m.surface_vertices])
    assert np.abs(vol / vol[0] - 1.0).max() < 5e-3
    # while wrapped (>= 30 degrees: fibre points in the sector), every fibre's moment
    # arm is minus its own distance from the axis within 2 %
    deep = q >= np.deg2rad(30)
    rho, count = wrapped_sector_radius(pts[deep], q[deep])
    assert (count >= 1).all()
    r = -m.fibre_moment_arms[deep, :, 0]
    err = np.abs(r - rho) / rho
    assert err.max() < 0.02, f"worst fibre {100 * err.max():.2f} % off its radius"
    # the fibres span the thickness: inner ones well inside the wrap radius, outer ones outside
    assert rho.min() < R - 0.25 * thickness and rho.max() > R + 0.25 * thickness
