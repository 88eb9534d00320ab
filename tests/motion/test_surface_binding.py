"""Surface binding on synthetic arrays: a cylinder muscle between two bodies across a pin joint."""
from __future__ import annotations

import numpy as np
import pytest

from motion.surface.bind import bind_surface
from motion.surface.binding import smoothstep
from motion.surface.collision import WrapObstacle
from motion.surface.curves import resample_polylines, rotation_minimizing_frames
from motion.surface.generate import fusiform_surface
from motion.surface.volume import mesh_volume, solve_radial_scale, volume_cubic

from meshes import capped_tube

LENGTH, RADIUS = 0.2, 0.02


def capped_cylinder(length=LENGTH, radius=RADIUS, n_around=64, n_rings=41):
    """Closed cylinder along +x from 0 to ``length`` with flat caps (outward faces)."""
    return capped_tube([0.0, 0.0, 0.0], [length, 0.0, 0.0], radius, n_around=n_around, n_rings=n_rings,
                       ref=[0.0, 1.0, 0.0])


def rot_z(theta):
    c, s = np.cos(theta), np.sin(theta)
    tf = np.tile(np.eye(4), (len(theta), 1, 1))
    tf[:, 0, 0], tf[:, 0, 1], tf[:, 1, 0], tf[:, 1, 1] = c, -s, s, c
    return tf


def pin_about(point, theta):
    """Pose (F, 4, 4) of a body turning by ``theta`` about the z axis through ``point``."""
    shift, back = np.eye(4), np.eye(4)
    shift[:3, 3], back[:3, 3] = point, -np.asarray(point)
    return shift @ rot_z(theta) @ back


@pytest.fixture(scope="module")
def pin_cylinder():
    verts, faces = capped_cylinder()
    origin, insertion = np.zeros(3), np.array([LENGTH, 0.0, 0.0])
    theta = np.deg2rad(np.linspace(-30, 90, 25))
    tf_ins = pin_about([0.12, 0.03, 0.0], theta)
    tf_org = np.tile(np.eye(4), (len(theta), 1, 1))
    ins_now = tf_ins[:, :3, :3] @ insertion + tf_ins[:, :3, 3]
    line = np.stack([np.broadcast_to(origin, ins_now.shape), ins_now], axis=1)
    binding = bind_surface(verts, faces, [np.array([origin, insertion])], np.eye(4), np.eye(4),
                           origin[None], insertion[None])
    return binding, binding.deform([line], tf_org, tf_ins), line


def test_straight_cylinder_stays_a_cylinder(pin_cylinder):
    binding, result, line = pin_cylinder
    belly = binding.weight_belly > 1 - 1e-12
    assert belly.sum() > 0.3 * len(belly)
    u = line[:, 1] - line[:, 0]
    length = np.linalg.norm(u, axis=-1)
    u = u / length[:, None]
    rel = result.vertices - line[:, :1]
    along = np.einsum("fvk,fk->fv", rel, u)
    radial = np.linalg.norm(rel - along[..., None] * u[:, None], axis=-1)
    # the belly's side wall (cap centres are not in the belly): one radius per frame
    wall = belly[None] & (radial > 0.5 * RADIUS)
    r_mean = np.array([radial[f][wall[f]].mean() for f in range(len(line))])
    err = np.max(np.abs(radial - r_mean[:, None]) * wall, axis=1) / RADIUS
    # the 64-gon wall is exact; rigid caps do not enter the belly set -> 1 % of the radius is generous
    assert err.max() < 0.01, err.max()
    # cross-section follows the stretch of the line as volume preservation predicts, roughly
    # (rigid caps keep their size): r ~ k * RADIUS with k the solved scale
    np.testing.assert_allclose(r_mean, result.radial_scale * RADIUS, rtol=2e-3)
    assert np.abs(result.volume_error).max() < 1e-9  # exact cubic solve; 0.5 % is the requirement


def test_rest_pose_reproduces_rest_surface(pin_cylinder):
    binding, _, _ = pin_cylinder
    origin, insertion = np.zeros(3), np.array([LENGTH, 0.0, 0.0])
    line = np.array([[origin, insertion]])
    out = binding.deform([line], np.eye(4)[None], np.eye(4)[None])
    np.testing.assert_allclose(out.vertices[0], binding.rest_vertices, atol=1e-12)
    np.testing.assert_allclose(out.radial_scale, 1.0, atol=1e-12)


def test_attachment_regions_are_rigid(pin_cylinder):
    binding, result, _ = pin_cylinder
    theta = np.deg2rad(np.linspace(-30, 90, 25))
    tf_ins = pin_about([0.12, 0.03, 0.0], theta)
    rigid_i = binding.weight_insertion > 1 - 1e-12
    rigid_o = binding.weight_origin > 1 - 1e-12
    assert rigid_i.any() and rigid_o.any()
    expect = np.einsum("fij,vj->fvi", tf_ins[:, :3, :3], binding.rest_vertices[rigid_i]) + tf_ins[:, None, :3, 3]
    np.testing.assert_allclose(result.vertices[:, rigid_i], expect, atol=1e-9)
    np.testing.assert_allclose(result.vertices[:, rigid_o], binding.rest_vertices[rigid_o][None].repeat(25, 0),
                               atol=1e-9)


def test_smooth_in_the_joint_angle():
    verts, faces = capped_cylinder(n_around=32, n_rings=21)
    origin, insertion = np.zeros(3), np.array([LENGTH, 0.0, 0.0])
    binding = bind_surface(verts, faces, [np.array([origin, insertion])], np.eye(4), np.eye(4),
                           origin[None], insertion[None])
    h = 1e-4
    theta = np.array([0.5 - 2 * h, 0.5 - h, 0.5, 0.5 + h, 0.5 + 2 * h])
    tf = pin_about([0.12, 0.03, 0.0], theta)
    ins_now = tf[:, :3, :3] @ insertion + tf[:, :3, 3]
    line = np.stack([np.broadcast_to(origin, ins_now.shape), ins_now], axis=1)
    v = binding.deform([line], np.tile(np.eye(4), (5, 1, 1)), tf).vertices
    # second differences are O(h^2): a jump would show as O(1) * h
    second = np.abs(v[:-2] - 2 * v[1:-1] + v[2:]).max()
    first = np.abs(v[2:] - v[:-2]).max()
    assert second < 1e-3 * first, (second, first)


def test_free_vertices_follow_the_belly_not_the_rigid_zones(pin_cylinder):
    """A rider (face-less extra vertex marked free) has no rigid zone: a copy of a vertex deep in
    the insertion's rigid zone moves on the straight line's belly formula instead,
    c(s) + k (x N + y B) with N, B the line's frame turned with the line, not with the body."""
    binding, result, line = pin_cylinder
    verts, faces = capped_cylinder()
    near_end = np.array([[LENGTH - 0.002, 0.01, 0.0], [0.1, 0.0, 0.015]])   # 2 mm from the insertion cap; mid-belly
    both = np.vstack([verts, near_end])
    origin, insertion = np.zeros(3), np.array([LENGTH, 0.0, 0.0])
    free = bind_surface(both, faces, [np.array([origin, insertion])], np.eye(4), np.eye(4), origin[None],
                        insertion[None], free_vertices=[len(verts), len(verts) + 1])
    assert free.weight_insertion[len(verts)] == 0.0 and free.weight_belly[len(verts)] == 1.0
    theta = np.deg2rad(np.linspace(-30, 90, 25))
    out = free.deform([line], np.tile(np.eye(4), (25, 1, 1)), pin_about([0.12, 0.03, 0.0], theta))
    # the surface itself is unchanged by the riders (faces do not use them)
    np.testing.assert_allclose(out.vertices[:, :len(verts)], result.vertices, atol=1e-12)
    # closed form for a straight line: arc fraction t = x / LENGTH, frame turned by the line's angle
    u = line[:, 1] - line[:, 0]
    phi = np.arctan2(u[:, 1], u[:, 0])
    k = result.radial_scale
    for p, got in zip(near_end, out.vertices[:, len(verts):].transpose(1, 0, 2)):
        t = p[0] / LENGTH
        n = np.stack([-np.sin(phi), np.cos(phi), np.zeros_like(phi)], axis=1)
        expect = line[:, 0] + t * u + k[:, None] * (p[1] * n + p[2] * np.array([0.0, 0.0, 1.0]))
        np.testing.assert_allclose(got, expect, atol=1e-12)


def test_volume_cubic_matches_direct_volume():
    rng = np.random.default_rng(0)
    verts, faces = capped_cylinder(n_around=16, n_rings=5)
    p = 0.3 * verts[None] + 0.001 * rng.standard_normal((3,) + verts.shape)
    q = 0.7 * verts[None] + 0.001 * rng.standard_normal((3,) + verts.shape)
    c = volume_cubic(p, q, faces)
    for k in (0.5, 1.0, 1.7):
        np.testing.assert_allclose(c @ [1, k, k * k, k ** 3], mesh_volume(p + k * q, faces), rtol=1e-12)
    k = solve_radial_scale(c, mesh_volume(verts, faces))
    np.testing.assert_allclose(mesh_volume(p + k[:, None, None] * q, faces), mesh_volume(verts, faces), rtol=1e-12)


def test_rmf_of_a_helix_has_no_twist_rate():
    # the RMF of a helix turns about the tangent at rate -tau*s relative to Frenet: check the
    # defining property instead: dN/ds has no binormal component (Bishop 1975)
    s = np.linspace(0, 4 * np.pi, 2001)
    helix = np.stack([np.cos(s), np.sin(s), 0.5 * s], -1)[None]
    fr = rotation_minimizing_frames(helix, np.array([[0.0, 0.0, 1.0]]))[0]
    dn = np.diff(fr[:, :, 0], axis=0)
    mid_b = 0.5 * (fr[1:, :, 1] + fr[:-1, :, 1])
    assert np.abs(np.sum(dn * mid_b, axis=-1)).max() < 1e-7


def test_resample_ignores_nan_padding():
    pts = np.array([[[0, 0, 0], [1, 0, 0], [1, 1, 0], [np.nan] * 3],
                    [[0, 0, 0], [2, 0, 0], [np.nan] * 3, [np.nan] * 3]], float)
    out = resample_polylines(pts, 5)
    np.testing.assert_allclose(out[0, 2], [1, 0, 0])
    np.testing.assert_allclose(out[1, :, 0], [0, 0.5, 1, 1.5, 2])


def test_pulley_push_out_keeps_outside_and_volume():
    # a straight cylinder muscle bent over a fixed pulley of radius R at the joint
    radius_p = 0.015
    verts, faces = capped_cylinder(n_around=32, n_rings=41)
    verts = verts + [0.0, radius_p + RADIUS, 0.0]   # muscle rests on top of the pulley axis (z)
    origin = np.array([0.0, radius_p + RADIUS, 0])
    insertion = origin + [LENGTH, 0, 0]
    binding = bind_surface(verts, faces, [np.array([origin, insertion])], np.eye(4), np.eye(4),
                           origin[None], insertion[None])
    theta = np.deg2rad([0.0, 60.0, 120.0])
    centre = np.array([0.1, 0.0, 0.0])
    tf_ins = pin_about(centre, theta)
    # current line: bent around a circle of radius (radius_p + RADIUS) about the pulley centre
    n = 60
    ang = np.linspace(0, 1, n)
    lines = []
    for th in theta:  # three frames of test data
        left = np.linspace(origin, centre + [0, radius_p + RADIUS, 0], 10)
        arc = centre + (radius_p + RADIUS) * np.stack([-np.sin(th * ang), np.cos(th * ang), 0 * ang], -1)
        end = tf_ins[0, :3, :3] @ insertion + tf_ins[0, :3, 3]
        tf = pin_about(centre, np.array([th]))[0]
        end = tf[:3, :3] @ insertion + tf[:3, 3]
        right = np.linspace(arc[-1], end, 10)
        lines.append(np.concatenate([left, arc[1:], right[1:]]))
    line = np.stack(lines)
    tf_pulley = np.eye(4)
    tf_pulley[:3, 3] = centre
    pulley = WrapObstacle("cylinder", tf_pulley, np.array([radius_p, radius_p, np.inf]), margin=5e-4)
    result = binding.deform([line], np.tile(np.eye(4), (3, 1, 1)), tf_ins, obstacles=[pulley])
    rad = np.linalg.norm((result.vertices - centre)[..., :2], axis=-1)
    assert rad.min() > radius_p - 1e-4
    assert np.abs(result.volume_error).max() < 5e-3


def test_fusiform_surface_closed_with_requested_volume():
    trimesh = pytest.importorskip("trimesh")
    line = np.array([[0, 0, 0], [0.1, 0.02, 0], [0.25, 0.0, 0.01]])
    v, f = fusiform_surface(line, volume=1.2e-4)
    mesh = trimesh.Trimesh(v, f, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert abs(mesh.volume / 1.2e-4 - 1) < 1e-9
    np.testing.assert_allclose(v[0], line[0])
    np.testing.assert_allclose(v[-1], line[-1])


def test_smoothstep_is_c2_at_the_ends():
    x = np.array([0.0, 1.0])
    h = 1e-4
    d1 = (smoothstep(x + h) - smoothstep(x - h)) / (2 * h)
    assert np.abs(d1).max() < 1e-6


def test_obstacles_push_and_the_volume_is_kept():
    # the obstacles (numpy: motion.surface.collision) move the surface; the volume correction
    # (motion.surface.volume) still restores the rest volume
    verts, faces = capped_cylinder(n_around=16, n_rings=11)
    origin, insertion = np.zeros(3), np.array([LENGTH, 0.0, 0.0])
    binding = bind_surface(verts, faces, [np.array([origin, insertion])], np.eye(4), np.eye(4),
                           origin[None], insertion[None])
    theta = np.deg2rad([0.0, 40.0, 80.0])
    tf = pin_about([0.12, 0.03, 0.0], theta)
    ins = tf[:, :3, :3] @ insertion + tf[:, :3, 3]
    line = np.stack([np.broadcast_to(origin, ins.shape), ins], axis=1)
    tf_obs = np.eye(4)
    tf_obs[:3, 3] = [0.12, -0.037, 0.0]   # overlaps the muscle's underside by a few mm
    obstacles = [WrapObstacle("sphere", tf_obs, np.full(3, 0.02)),
                 WrapObstacle("ellipsoid", tf_obs, np.array([0.01, 0.025, 0.015]))]
    compiled = binding.deform([line], np.tile(np.eye(4), (3, 1, 1)), tf, obstacles=obstacles)
    free = binding.deform([line], np.tile(np.eye(4), (3, 1, 1)), tf)
    assert np.abs(compiled.vertices - free.vertices).max() > 1e-3   # the obstacles did push
    assert np.abs(compiled.volume_error).max() < 1e-6
    np.testing.assert_allclose(compiled.volume, free.volume, rtol=1e-6)


def _squeeze_on_cylinder(h, t, y=0.005, radius=0.02, margin=5e-4):
    """Offsets (-t, 0, y) from centres at clearance h outside a z-axis cylinder, squeezed."""
    pulley = WrapObstacle("cylinder", np.eye(4), np.array([radius, radius, np.inf]), margin=margin)
    centres = np.zeros((1, len(t), 3))
    centres[..., 0] = radius + h
    offsets = np.stack([-t, np.zeros_like(t), np.full_like(t, y)], axis=-1)[None]
    return centres, offsets, pulley.squeezer(centres)(offsets)


def test_squeeze_flattens_layers_in_order_into_the_room_left():
    from motion.surface.collision import SQUEEZE_KNEE

    h, radius, margin = 0.004, 0.02, 5e-4
    room = h - margin                             # down to the push-out shell
    t = np.linspace(-0.01, 0.03, 4001)            # inward depth of the offset (m)
    centres, offsets, out = _squeeze_on_cylinder(h, t, radius=radius, margin=margin)
    depth = -out[0, :, 0]
    # offsets reaching less than the knee fraction of the room (and all outward ones) are kept
    keep = t <= SQUEEZE_KNEE * room
    np.testing.assert_array_equal(out[0, keep], offsets[0, keep])
    # the squeezed vertices stay outside the push-out shell, in their order, at their height
    assert (depth < room).all()
    assert (np.diff(depth) > 0).all()
    assert (np.linalg.norm((centres + out)[0, :, :2], axis=-1) > radius + margin).all()
    np.testing.assert_array_equal(out[0, :, 1:], offsets[0, :, 1:])
    # C1 at the knee: the slope is 1 on both sides (one-sided differences, step 1e-5 m: the
    # curvature beyond the knee is 1 / ((1 - a) h) ~ 360 /m, so the slope changes by < 0.4 %)
    knee = SQUEEZE_KNEE * room
    s = 1e-5
    t3 = np.array([knee - s, knee, knee + s])
    d3 = -_squeeze_on_cylinder(h, t3, radius=radius)[2][0, :, 0]
    np.testing.assert_allclose(np.diff(d3) / s, 1.0, rtol=5e-3)
    # a centre on the surface (or inside, as chords of an arc are): everything pointing in,
    # or out by less than the shell, goes onto the shell's outer face; farther out stays
    for h0 in (0.0, -3e-4):
        t0 = np.array([-0.005, -1e-4, 0.001, 0.01])
        out0 = _squeeze_on_cylinder(h0, t0, radius=radius, margin=margin)[2][0]
        np.testing.assert_allclose(-out0[:, 0], [-0.005, h0 - margin, h0 - margin, h0 - margin], atol=1e-15)


def test_squeeze_moves_offsets_on_every_obstacle_kind():
    rng = np.random.default_rng(3)
    tf = np.tile(np.eye(4), (2, 1, 1))
    tf[1] = rot_z([0.7])[0]
    tf[:, :3, 3] = [0.01, -0.02, 0.0]
    centres = rng.normal(scale=0.03, size=(2, 500, 3))
    offsets = rng.normal(scale=0.01, size=(2, 500, 3))
    for obstacle in (WrapObstacle("cylinder", tf, np.array([0.02, 0.02, 0.05])),
                     WrapObstacle("sphere", tf, np.full(3, 0.02)),
                     WrapObstacle("ellipsoid", tf, np.array([0.01, 0.025, 0.015]))):
        compiled = obstacle.squeezer(centres)(offsets)
        assert np.abs(compiled - offsets).max() > 1e-3        # something was squeezed
        assert np.isfinite(compiled).all()


def test_riders_must_be_trailing_face_less_vertices():
    from motion.surface.spec import MuscleSurfaceSpec

    verts, faces = capped_cylinder()
    both = np.vstack([verts, np.zeros((3, 3))])
    assert MuscleSurfaceSpec("m", ("line",), vertices=both, faces=faces, riders=3).riders == 3
    for bad in (4, -1, len(both) + 1):        # 4: the last surface vertex is used by a face
        with pytest.raises(ValueError, match="riders"):
            MuscleSurfaceSpec("m", ("line",), vertices=both, faces=faces, riders=bad)


def test_riders_placed_once_at_the_final_scale_are_the_same_numbers():
    """With obstacles, the secant steps on k move only the vertices the faces use; face-less
    riders are placed once at the final k. Every step acts on each vertex alone, so a rider that
    copies a mid-belly surface vertex lands exactly on it, the surface is exactly the surface
    deformed without riders, and an obstacle without ``leading`` (full passes) gives the same."""
    radius_p = 0.015
    verts, faces = capped_cylinder(n_around=32, n_rings=41)
    verts = verts + [0.0, radius_p + 0.5 * RADIUS, 0.0]        # half the thickness inside the pulley
    origin = np.array([0.0, radius_p + 0.5 * RADIUS, 0])
    insertion = origin + [LENGTH, 0, 0]
    theta = np.deg2rad([20.0, 60.0, 100.0])
    centre = np.array([0.1, 0.0, 0.0])
    tf_ins = pin_about(centre, theta)
    line = np.stack([origin + 0 * theta[:, None], tf_ins[:, :3, :3] @ insertion + tf_ins[:, :3, 3]], axis=1)
    tf_pulley = np.eye(4)
    tf_pulley[:3, 3] = centre
    pulley = WrapObstacle("cylinder", tf_pulley, np.array([radius_p, radius_p, np.inf]), margin=5e-4)
    ends = (np.eye(4), np.eye(4), origin[None], insertion[None])
    plain = bind_surface(verts, faces, [np.array([origin, insertion])], *ends)
    mid = np.flatnonzero((plain.weight_belly == 1.0) & (np.abs(verts[:, 0] - 0.1) < 0.03))
    assert len(mid) > 10
    riding = bind_surface(np.vstack([verts, verts[mid]]), faces, [np.array([origin, insertion])], *ends,
                          free_vertices=np.arange(len(verts), len(verts) + len(mid)))
    tf_org = np.tile(np.eye(4), (3, 1, 1))
    ref = plain.deform([line], tf_org, tf_ins, obstacles=[pulley])
    got = riding.deform([line], tf_org, tf_ins, obstacles=[pulley])

    class Full:   # the same obstacle without `leading`: every pass over all vertices
        squeezer, push_out = pulley.squeezer, pulley.push_out

    full = riding.deform([line], tf_org, tf_ins, obstacles=[Full()])
    squeezed = np.linalg.norm((ref.vertices[:, mid] - centre)[..., :2], axis=-1) < radius_p + 0.5 * RADIUS
    assert squeezed.any()                                     # the squeeze and push did act on them
    np.testing.assert_array_equal(got.vertices[:, :len(verts)], ref.vertices)
    np.testing.assert_array_equal(got.radial_scale, ref.radial_scale)
    np.testing.assert_array_equal(got.vertices[:, len(verts):], ref.vertices[:, mid])
    np.testing.assert_array_equal(full.vertices, got.vertices)


def test_bone_obstacle_leading_is_the_first_vertices():
    """`BoneObstacle.leading(n)` pushes the first n vertices exactly as the whole obstacle does."""
    import trimesh

    from motion.surface.bone_obstacles import BoneDistance, BoneObstacle

    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.02)
    dist = BoneDistance.from_mesh(ball.vertices, ball.faces, spacing=2e-3)
    rng = np.random.default_rng(3)
    rest = rng.normal(size=(60, 3))
    rest *= (0.021 + 0.01 * rng.random(60))[:, None] / np.linalg.norm(rest, axis=1, keepdims=True)
    tf = np.tile(np.eye(4), (2, 1, 1))
    obstacle = BoneObstacle.bind(dist, tf, rest, np.eye(4))
    now = np.stack([rest * 0.9, rest * 0.8])                  # pressed into the ball
    whole = obstacle.push_out(now)
    assert np.abs(whole - now).max() > 1e-3
    np.testing.assert_array_equal(obstacle.leading(40).push_out(now[:, :40]), whole[:, :40])


def test_riders_apart_without_obstacles_are_the_surface_deformation(pin_cylinder):
    """Without obstacles the riders apart are ``P + k Q`` from one product of their rows of
    ``[fixed | radial]`` with the radial features scaled by ``k``: the same sums as the surface's
    own, so riders copying surface vertices land on the deformed vertices (to round-off), the
    surface and ``k`` are those of the binding without riders, and ``keep_vertices`` keeps the
    first frames' surface only."""
    binding, result, line = pin_cylinder
    verts, faces = binding.rest_vertices, binding.faces
    pick = np.flatnonzero(binding.weight_belly == 1.0)[::7]
    assert len(pick) > 20
    rest_line = np.array([[0.0, 0.0, 0.0], [LENGTH, 0.0, 0.0]])       # as bound in `pin_cylinder`
    riding = bind_surface(np.vstack([verts, verts[pick]]), faces, [rest_line], np.eye(4), np.eye(4),
                          rest_line[:1], rest_line[1:],
                          free_vertices=np.arange(len(verts), len(verts) + len(pick)))
    tf_org = np.tile(np.eye(4), (len(line), 1, 1))
    tf_ins = pin_about([0.12, 0.03, 0.0], np.deg2rad(np.linspace(-30, 90, 25)))
    got = riding.deform([line], tf_org, tf_ins, riders_apart=len(pick), keep_vertices=4)
    assert got.vertices.shape == (4,) + verts.shape and got.riders.shape == (len(pick), len(line), 3)
    np.testing.assert_allclose(got.radial_scale, result.radial_scale, rtol=0, atol=1e-14)
    np.testing.assert_allclose(got.vertices, result.vertices[:4], rtol=0, atol=1e-15)
    np.testing.assert_allclose(got.riders.transpose(1, 0, 2), result.vertices[:, pick], rtol=0, atol=1e-15)


@pytest.mark.parametrize("kind, radii", [("cylinder", (0.02, 0.02, 0.05)), ("cylinder", (0.02, 0.02, np.inf)),
                                         ("sphere", (0.025,) * 3), ("ellipsoid", (0.03, 0.02, 0.015))])
def test_push_out_is_the_soft_floor_along_the_obstacles_direction(kind, radii):
    """The compiled push-out (`collision._push_loop`) moves every vertex as the module docstring
    says, written here with the obstacle's own distance and direction (`_distance_direction`,
    which the squeeze uses) and `soft_floor`: along n by g(d + inset) - (d + inset), times the
    window; the ellipsoid radially in its scaled space. Random vertices around the object, many
    of them inside its margin, per-vertex insets, one pose per frame and one for all."""
    from scipy.spatial.transform import Rotation

    from motion.surface.collision import soft_floor, to_obstacle_frame

    rng = np.random.default_rng(4)
    n_f, n_v = 5, 400
    tf = np.tile(np.eye(4), (n_f, 1, 1))
    tf[:, :3, :3] = Rotation.random(n_f, random_state=5).as_matrix()
    tf[:, :3, 3] = rng.normal(0.0, 0.01, (n_f, 3))
    v = rng.normal(0.0, 0.03, (n_f, n_v, 3))
    inset = rng.uniform(0.0, 0.004, n_v)
    for pose in (tf, tf[0]):
        obstacle = WrapObstacle(kind, pose, np.array(radii), 5e-4, inset)
        p = to_obstacle_frame(pose, v)
        d, n, window = obstacle._distance_direction(p)
        move = (soft_floor(d + inset, 5e-4) - d - inset) * window
        if kind == "ellipsoid":
            scaled = p / obstacle.radii
            rad = np.linalg.norm(scaled, axis=-1)
            delta = scaled * (((d + move) / obstacle.radii.min() + 1.0) / rad)[..., None] * obstacle.radii - p
        else:
            delta = move[..., None] * n
        rot = np.broadcast_to(pose[..., :3, :3], (n_f, 3, 3))
        want = v + np.einsum("fij,fvj->fvi", rot, delta)
        got = obstacle.push_out(v)
        assert (move != 0).mean() > 0.2                       # the check moves many vertices
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)
        assert np.array_equal(got[move == 0], v[move == 0])   # outside the margin: untouched
