"""`analysis.run`: the whole per-motion fibre study of a fibre model, in memory.

The chain (DESIGN.md), per muscle:

1. Poses and action lines for all frames (``motion.wrapping.action_lines``: lengths and exact moment arms
   r = -dL/dq of the OpenSim paths, and which coordinates each path spans).
2. The muscle surface wrapped at every frame (``motion.wrap_surfaces``): same topology as the rest
   surface, attachments riding their bodies.
3. Fibres: ``fibres.decompose`` once on the rest-pose surface, which fixes the decomposition plan
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
4. Per-fibre length = polyline arc length (sum of segment lengths). In ``"bind"`` mode it is
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
5. Per-fibre moment arms r = -dL/dq about every coordinate the muscle's action lines span, by
   central differences of the WHOLE chain (wrap + decompose with the frozen plan + length):
   ``r = -(L(q + h e_c) - L(q - h e_c)) / (2 h)``. All perturbed poses are extra frames of ONE
   batch (the motion is stacked ``[q; q + h e_1; q - h e_1; ...]``), so wrapping runs once.

The step h (``FD_STEP``: 1e-4 rad for rotational, 1e-5 m for translational coordinates). The
central difference has truncation error h^2/6 * L''' and round-off error ~ eps * L / h. For a
muscle path L''' is of the order of L (a rotation by q changes a point's position with
derivatives of order its lever arm ~ L), so with L ~ 0.1 m the truncation error is ~1e-10 m,
four orders below the 1e-6 m resolution that matters for a moment arm of ~1e-2 m; the round-off
error of double precision is ~1e-16 * 0.1 / 1e-4 ~ 1e-13 m, and even if the chain's own
numerical noise were 1e-9 relative (iterative steps in wrapping), it contributes ~1e-6 m. The
step is also far below the 1-2 degree scale on which wrapping contact or the path geometry
change, so the quotient is a derivative, not a secant (checked by the smoothness test against a
2-degree difference quotient). Where the +h or -h pose switches a ConditionalPathPoint of the
muscle's action lines on or off (a step in the path, as in OpenSim), the quotient is one-sided on
the side that keeps the frame's own path (error ~ h/2 * L'' instead of a spike of the step / 2h).
"""
from __future__ import annotations

import concurrent.futures
import dataclasses
import time as _time
import warnings
from pathlib import Path

import numpy as np

from fibres.threads import blas_single

from . import budget, interrupts
from .errors import FibreWarning, InputError
from .fibre_checks import line_normalized_lengths, moment_arm_notes, optimal_lengths
from .progress import progress
from .result import MuscleResult, RunResult
from .spec import FibreModelSpec, load_spec

__all__ = ["run", "FD_STEP", "fibre_lengths", "select_frames"]

#: central-difference step per motion type (SI): see the module docstring.
FD_STEP = {"rotational": 1e-4, "translational": 1e-5, "coupled": 1e-4}
#: how rest fibres reach every frame (module docstring)
TRANSPORTS = ("bind", "decompose")
#: ``"bind"`` transport: material points carried per rest fibre segment to measure its length
#: (module docstring, step 4); the reported polylines are every LENGTH_SUBDIVISION-th of them
LENGTH_SUBDIVISION = 2


def fibre_lengths(points) -> np.ndarray:
    """Polyline arc lengths.

    Parameters
    ----------
    points : (..., N, P, 3) float

    Returns
    -------
    (..., N) float
    """
    return np.linalg.norm(np.diff(np.asarray(points, dtype=float), axis=-2), axis=-1).sum(-1)


def select_frames(frames, n_rows: int, *, file=None) -> np.ndarray:
    """Row indices from ``frames``: None (all), "START:STOP:STEP" or a ``FrameSelection``
    (`analysis.frames_option`), a slice, or a sequence of ints.

    Out-of-range or empty selections raise InputError with the valid range.
    """
    from .frames_option import FrameSelection, resolve_frames

    if frames is None or isinstance(frames, (str, FrameSelection)):
        return resolve_frames(frames, n_rows, source=file)
    if isinstance(frames, slice):
        if frames.step is not None and frames.step <= 0:
            raise InputError("the frame step must be positive", file=file, where="frames",
                             fix="Use START:STOP:STEP with STEP >= 1.")
        rows = np.arange(n_rows)[frames]
    else:
        rows = np.asarray(frames, dtype=np.int64).reshape(-1)
        if rows.size and (rows.min() < 0 or rows.max() >= n_rows):
            raise InputError("frame index out of range", file=file, where="frames",
                             fix=f"The motion has {n_rows} frames: use indices 0..{n_rows - 1}.")
    if rows.size == 0:
        raise InputError("the frame selection is empty", file=file, where="frames",
                         fix=f"The motion has {n_rows} frames (0..{n_rows - 1}); widen START:STOP.")
    return rows


# --------------------------------------------------------------------------------- the chain
@dataclasses.dataclass
class _Ctx:
    spec: FibreModelSpec
    model: object
    motion: object            # motion.Motion of the frames used
    lines: object             # motion.ActionLines of every action line used
    quiet: bool
    keep_points: bool
    keep_surfaces: bool
    step: dict
    transport: str = "bind"


def _timed(timings, stage):
    class _T:
        def __enter__(self):
            self.t0 = _time.perf_counter()

        def __exit__(self, *exc):
            timings[stage] = timings.get(stage, 0.0) + _time.perf_counter() - self.t0
            return False

    return _T()


@blas_single
def run(spec_path, motion=None, *, muscles=None, fibres=None, resolution=None, template=None,
        frames=None, quiet=True, jobs=1, step=None, keep_points=True, keep_surfaces=False,
        transport="bind", slicing=None, max_memory=None, out_dir=None) -> RunResult:
    """Run the fibre study of a fibre model over a motion.

    Parameters
    ----------
    spec_path : str or os.PathLike or FibreModelSpec
        The fibre-model TOML (docs/INTERFACE.md).
    motion : str or os.PathLike or motion.Motion, optional
        The motion (.mot/.sto); default: the ``motion`` key of the TOML.
    muscles : sequence of str, optional, keyword-only
        Muscles of the TOML to run (default all).
    fibres, resolution : int, optional, keyword-only
        Override the number of fibres / segments per fibre for every muscle.
    template : str, optional, keyword-only
        Override the fibre template for every muscle.
    frames : None, slice, "START:STOP:STEP" or sequence of int, keyword-only
        Motion rows to use.
    quiet : bool, keyword-only
        No progress bars.
    jobs : int, keyword-only
        Muscles processed in parallel (threads; numpy releases the GIL in the heavy parts).
    step : dict, optional, keyword-only
        Central-difference step per motion type (default `FD_STEP`).
    keep_points : bool, keyword-only
        Keep the fibre polylines per frame (``MuscleResult.fibre_points``) for the 3D files.
    keep_surfaces : bool, keyword-only
        Keep the wrapped surfaces per frame.
    transport : {"bind", "decompose"}, keyword-only
        How the rest fibres reach each frame (module docstring).
    slicing : {"harmonic", "planes"}, optional, keyword-only
        Override the cross-section method for every muscle (`fibres.decompose`).
    max_memory : int, optional, keyword-only
        Memory budget in bytes (default: `analysis.budget.default_budget`, 80 % of the physical
        memory). The run is refused with an InputError, before the long computation, when its
        estimate (`analysis.budget`) exceeds it; the estimate is ``settings["estimate"]``.
    out_dir : str or os.PathLike, optional, keyword-only
        Where the files will be written: the disk estimate is checked against its free space.

    Returns
    -------
    RunResult
    """
    import motion as motion_pkg

    if transport not in TRANSPORTS:
        raise ValueError(f"transport must be one of {TRANSPORTS}, got {transport!r}")
    timings = {}
    t_start = _time.perf_counter()
    limit = budget.default_budget() if max_memory is None else int(max_memory)
    with _timed(timings, "load"):
        spec = spec_path if isinstance(spec_path, FibreModelSpec) else load_spec(spec_path)
        model = spec.model
        mot_path = None
        if motion is None or isinstance(motion, (str, Path)):
            mot_path = Path(motion) if motion is not None else spec.motion_path
            if mot_path is None:
                raise InputError("no motion given and the fibre model has no 'motion' key", file=spec.file,
                                 where="motion", fix="Pass --motion FILE or add motion = \"<file>.mot\".")
            budget.check_motion_file(mot_path, limit)
            full = motion_pkg.load_motion(mot_path, model)
        else:
            full = motion
        rows = select_frames(frames, len(full.time), file=mot_path)
        mot = motion_pkg.Motion.from_array(model, full.time[rows], full.q[rows], source=full.source)
        mspecs = _select_muscles(spec, muscles, fibres=fibres, resolution=resolution, template=template,
                                 slicing=slicing)
    names = tuple(dict.fromkeys(n for m in mspecs for n in m.action_lines))
    budget.check_lines(len(rows), len(names), len(model.coordinates), limit)
    interrupts.check()
    with _timed(timings, "action_lines"):
        lines = _action_lines()(model, mot, muscles=names)
    interrupts.check()
    ctx = _Ctx(spec=spec, model=model, motion=mot, lines=lines, quiet=quiet, keep_points=keep_points,
               keep_surfaces=keep_surfaces, step=dict(FD_STEP, **(step or {})), transport=transport)
    costs = [budget.muscle_costs(m, len(rows), len(_spanned_coordinates(ctx, m)[0]), transport)
             for m in mspecs]
    estimate = budget.check_budget(costs, budget=limit, jobs=jobs, out_dir=out_dir)
    results, muscle_timings = [None] * len(mspecs), []
    bar = progress(total=len(mspecs), desc="wrap + fibres", quiet=quiet, unit="muscle")
    try:
        if jobs > 1 and len(mspecs) > 1:
            interrupts.check()
            pool = concurrent.futures.ThreadPoolExecutor(max_workers=jobs)
            futures = [pool.submit(_run_muscle, ctx, m) for m in mspecs]
            try:
                for i, fut in enumerate(futures):
                    results[i], t = fut.result()
                    muscle_timings.append(t)
                    bar.update(1)
            except BaseException:   # Ctrl-C or a failed muscle: do not wait for the others
                pool.shutdown(wait=False, cancel_futures=True)
                raise
            pool.shutdown(wait=True)
        else:
            for i, m in enumerate(mspecs):
                interrupts.check()
                results[i], t = _run_muscle(ctx, m)
                muscle_timings.append(t)
                bar.update(1)
    finally:
        bar.close()
    for t in muscle_timings:   # per-muscle stages summed (thread time when jobs > 1)
        for k, v in t.items():
            timings[k] = timings.get(k, 0.0) + v
    timings["total"] = _time.perf_counter() - t_start
    inputs = {"spec": spec.file, "model": spec.model_path}
    if mot_path is not None:
        inputs["motion"] = Path(mot_path).resolve()
    for m in mspecs:
        if m.mesh is not None:
            inputs[f"mesh:{m.name}"] = m.mesh
        for k, (_, bone) in enumerate(m.bones):
            inputs[f"bone:{m.name}:{k}"] = bone
        for end in ("origin", "insertion"):
            src = getattr(m, end).source
            if src and Path(src).is_file():
                inputs[f"{end}:{m.name}"] = Path(src)
    settings = {
        "motion_rows": rows.tolist(), "jobs": int(jobs), "fd_step": ctx.step, "transport": transport,
        "estimate": estimate,
        "motion_types": {c.name: c.motion_type for c in model.coordinates},
        "muscles": {m.name: {"action_lines": list(m.action_lines), "template": m.template,
                             "fibres": m.n_fibres, "resolution": m.resolution, "seed": m.seed,
                             "frame": m.frame, "units": m.units, "rest_pose": dict(m.rest_pose),
                             "template_params": dict(m.template_params), "slicing": m.slicing}
                    for m in mspecs},
    }
    return RunResult(time=mot.time, frames=rows, coordinate_names=model.coordinate_names, q=mot.q,
                     muscles=tuple(results), timings=timings, settings=settings, inputs=inputs)


def _select_muscles(spec, muscles, *, fibres, resolution, template, slicing=None):
    if muscles:
        unknown = [m for m in muscles if m not in spec.muscle_names]
        if unknown:
            raise InputError(f"no muscle '{unknown[0]}' in the fibre model", file=spec.file, where="--muscle",
                             fix=f"Use one of: {', '.join(spec.muscle_names)}.")
        chosen = [spec.muscle(m) for m in dict.fromkeys(muscles)]
    else:
        chosen = list(spec.muscles)
    from .spec import check_count

    over = {}
    for key, val in (("fibres", fibres), ("resolution", resolution)):
        if val is not None:
            if isinstance(val, float) and val.is_integer():
                val = int(val)
            over["n_fibres" if key == "fibres" else key] = check_count(key, val, where=f"--{key}")
    if template is not None:
        from .spec import _template_names

        if template not in _template_names():
            raise InputError(f"unknown template {template!r}", where="--template",
                             fix=f"Use one of: {', '.join(_template_names())}.")
        over["template"] = template
    if slicing is not None:
        from .spec import SLICINGS

        if slicing not in SLICINGS:
            raise InputError(f"unknown slicing {slicing!r}", where="--slicing",
                             fix=f"Use one of: {', '.join(SLICINGS)}.")
        over["slicing"] = slicing
    return [dataclasses.replace(m, **over) for m in chosen]


def check_mesh_files(mspecs) -> None:
    """Read every mesh and bone file of the muscles once (`fibres.surface.read_mesh`), so that a
    damaged file is reported before any work or output folder (the run reads them again)."""
    from fibres.surface import read_mesh

    for m in mspecs:
        for path in ([m.mesh] if m.mesh is not None else []) + [p for _, p in m.bones]:
            read_mesh(path)


def _spanned_coordinates(ctx, mspec):
    """Indices (into model coordinates) of the independent coordinates the muscle's lines span."""
    lines = ctx.lines
    rows = [list(lines.muscle_names).index(n) for n in mspec.action_lines]
    spanned = np.asarray(lines.spanned, dtype=bool)[rows].any(axis=0)
    indep = np.asarray(ctx.model.independent_coordinates, dtype=bool)
    return np.flatnonzero(spanned & indep), rows


def _stacked_motion(ctx, coord_idx):
    """The base motion followed by +h and -h perturbations of each coordinate: (F * (1 + 2K), C)."""
    import motion as motion_pkg

    q = np.asarray(ctx.motion.q, dtype=float)
    n_f = len(q)
    coords = ctx.model.coordinates
    steps = np.array([ctx.step[coords[c].motion_type] for c in coord_idx])
    blocks = [q]
    for k, c in enumerate(coord_idx):
        for sign in (1.0, -1.0):
            qp = q.copy()
            qp[:, c] += sign * steps[k]
            blocks.append(qp)
    q_all = np.concatenate(blocks, axis=0)
    t_all = np.arange(len(q_all), dtype=float)   # a placeholder clock: poses do not depend on time
    stacked = motion_pkg.Motion.from_array(ctx.model, t_all, q_all, source=ctx.motion.source)
    return stacked, steps, n_f


def _surface_spec(mspec):
    """The `motion.MuscleSurfaceSpec` of a muscle: mesh read (and safely repaired) in metres."""
    from fibres import as_surface
    from motion.surface.spec import BoneMesh, MuscleSurfaceSpec, SurfaceAttachment

    vertices = faces = None
    if mspec.mesh is not None:
        surf = as_surface(mspec.mesh, units=mspec.units)
        vertices, faces = surf.vertices, surf.faces
    ends = {end: SurfaceAttachment(body=a.body, points=a.points, in_body_frame=a.in_body_frame)
            for end, a in (("origin", mspec.origin), ("insertion", mspec.insertion))}
    bones = []
    for body, path in mspec.bones:
        bone = as_surface(path, units=mspec.units)
        bones.append(BoneMesh(body=body, vertices=bone.vertices, faces=bone.faces))
    return MuscleSurfaceSpec(name=mspec.name, action_lines=tuple(mspec.action_lines), vertices=vertices,
                             faces=faces, frame=mspec.frame, rest_pose=dict(mspec.rest_pose),
                             bones=tuple(bones), volume=mspec.volume, **ends)


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


def _ends_ride_their_bodies(carried, rest, origin_ends, insertion_ends, frames=None):
    """Fibres carried by the belly deformation (F, N, P, 3), corrected so that their ends are
    ``origin_ends`` / ``insertion_ends`` (F, N, 3) (rigid with their bodies), the residuals
    spread linearly in each rest fibre's (N, P, 3) arc-length fraction (module docstring).

    ``frames`` (F, N, P, 3, 3), the belly's line frames at the fibre points (columns normal,
    binormal, tangent; `motion.WrappedSurface.rider_frames`): each end residual is then held in
    the frame at its end and carried along the fibre with the frames, so over a pulley a
    residual across the muscle stays across it instead of a fixed ground vector (where the
    frames are constant, on a straight line, it is the same correction)."""
    seg = np.linalg.norm(np.diff(rest, axis=1), axis=-1)                      # (N, P-1)
    u = np.concatenate([np.zeros((rest.shape[0], 1)), np.cumsum(seg, axis=1)], axis=1)
    u = u / np.maximum(u[:, -1:], 1e-300)                                      # (N, P)
    e0 = origin_ends - carried[:, :, 0]
    e1 = insertion_ends - carried[:, :, -1]
    if frames is not None:
        local0 = np.einsum("fnji,fnj->fni", frames[:, :, 0], e0)       # e0 in the frame at the end
        local1 = np.einsum("fnji,fnj->fni", frames[:, :, -1], e1)
        mix = local0[:, :, None] + u[None, :, :, None] * (local1 - local0)[:, :, None]   # (F, N, P, 3)
        out = carried + np.matmul(frames, mix[..., None])[..., 0]
        # the ends exactly (the interpolated frames there are those used for local0/local1)
        out[:, :, 0] = origin_ends
        out[:, :, -1] = insertion_ends
        return out
    out = carried + e0[:, :, None]                       # = ... + (1 - u) e0 + u e1, two temporaries
    out += u[None, :, :, None] * (e1 - e0)[:, :, None]
    return out


def _api(package: str, name: str, module: str):
    """``package.name`` if exported as a function, else ``package.module.name`` (a checkout in
    which the name is not yet exported; ``from package import name`` could return the module)."""
    import importlib

    obj = getattr(importlib.import_module(package), name, None)
    if callable(obj) and not isinstance(obj, type(importlib)):
        return obj
    return getattr(importlib.import_module(f"{package}.{module}"), name)


def _action_lines():
    return _api("motion", "action_lines", "action_lines")


def _wrap_surfaces():
    return _api("motion", "wrap_surfaces", "surface_wrap")


def _active_set_changes(model, mspec, q_stacked, n_f):
    """(K, F) bool masks: the +h (-h) pose switches a ConditionalPathPoint of the muscle's action
    lines on or off relative to the frame's own pose (OpenSim's rule: active when
    ``range_min - 1e-5 <= q <= range_max + 1e-5``)."""
    q = np.asarray(q_stacked, dtype=float)
    n_k = q.shape[0] // n_f // 2
    blocks = q.reshape(1 + 2 * n_k, n_f, -1)
    plus = np.zeros((n_k, n_f), dtype=bool)
    minus = np.zeros((n_k, n_f), dtype=bool)
    for name in mspec.action_lines:
        for pt in model.path(name).points:
            if pt.kind != "conditional" or pt.coordinate not in model.coordinate_names:
                continue
            c = model.coordinate_index(pt.coordinate)
            lo, hi = pt.range[0] - 1e-5, pt.range[1] + 1e-5
            active = (blocks[..., c] >= lo) & (blocks[..., c] <= hi)      # (1 + 2K, F)
            plus |= active[1::2] != active[0]
            minus |= active[2::2] != active[0]
    return plus, minus


def _difference_quotients(base, plus, minus, steps, plus_switch, minus_switch):
    """r = -dL/dq per fibre: central differences, one-sided where the +h or -h pose switches a
    conditional path point (a step in the path, as in OpenSim, that a central difference would
    turn into a spike; the exact action-line derivative is likewise one-sided there).

    base (F, N), plus/minus (K, F, N), steps (K,), switches (K, F) -> (F, N, K)."""
    h = steps[:, None, None]
    central = -(plus - minus) / (2.0 * h)
    forward = -(plus - base[None]) / h
    backward = -(base[None] - minus) / h
    r = np.where(plus_switch[..., None] & ~minus_switch[..., None], backward, central)
    r = np.where(minus_switch[..., None] & ~plus_switch[..., None], forward, r)
    return np.moveaxis(r, 0, -1)


def _run_muscle(ctx, mspec):
    """Wrap, decompose, measure one muscle over all frames (+ perturbed frames)."""
    import motion as motion_pkg
    from motion.surface.rest import rest_pose

    interrupts.check()
    decompose = _api("fibres", "decompose", "decompose")
    wrap_surfaces = _wrap_surfaces()
    timings = {}
    coord_idx, line_rows = _spanned_coordinates(ctx, mspec)
    stacked, steps, n_f = _stacked_motion(ctx, coord_idx)
    sspec = _surface_spec(mspec)
    with _timed(timings, "wrap"):   # the rest surface and landmarks in ground (one frame)
        first = motion_pkg.Motion.from_array(ctx.model, ctx.motion.time[:1], ctx.motion.q[:1])
        (rest,) = wrap_surfaces(ctx.model, first, [sspec])
    from .landmark_checks import check_landmarks

    check_landmarks(ctx.model, mspec, sspec, rest)
    opts = dict(template=mspec.template, n_fibres=mspec.n_fibres, resolution=mspec.resolution,
                seed=mspec.seed, slicing=mspec.slicing)
    if mspec.template_params:
        opts["template_params"] = dict(mspec.template_params)
    faces = rest.faces
    interrupts.check()
    with _timed(timings, "decompose_rest"):
        bundle0 = decompose((rest.rest_vertices, faces), rest.rest_origin, rest.rest_insertion, **opts)
    shape = bundle0.points.shape                                  # (N, P, 3)
    n_v = rest.rest_vertices.shape[0]
    if ctx.transport == "bind":
        # rest surface + fibre points back to the mesh's own frame, wrapped together
        pose0 = rest_pose(ctx.model, sspec)
        tf_data_ground = np.linalg.inv(pose0.tf_ground_data)
        fine = _subdivided(bundle0.points, LENGTH_SUBDIVISION)          # (N, m (P - 1) + 1, 3)
        both = np.vstack([rest.rest_vertices, fine.reshape(-1, 3)])
        both = both @ tf_data_ground[:3, :3].T + tf_data_ground[:3, 3]
        # the fibre end points lie in the attachment areas by construction (Kohout 2012 §3.4):
        # bind them as attachment points too, so they ride their bones exactly
        # (a generated muscle with tendons: the landmarks are the belly's ends and ride the belly)
        ends = {"origin": np.vstack([rest.rest_origin, bundle0.points[:, 0]]),
                "insertion": np.vstack([rest.rest_insertion, bundle0.points[:, -1]])}
        bound = dataclasses.replace(sspec, vertices=both, faces=faces, riders=both.shape[0] - n_v,
                                    tendon_slack=getattr(rest, "tendon_slack", None) or None, **{
            end: _with_points(getattr(sspec, end), p_ground, pose0, ctx.model, tf_data_ground)
            for end, p_ground in ends.items()})
        with _timed(timings, "wrap"):
            (wrapped,) = wrap_surfaces(ctx.model, stacked, [bound])
        n_all = wrapped.vertices.shape[0]
        surfaces = wrapped.vertices[:, :n_v]
        frames = getattr(wrapped, "rider_frames", None)
        fine = _ends_ride_their_bodies(wrapped.vertices[:, n_v:].reshape((n_all,) + fine.shape), fine,
                                       wrapped.origin[:, -shape[0]:], wrapped.insertion[:, -shape[0]:],
                                       None if frames is None else frames.reshape((n_all,) + fine.shape[:2] + (3, 3)))
        points = fine[:, :, ::LENGTH_SUBDIVISION]
    else:
        with _timed(timings, "wrap"):
            (wrapped,) = wrap_surfaces(ctx.model, stacked, [sspec])
        n_all = wrapped.vertices.shape[0]
        surfaces = wrapped.vertices
        points = np.empty((n_all,) + shape)
        bar = progress(total=n_all, desc=f"fibres {mspec.name}", quiet=ctx.quiet, unit="frame")
        with _timed(timings, "decompose"):
            try:
                for f in range(n_all):  # one decomposition per (perturbed) frame, the plan frozen
                    interrupts.check()
                    b = decompose((wrapped.vertices[f], faces), wrapped.origin[f], wrapped.insertion[f],
                                  plan=bundle0.plan, **opts)
                    points[f] = b.points
                    bar.update(1)
            finally:
                bar.close()
    interrupts.check()
    with _timed(timings, "lengths"):
        lengths = fibre_lengths(fine if ctx.transport == "bind" else points)   # (F * (1 + 2K), N)
    with _timed(timings, "moment_arms"):
        blocks = lengths.reshape(1 + 2 * len(coord_idx), n_f, -1)
        base = blocks[0]
        r = _difference_quotients(base, blocks[1::2], blocks[2::2], steps,
                                  *_active_set_changes(ctx.model, mspec, stacked.q, n_f))
    lines = ctx.lines
    al_len = np.asarray(lines.lengths)[:, line_rows]
    al_r = np.asarray(lines.moment_arms)[:, line_rows][:, :, coord_idx]
    names = tuple(ctx.model.coordinate_names[c] for c in coord_idx)
    notes = tuple(getattr(bundle0, "notes", ()) or ())
    quality = bundle0.quality
    problems = quality.problems() if quality is not None else []
    if problems:
        from fibres.quality import FibreQualityWarning

        notes += (f"fibre quality below the usual limits: {'; '.join(problems)}",)
        warnings.warn(f"{mspec.name}: fibre quality below the usual limits: {'; '.join(problems)}"
                      f" (see fibre_quality.csv; try --slicing or another template)",
                      FibreQualityWarning, stacklevel=2)
    if getattr(rest, "rest_residual", 0.0):
        notes += (f"rest pose residual {rest.rest_residual:.3g}",)
    rest_lengths = fibre_lengths(bundle0.points)
    warned = tuple(f"warning: {n}" for n in getattr(wrapped, "notes", ())) + moment_arm_notes(names, r, al_r)
    for note in warned:
        warnings.warn(f"muscle {mspec.name!r}: {note[len('warning: '):]}", FibreWarning, stacklevel=3)
    result = MuscleResult(
        name=mspec.name, coordinates=names, fibre_lengths=base, fibre_moment_arms=r,
        action_lines=mspec.action_lines, action_line_lengths=al_len, action_line_moment_arms=al_r,
        rest_lengths=rest_lengths,
        fibre_points=points[:n_f] if ctx.keep_points else None,
        surface_vertices=surfaces[:n_f] if ctx.keep_surfaces else None,
        surface_faces=faces if ctx.keep_surfaces else None, notes=notes + warned,
        quality=None if quality is None else quality.as_dict(),
        optimal_lengths=optimal_lengths(ctx.model, mspec.action_lines, rest_lengths, generated=mspec.mesh is None),
        line_normalized_lengths=line_normalized_lengths(ctx.model, mspec.action_lines, al_len))
    return result, timings
