"""`analysis.run` end to end on analytic models built here with `motion.osim.builder`:

(a) a straight cylinder muscle across a pin joint: every fibre is a straight segment whose end
    points ride their bodies rigidly, so its length is |p0 - Rz(q) p1| and its moment arm is
    minus the derivative of that closed form;
(b) the same muscle over a pulley (WrapCylinder of radius R at the joint): while wrapped, the
    action line's moment arm is R and a fibre's is its own radius around the pulley axis.
"""
from __future__ import annotations

import textwrap

import numpy as np
import pytest

pytest.importorskip("motion.surface.wrap", reason="motion.wrap_surfaces is not in this checkout yet")
pytest.importorskip("fibres.decompose", reason="fibres.decompose is not in this checkout yet")

from analysis.run import run  # noqa: E402

A, B, C, RHO = 0.15, 0.12, 0.03, 0.01   # origin / insertion distance along the muscle, offset, radius
R_PULLEY = 0.02


def tube(p0, p1, radius, *, n_around=32, n_along=40):
    """Closed tube mesh (V, 3), (T, 3) from p0 to p1 with flat caps, outward faces."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    axis = (p1 - p0) / np.linalg.norm(p1 - p0)
    u = np.cross(axis, [0.0, 0.0, 1.0])
    u = u / np.linalg.norm(u) if np.linalg.norm(u) > 1e-9 else np.array([1.0, 0.0, 0.0])
    v = np.cross(axis, u)
    th = np.linspace(0, 2 * np.pi, n_around, endpoint=False)
    s = np.linspace(0, 1, n_along + 1)
    ring = radius * (np.cos(th)[:, None] * u + np.sin(th)[:, None] * v)            # (K, 3)
    verts = (p0 + s[:, None, None] * (p1 - p0) + ring[None]).reshape(-1, 3)
    verts = np.vstack([verts, p0, p1])
    c0, c1 = len(verts) - 2, len(verts) - 1
    i, j = np.meshgrid(np.arange(n_along), np.arange(n_around), indexing="ij")
    a = i * n_around + j
    b = i * n_around + (j + 1) % n_around
    faces = np.concatenate([np.stack([a, b, b + n_around], -1).reshape(-1, 3),
                            np.stack([a, b + n_around, a + n_around], -1).reshape(-1, 3)])
    jj = np.arange(n_around)
    cap0 = np.stack([np.full(n_around, c0), (jj + 1) % n_around, jj], -1)
    top = n_along * n_around
    cap1 = np.stack([np.full(n_around, c1), top + jj, top + (jj + 1) % n_around], -1)
    faces = np.concatenate([faces, cap0, cap1])
    import trimesh

    mesh = trimesh.Trimesh(verts, faces, process=False)
    if mesh.volume < 0:
        faces = faces[:, ::-1]
    return verts, faces


def disc(centre, radius, normal_axis=1, n=9):
    """Landmarks on a cap: the centre and a ring."""
    th = np.linspace(0, 2 * np.pi, n - 1, endpoint=False)
    pts = np.zeros((n, 3))
    other = [k for k in range(3) if k != normal_axis]
    pts[1:, other[0]] = radius * np.cos(th)
    pts[1:, other[1]] = radius * np.sin(th)
    return pts + np.asarray(centre, float)


def build_model(tmp_path, *, pulley: bool, q_deg, fibres=24, resolution=12):
    """Write model, motion, mesh and TOML into tmp_path; return the TOML path."""
    import trimesh

    from motion import write_sto
    from motion.osim.builder import ModelBuilder

    x = -(R_PULLEY + RHO) if pulley else C
    o, i = (x, A, 0.0), (x, -B, 0.0)
    mb = (ModelBuilder("cyl").add_body("upper").add_weld_joint("fix", "ground", "upper")
          .add_body("lower").add_pin_joint("pin", "upper", "lower", "q", range=(-3.0, 3.0)))
    wraps = ()
    if pulley:
        mb.add_wrap_cylinder("upper", "pulley", radius=R_PULLEY, length=0.2, quadrant="-x")
        wraps = ("pulley",)
    mb.add_muscle("cyl", [("upper", o), ("lower", i)], wraps=wraps)
    mb.write(tmp_path / "cyl.osim")
    verts, faces = tube(i, o, RHO)
    trimesh.Trimesh(verts, faces, process=False).export(tmp_path / "cyl.ply")
    q = np.deg2rad(np.asarray(q_deg, float))
    write_sto(tmp_path / "sweep.mot", np.arange(len(q)) * 0.01, {"q": q})
    (tmp_path / "cyl.toml").write_text(textwrap.dedent(f"""
        model = "cyl.osim"
        motion = "sweep.mot"
        [muscles.cyl]
        action_lines = ["cyl"]
        mesh = "cyl.ply"
        frame = "ground"
        rest_pose = {{ q = 0.0 }}
        template = "parallel"
        fibres = {fibres}
        resolution = {resolution}
        origin = {{ body = "upper", points = {disc(o, 0.6 * RHO).tolist()} }}
        insertion = {{ body = "lower", points = {disc(i, 0.6 * RHO).tolist()} }}
        """))
    return tmp_path / "cyl.toml"


def _rz(q):
    c, s = np.cos(q), np.sin(q)
    out = np.zeros(np.shape(q) + (3, 3))
    out[..., 0, 0], out[..., 0, 1], out[..., 1, 0], out[..., 1, 1], out[..., 2, 2] = c, -s, s, c, 1.0
    return out


def _straight(tmp_path):
    q_deg = np.arange(0, 61, 6)          # frame 0 is the rest pose
    res = run(build_model(tmp_path, pulley=False, q_deg=q_deg))
    m = res.muscle("cyl")
    q = res.coordinate_values("q")
    p0 = m.fibre_points[0, :, 0]           # (N, 3) origin ends at rest (upper body = ground)
    p1 = m.fibre_points[0, :, -1]          # insertion ends at rest (lower body = ground at q=0)
    p1q = np.einsum("fij,nj->fni", _rz(q), p1)                   # carried by the lower body
    d = np.linalg.norm(p0[None] - p1q, axis=-1)                  # (F, N) closed-form length
    # d d/dq = (p1q - p0) . (e_z x p1q) / d ; r = -d d/dq
    r_closed = -np.einsum("fni,fni->fn", p1q - p0[None], np.cross([0.0, 0.0, 1.0], p1q)) / d
    return res, m, q, p0, p1q, d, r_closed


def test_straight_cylinder_fibre_ends_ride_their_bodies_and_action_line_is_exact(tmp_path):
    res, m, q, p0, p1q, d, r_closed = _straight(tmp_path)
    assert m.coordinates == ("q",)
    # fibre ends lie in the rigid attachment zones: they ride their bodies (to round-off)
    np.testing.assert_allclose(m.fibre_points[:, :, 0], np.broadcast_to(p0, p1q.shape), atol=1e-12)
    np.testing.assert_allclose(m.fibre_points[:, :, -1], p1q, atol=1e-12)
    # a polyline is never shorter than its chord
    assert (m.fibre_lengths >= d * (1 - 1e-12)).all()
    # the action line (exact, from motion) is the closed form through the two path points
    o, i = np.array([C, A, 0.0]), np.array([C, -B, 0.0])
    iq = _rz(q) @ i
    dl = np.linalg.norm(o - iq, axis=-1)
    np.testing.assert_allclose(m.action_line_lengths[:, 0], dl, rtol=1e-12)
    r_line = -np.einsum("fi,fi->f", iq - o, np.cross([0.0, 0.0, 1.0], iq)) / dl
    np.testing.assert_allclose(m.action_line_moment_arms[:, 0, 0], r_line, rtol=1e-9)


def test_straight_cylinder_fibres_are_the_rigid_chord(tmp_path):
    res, m, q, p0, p1q, d, r_closed = _straight(tmp_path)
    # 0.1 %: a straight fibre of the re-straightened cylinder is its chord
    np.testing.assert_allclose(m.fibre_lengths, d, rtol=1e-3)
    # 1 %: the finite-difference chain vs the exact derivative of the closed form
    np.testing.assert_allclose(m.fibre_moment_arms[:, :, 0], r_closed, rtol=1e-2)


def _wrapped(q):
    """The path wraps (quadrant -x) once the straight segment from the origin to the rotated
    insertion would come closer than R to the axis on the -x side or cross to the +x side:
    the signed distance of the axis from the segment's line drops below R."""
    x = -(R_PULLEY + RHO)
    o = np.array([x, A, 0.0])
    d = _rz(q) @ np.array([x, -B, 0.0]) - o
    signed = (o[0] * d[:, 1] - o[1] * d[:, 0]) / np.linalg.norm(d, axis=-1)
    return signed < R_PULLEY


def _pulley(tmp_path):
    q_deg = np.arange(0, 121, 10)
    res = run(build_model(tmp_path, pulley=True, q_deg=q_deg, fibres=24, resolution=40))
    return res, res.muscle("cyl"), res.coordinate_values("q")


def test_pulley_action_line_lengthens_by_r_dq_while_wrapped(tmp_path):
    res, m, q = _pulley(tmp_path)
    wrapped = _wrapped(q)
    assert wrapped[1:].all() and not wrapped[0]
    # wrapped on a cylinder about the joint axis, both tangent lengths are constant and the
    # arc grows by R dq: dL/dq = R exactly (10-degree differences of exact lengths)
    dl = np.diff(m.action_line_lengths[:, 0])[wrapped[:-1]] / np.deg2rad(10.0)
    np.testing.assert_allclose(dl, R_PULLEY, rtol=1e-6)
    # the fibres, on average, follow the action line over the pulley (the belly's mean fibre
    # sits on the line): the median fibre moment arm is -R within 5 %
    deep = q >= np.deg2rad(60)
    np.testing.assert_allclose(np.median(m.fibre_moment_arms[deep, :, 0], axis=1), -R_PULLEY, rtol=0.05)


def test_pulley_moment_arms_are_the_radius_plus_the_fibre_offset(tmp_path):
    res, m, q = _pulley(tmp_path)
    wrapped = _wrapped(q)
    # the action line wraps the pulley: r = -dL/dq = -R (the path lengthens as q grows)
    np.testing.assert_allclose(m.action_line_moment_arms[wrapped, 0, 0], -R_PULLEY, rtol=1e-6)
    # each fibre: r = -(its radius about the pulley axis where it crosses the pulley); the
    # radius is measured on the fibre's vertices (xy distance to the axis, the closest one)
    deep = q >= np.deg2rad(60)           # well wrapped: several fibre vertices lie on the arc
    pts = m.fibre_points[deep]           # (F', N, P, 3)
    rho = np.linalg.norm(pts[..., :2], axis=-1).min(-1)          # (F', N)
    # 2 % of R: the vertex sampling of the radius (40 segments: the closest vertex is up to ~0.5 %
    # of R farther out than the fibre's lowest point), the chords of the length polyline (the
    # length is measured on LENGTH_SUBDIVISION = 2 carried points per segment; with one, the
    # growing chords on the arc alone made r 1.5 % of rho short: measured 3.2 % of R in all),
    # and the fibres' radius drift with the volume-preserving scale. Measured max 1.06 % of R.
    np.testing.assert_allclose(m.fibre_moment_arms[deep, :, 0], -rho, atol=0.02 * R_PULLEY)


@pytest.mark.parametrize("pulley", [False, True])
def test_fd_moment_arms_agree_with_a_2_degree_difference_quotient(tmp_path, pulley):
    """Smoothness: on a 1-degree sweep, r from h = 1e-4 rad and from the 2-degree central
    quotient of the frame lengths agree within 5 % for >= 95 % of fibres (interior frames)."""
    q_deg = np.arange(20, 41, 1) if pulley else np.arange(0, 21, 1)
    res = run(build_model(tmp_path, pulley=pulley, q_deg=q_deg, fibres=24, resolution=20))
    m = res.muscle("cyl")
    L = m.fibre_lengths
    r_quot = -(L[2:] - L[:-2]) / np.deg2rad(2.0)
    r_fd = m.fibre_moment_arms[1:-1, :, 0]
    ok = np.abs(r_fd - r_quot) <= 0.05 * np.abs(r_quot)
    assert ok.mean() >= 0.95, f"only {ok.mean():.1%} agree"


def test_length_points_cut_each_rest_segment_into_equal_pieces():
    """The extra carried points lie on the rest segments: the original points are every m-th,
    each segment is cut into m equal pieces and the rest length is unchanged (round-off)."""
    from analysis.fibre_transport import _subdivided, fibre_lengths

    pts = np.random.default_rng(5).normal(size=(4, 6, 3))
    fine = _subdivided(pts, 3)
    assert fine.shape == (4, 16, 3)
    np.testing.assert_array_equal(fine[:, ::3], pts)
    np.testing.assert_allclose(fine[:, 1::3], pts[:, :-1] + (pts[:, 1:] - pts[:, :-1]) / 3, atol=1e-15)
    np.testing.assert_allclose(fine[:, 2::3], pts[:, :-1] + 2 * (pts[:, 1:] - pts[:, :-1]) / 3, atol=1e-15)
    np.testing.assert_allclose(fibre_lengths(fine), fibre_lengths(pts), rtol=1e-14)
    assert _subdivided(pts, 1) is pts or np.array_equal(_subdivided(pts, 1), pts)
