"""How the rest fibres of `analysis.run` reach every frame, and their lengths there.

Fibres: ``fibres.decompose`` once on the rest-pose surface, which fixes the decomposition plan
(box orientation, slicing, contour starts, template parameters of every fibre). Then, per
frame, one of two ``transport`` modes:

- ``"bind"`` (default): the rest fibres are bound to the action lines like the surface's
  own belly (they are handed to ``motion.wrap_surfaces`` as ``riders``, face-less extra
  vertices of the rest surface), so the same smooth deformation moves the surface and its
  fibres, as Kohout et al. ("Real-time modelling of fibrous muscle", Computer Graphics Forum
  2014) deform the fibres with the muscle. Fibre k is by construction the same material
  fibre in every frame, and all frames cost one call (no decomposition per frame). The
  fibre ends are attachment points: they ride their bones exactly. Each fibre's interior is
  then corrected by the end residuals spread linearly in its rest arc-length fraction u,

      p'(u) = b(p(u)) + (1 - u) [T_o p(0) - b(p(0))] + u [T_i p(1) - b(p(1))],

  with ``b`` the belly deformation and ``T_o``, ``T_i`` the origin and insertion body motions
  (each residual held in the belly's line frame at its end and carried along the fibre with
  those frames, `motion.WrappedSurface.rider_frames`: over a pulley a fibre keeps its offset
  from the line, so its moment arm is its own radius; on a straight line the frames are
  constant and this is the plain linear spread). A generated, tendon-aware surface
  (`motion.surface.tendons`) has its fibre ends on the belly's caps, riding the belly.
  Why not the surface's own rigid attachment zones: a zone turns the fibre's end piece with
  its body while the belly turns with the action line, which kinks every fibre next to its
  ends (a straight cylinder across a pin joint measured 0.33 % too long at 60 degrees). With
  the linear correction a straight fibre on a straight action line stays exactly the chord
  of its rigidly carried ends (``b`` is affine in u there), and where the line's end pieces
  are fixed on their bodies (most paths) the residuals vanish and fibres follow the surface.
- ``"decompose"``: the paper's procedure per frame, ``fibres.decompose(..., plan=plan)`` on
  every wrapped surface (slower; fibre identity then rests on the plan's consistency).

Per-fibre length = polyline arc length (sum of segment lengths). In ``"bind"`` mode it is
measured on a finer sampling of the same material fibre: every rest segment is cut into
``LENGTH_SUBDIVISION`` (2) pieces whose points are carried as riders too, and the reported
polylines are every second point (exactly the points a plain binding would give). Why: a
material polyline stretched over a wrap surface keeps its vertex count on the arc while its
chords grow, so its length grows at the chords' distance from the axis, rho cos(dphi / 2),
not at rho (dphi: the angle one chord subtends). On the pulley test of
``tests/analysis/test_run_cylinders.py`` (40 segments, dphi ~ 0.35 rad) that made fibre
moment arms up to 3.2 % of R short; with 2 pieces per segment 1.1 % (4: 1.2 %, the rest is
the radius drift with the volume scale and the vertex sampling of the radius). The length in
``fibre_lengths.csv`` is therefore the finer curve's, which can exceed the reported
polyline's own length by the difference of their chord deficits (where fibres bend; on the
pulley test up to 0.76 mm, 0.23 %, at 120 degrees of wrap; zero on straight pieces).

Both transports are set up once per muscle (`bind_transport`, `decompose_transport`) and then
carry the fibres over any number of poses, so `analysis.muscle_chain` can stream a long motion
through them in chunks of frames (bounded memory).
"""
from __future__ import annotations

import dataclasses

import numpy as np
from numba import njit

from . import interrupts

__all__ = ["TRANSPORTS", "LENGTH_SUBDIVISION", "Carried", "fibre_lengths", "bind_transport",
           "decompose_transport"]

#: how rest fibres reach every frame (module docstring)
TRANSPORTS = ("bind", "decompose")
#: ``"bind"`` transport: material points carried per rest fibre segment to measure its length
#: (module docstring); the reported polylines are every LENGTH_SUBDIVISION-th of them
LENGTH_SUBDIVISION = 2


@dataclasses.dataclass
class Carried:
    """The fibres at a batch of poses: ``points`` (K, N, P, 3) as reported at the first K poses
    (``carry(stacked, keep=K)``; all poses by default), ``lengths`` (F, N) (measured as the
    module docstring says), ``surfaces`` (K, V, 3) the wrapped surface at the first K poses and
    the wrapping's ``notes``."""

    points: np.ndarray
    lengths: np.ndarray
    surfaces: np.ndarray
    notes: tuple


def fibre_lengths(points) -> np.ndarray:
    """Polyline arc lengths.

    Parameters
    ----------
    points : (..., N, P, 3) float

    Returns
    -------
    (..., N) float
    """
    p = np.asarray(points, dtype=float)
    d = p[..., 1:, :] - p[..., :-1, :]
    # einsum, not np.linalg.norm: one temporary fewer
    return np.sqrt(np.einsum("...i,...i->...", d, d)).sum(-1)


def _with_points(att, p_ground, pose0, model, tf_data_ground):
    """``att`` (a `motion.SurfaceAttachment`) with its points replaced by the rest-pose points
    ``p_ground`` (K, 3), expressed in the attachment's own frame (the mesh frame or its body's)."""
    if att.in_body_frame:
        tf = np.linalg.inv(pose0.tf_ground_body[model.body_index(att.body)])
    else:
        tf = tf_data_ground
    return dataclasses.replace(att, points=p_ground @ tf[:3, :3].T + tf[:3, 3])


def _subdivided(points, m: int) -> np.ndarray:
    """Fibre polylines (N, P, 3) with every segment cut into ``m`` equal pieces: (N, m (P - 1) + 1, 3).

    The new points lie on the rest segments, so the rest length and every original point (each
    ``m``-th) are unchanged; carried by the deformation they sample the deformed material curve
    between the original points."""
    p = np.asarray(points, dtype=float)
    if m <= 1:
        return p
    t = np.arange(m) / m                                                         # (m,)
    inner = p[:, :-1, None] + t[None, None, :, None] * (p[:, 1:, None] - p[:, :-1, None])
    return np.concatenate([inner.reshape(p.shape[0], -1, 3), p[:, -1:]], axis=1)


def _ends_ride_their_bodies(carried, rest, origin_ends, insertion_ends, frames=None, *, keep=0,
                            every=LENGTH_SUBDIVISION):
    """Fibres carried by the belly deformation, rider-major (N, Q, F, 3), corrected so that their
    ends are ``origin_ends`` / ``insertion_ends`` (F, N, 3) (rigid with their bodies), the
    residuals spread linearly in each rest fibre's (N, Q, 3) arc-length fraction (module
    docstring), and measured: returns the lengths (F, N) of the corrected polylines and their
    every ``every``-th point (``keep``, N, Q', 3) at the first ``keep`` poses (the reported
    polylines).

    ``frames`` (N, Q, F, 3, 3), the belly's line frames at the fibre points (columns normal,
    binormal, tangent; `motion.WrappedSurface.rider_frames`): each end residual is then held in
    the frame at its end and carried along the fibre with the frames, so over a pulley a
    residual across the muscle stays across it instead of a fixed ground vector (where the
    frames are constant, on a straight line, it is the same correction).

    One pass over the points (`_carry_loop`, compiled): the corrected points of the
    perturbed poses are never stored, only their lengths."""
    seg = np.linalg.norm(np.diff(rest, axis=1), axis=-1)                      # (N, Q-1)
    u = np.concatenate([np.zeros((rest.shape[0], 1)), np.cumsum(seg, axis=1)], axis=1)
    u = u / np.maximum(u[:, -1:], 1e-300)                                      # (N, Q)
    n_n, n_q, n_f = carried.shape[:3]
    lengths = np.empty((n_f, n_n))
    points = np.empty((int(keep), n_n, (n_q - 1) // every + 1, 3))
    use = frames is not None
    dummy = np.zeros((1, 1, 1, 3, 3))
    _carry_loop(carried, np.asarray(origin_ends, dtype=float), np.asarray(insertion_ends, dtype=float), u,
                frames if use else dummy, use, int(every), lengths, points)
    return lengths, points


@njit(cache=True, nogil=True)
def _carry_loop(x, ends0, ends1, u, frames, use_frames, every, lengths, points):  # pragma: no cover
    """`_ends_ride_their_bodies` fibre by fibre, point by point, all poses at once (rider-major
    input read in order): the end residuals (in the line frames at the ends when
    ``use_frames``), the corrected points, their polyline lengths, and the kept points of the
    first ``points.shape[0]`` poses."""
    n_n, n_q, n_f = x.shape[0], x.shape[1], x.shape[2]
    keep = points.shape[0]
    last = n_q - 1
    e0 = np.empty((n_f, 3))
    e1 = np.empty((n_f, 3))
    prev = np.empty((n_f, 3))
    total = np.empty(n_f)
    y = np.empty(3)
    m = np.empty(3)
    for n in range(n_n):
        for f in range(n_f):
            for a in range(3):
                e0[f, a] = ends0[f, n, a] - x[n, 0, f, a]
                e1[f, a] = ends1[f, n, a] - x[n, last, f, a]
            if use_frames:           # residuals in the frames at the ends: local = R^T e
                r0, r1, r2 = e0[f, 0], e0[f, 1], e0[f, 2]
                s0, s1, s2 = e1[f, 0], e1[f, 1], e1[f, 2]
                for a in range(3):
                    e0[f, a] = frames[n, 0, f, 0, a] * r0 + frames[n, 0, f, 1, a] * r1 + frames[n, 0, f, 2, a] * r2
                    e1[f, a] = (frames[n, last, f, 0, a] * s0 + frames[n, last, f, 1, a] * s1
                                + frames[n, last, f, 2, a] * s2)
            total[f] = 0.0
        for j in range(n_q):
            w = u[n, j]
            for f in range(n_f):
                if j == 0:
                    for a in range(3):
                        y[a] = ends0[f, n, a]
                elif j == last:
                    for a in range(3):
                        y[a] = ends1[f, n, a]
                else:
                    for a in range(3):
                        m[a] = e0[f, a] + w * (e1[f, a] - e0[f, a])
                    if use_frames:
                        for a in range(3):
                            y[a] = x[n, j, f, a] + (frames[n, j, f, a, 0] * m[0] + frames[n, j, f, a, 1] * m[1]
                                                    + frames[n, j, f, a, 2] * m[2])
                    else:
                        for a in range(3):
                            y[a] = x[n, j, f, a] + m[a]
                if j > 0:
                    d0, d1, d2 = y[0] - prev[f, 0], y[1] - prev[f, 1], y[2] - prev[f, 2]
                    total[f] += np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                if f < keep and j % every == 0:
                    for a in range(3):
                        points[f, n, j // every, a] = y[a]
                for a in range(3):
                    prev[f, a] = y[a]
        for f in range(n_f):
            lengths[f, n] = total[f]


def bind_transport(model, sspec, rest, bundle0):
    """The ``"bind"`` transport of one muscle (module docstring): ``carry(stacked, keep=None,
    poses=None, frames=None)`` wraps the rest surface with the rest fibres' material points as
    riders at every pose of ``stacked`` (a `motion.Motion`; ``poses``: its `motion.BodyPoses`
    when already known; ``frames``: how many leading poses are frames, the others their
    moment-arm copies, `motion.surface.wrap.SurfaceWrapper.wrap`) and returns a `Carried` (the
    polylines of the first ``keep`` poses). The muscle is bound
    once (`motion.surface.wrap.SurfaceWrapper`), whatever the number of calls.

    ``sspec`` is the muscle's `motion.MuscleSurfaceSpec`, ``rest`` its surface wrapped at one
    frame (its rest geometry in ground), ``bundle0`` the rest-pose `fibres.FibreBundle`."""
    from motion.surface.rest import rest_pose
    from motion.surface.wrap import SurfaceWrapper

    shape = bundle0.points.shape                                  # (N, P, 3)
    n_v = rest.rest_vertices.shape[0]
    # rest surface + fibre points back to the mesh's own frame, wrapped together
    pose0 = rest_pose(model, sspec)
    tf_data_ground = np.linalg.inv(pose0.tf_ground_data)
    fine = _subdivided(bundle0.points, LENGTH_SUBDIVISION)          # (N, m (P - 1) + 1, 3)
    both = np.vstack([rest.rest_vertices, fine.reshape(-1, 3)])
    both = both @ tf_data_ground[:3, :3].T + tf_data_ground[:3, 3]
    # the fibre end points lie in the attachment areas by construction (Kohout 2012 §3.4):
    # bind them as attachment points too, so they ride their bones exactly
    # (a generated muscle with tendons: the landmarks are the belly's ends and ride the belly)
    ends = {"origin": np.vstack([rest.rest_origin, bundle0.points[:, 0]]),
            "insertion": np.vstack([rest.rest_insertion, bundle0.points[:, -1]])}
    bound = dataclasses.replace(sspec, vertices=both, faces=rest.faces, riders=both.shape[0] - n_v,
                                tendon_slack=getattr(rest, "tendon_slack", None) or None, **{
        end: _with_points(getattr(sspec, end), p_ground, pose0, model, tf_data_ground)
        for end, p_ground in ends.items()})

    wrapper = SurfaceWrapper(model, bound)

    def carry(stacked, keep=None, poses=None, frames=None) -> Carried:
        wrapped = wrapper(stacked, keep=keep, poses=poses, frames=frames)
        n_all = wrapped.radial_scale.shape[0]
        frames = wrapped.rider_frames
        lengths, points = _ends_ride_their_bodies(
            wrapped.riders.reshape(fine.shape[:2] + (n_all, 3)), fine,
            wrapped.origin[:, -shape[0]:], wrapped.insertion[:, -shape[0]:],
            None if frames is None else frames.reshape(fine.shape[:2] + (n_all, 3, 3)),
            keep=n_all if keep is None else keep)
        return Carried(points=points, lengths=lengths, surfaces=wrapped.vertices,
                       notes=tuple(getattr(wrapped, "notes", ())))

    return carry


def decompose_transport(model, sspec, bundle0, options, bar):
    """The ``"decompose"`` transport of one muscle (module docstring): ``carry(stacked, keep=None,
    poses=None, frames=None)`` wraps the surface at every pose of ``stacked`` (``poses`` and
    ``frames`` as in `bind_transport`)
    and decomposes each with the rest plan of ``bundle0`` (``options``: the `fibres.decompose`
    keywords of the rest decomposition); ``bar`` counts the decompositions (`analysis.progress`)."""
    from fibres import decompose
    from motion.surface.wrap import SurfaceWrapper

    wrapper = SurfaceWrapper(model, sspec)

    def carry(stacked, keep=None, poses=None, frames=None) -> Carried:
        wrapped = wrapper(stacked, poses=poses, frames=frames)
        points = np.empty((wrapped.vertices.shape[0],) + bundle0.points.shape)
        for f in range(len(points)):  # one decomposition per (perturbed) frame, the plan frozen
            interrupts.check()
            b = decompose((wrapped.vertices[f], wrapped.faces), wrapped.origin[f], wrapped.insertion[f],
                          plan=bundle0.plan, **options)
            points[f] = b.points
            bar.update(1)
        return Carried(points=points[:keep], lengths=fibre_lengths(points), surfaces=wrapped.vertices,
                       notes=tuple(getattr(wrapped, "notes", ())))

    return carry
