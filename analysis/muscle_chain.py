"""One muscle of `analysis.run` over a motion: wrap, decompose, carry, measure.

Per muscle (docs/DESIGN.md):

1. The rest surface: the muscle surface (its mesh, or one generated around its action line)
   wrapped at the motion's first frame (``motion.wrap_surfaces``), its landmarks in ground.
2. ``fibres.decompose`` once on it, which fixes the decomposition plan, and the fibre quality.
3. The fibres carried to every frame and to the perturbed poses of the moment arms
   (`analysis.fibre_transport`, `analysis.fibre_moment_arms`), streamed through the transport
   in chunks of at most ``POSES_PER_CHUNK`` poses, so the memory a muscle needs is bounded
   whatever the length of the motion; only the frames' own fibre points (for the 3D files),
   lengths and moment arms are kept.
4. The `MuscleResult`: lengths, moment arms, the action lines' values, notes and warnings.
"""
from __future__ import annotations

import collections
import dataclasses
import re
import threading
import time as _time
import warnings

import numpy as np

from . import interrupts
from .budget import POSES_PER_CHUNK
from .errors import FibreWarning
from .fibre_checks import line_normalized_lengths, moment_arm_notes, optimal_lengths, short_path_notes
from .fibre_moment_arms import active_set_changes, difference_quotients, range_limits, stacked_motion
from .fibre_transport import bind_transport, decompose_transport, fibre_lengths
from .progress import progress
from .result import MuscleResult
from .spec import FibreModelSpec

__all__ = ["Ctx", "PoseCache", "run_muscle", "spanned_coordinates", "surface_spec", "timed"]


class PoseCache:
    """The body poses of the stacked motions (`analysis.fibre_moment_arms.stacked_motion`) shared
    by the muscles of a run: muscles that span the same coordinates (the three hip muscles
    glut_med1-3, ...) move the bones through the same poses, chunk by chunk. Keyed by the
    spanned coordinates and the chunk's frames; the last ``size`` chunks are kept (a chunk of
    ``POSES_PER_CHUNK`` poses of a 20-body model is ~1.3 MB). Thread-safe (``jobs`` threads)."""

    def __init__(self, size: int = 16):
        self.size = int(size)
        self._kept = collections.OrderedDict()
        self._lock = threading.Lock()

    def get(self, key, make):
        """The value kept for ``key``, else ``make()`` (outside the lock), kept."""
        with self._lock:
            if key in self._kept:
                self._kept.move_to_end(key)
                return self._kept[key]
        value = make()
        with self._lock:
            self._kept[key] = value
            while len(self._kept) > self.size:
                self._kept.popitem(last=False)
        return value


@dataclasses.dataclass
class Ctx:
    """What every muscle of a run shares."""

    spec: FibreModelSpec
    model: object
    motion: object            # motion.Motion of the frames used
    lines: object             # motion.ActionLines of every action line used
    quiet: bool
    keep_points: bool
    keep_surfaces: bool
    step: dict
    transport: str = "bind"
    poses: PoseCache = dataclasses.field(default_factory=PoseCache)


def timed(timings, stage, *, process: bool = False):
    """A context adding its wall time to ``timings[stage]`` and the CPU time of its thread (of
    the whole process with ``process``: a stage with helper threads and no other work running)
    to ``timings[stage + "_cpu"]`` (the CPU times compare runs on a shared machine)."""
    clock = _time.process_time if process else _time.thread_time

    class _T:
        def __enter__(self):
            self.t0, self.c0 = _time.perf_counter(), clock()

        def __exit__(self, *exc):
            timings[stage] = timings.get(stage, 0.0) + _time.perf_counter() - self.t0
            timings[stage + "_cpu"] = timings.get(stage + "_cpu", 0.0) + clock() - self.c0
            return False

    return _T()


def spanned_coordinates(ctx, mspec):
    """Indices (into model coordinates) of the independent coordinates the muscle's lines span."""
    lines = ctx.lines
    rows = [list(lines.muscle_names).index(n) for n in mspec.action_lines]
    spanned = np.asarray(lines.spanned, dtype=bool)[rows].any(axis=0)
    indep = np.asarray(ctx.model.independent_coordinates, dtype=bool)
    return np.flatnonzero(spanned & indep), rows


def surface_spec(mspec):
    """The `motion.MuscleSurfaceSpec` of a muscle: mesh read (and safely repaired) in metres.
    A mesh smaller than `fibres.mesh.surface.MIN_MUSCLE_SIZE_M` across is refused (metres declared
    as mm; its decomposition would take minutes and give nonsense); one too large is refused by
    `motion.wrap_surfaces`, which also knows how far it lies from its action lines."""
    from fibres import as_surface
    from fibres.mesh.surface import check_muscle_scale
    from motion.surface.spec import BoneMesh, MuscleSurfaceSpec

    vertices = faces = None
    if mspec.mesh is not None:
        surf = as_surface(mspec.mesh, units=mspec.units)
        check_muscle_scale(surf, file=mspec.mesh, max_size_m=np.inf)
        vertices, faces = surf.vertices, surf.faces
    bones = []
    for body, path in mspec.bones:
        bone = as_surface(path, units=mspec.units)
        bones.append(BoneMesh(body=body, vertices=bone.vertices, faces=bone.faces))
    return MuscleSurfaceSpec(name=mspec.name, action_lines=tuple(mspec.action_lines), vertices=vertices,
                             faces=faces, frame=mspec.frame, rest_pose=dict(mspec.rest_pose),
                             bones=tuple(bones), volume=mspec.volume, origin=mspec.origin,
                             insertion=mspec.insertion, origin_tendon_share=mspec.origin_tendon_share)


def _chunks(n_frames: int, n_poses_per_frame: int):
    """Slices of frames whose poses fit in ``POSES_PER_CHUNK`` (at least one frame each)."""
    size = max(1, POSES_PER_CHUNK // max(n_poses_per_frame, 1))
    return [slice(a, min(a + size, n_frames)) for a in range(0, n_frames, size)]


_COUNT = re.compile(r"\(in (\d+) of (\d+) frames\)")


def _merged_notes(chunk_notes) -> tuple:
    """Notes of the chunks of one wrap, once each; a note that counts frames ("in 3 of 120
    frames") is summed over the chunks."""
    merged = {}
    for notes in chunk_notes:
        for note in notes:
            key = _COUNT.sub("(in # of # frames)", note)
            m = _COUNT.search(note)
            counts = (int(m.group(1)), int(m.group(2))) if m else (0, 0)
            old = merged.get(key, (note, (0, 0)))[1]
            merged[key] = (note, (old[0] + counts[0], old[1] + counts[1]))
    return tuple(_COUNT.sub(f"(in {a} of {b} frames)", note) if _COUNT.search(note) else note
                 for note, (a, b) in merged.values())


def run_muscle(ctx, mspec):
    """Wrap, decompose, carry and measure one muscle over all frames (module docstring);
    returns its `MuscleResult` and stage timings (s)."""
    import motion as motion_pkg
    from fibres import decompose
    from motion import wrap_surfaces

    interrupts.check()
    timings = {}
    coord_idx, line_rows = spanned_coordinates(ctx, mspec)
    sspec = surface_spec(mspec)
    with timed(timings, "wrap"):   # the rest surface and landmarks in ground (one frame)
        first = motion_pkg.Motion.from_array(ctx.model, ctx.motion.time[:1], ctx.motion.q[:1])
        (rest,) = wrap_surfaces(ctx.model, first, [sspec])
    from .landmark_checks import check_landmarks

    check_landmarks(ctx.model, mspec, sspec, rest)
    opts = dict(template=mspec.template, n_fibres=mspec.n_fibres, resolution=mspec.resolution,
                seed=mspec.seed, slicing=mspec.slicing)
    if mspec.template_params:
        opts["template_params"] = dict(mspec.template_params)
    interrupts.check()
    with timed(timings, "decompose_rest"):
        bundle0 = decompose((rest.rest_vertices, rest.faces), rest.rest_origin, rest.rest_insertion, **opts)
    q = np.asarray(ctx.motion.q, dtype=float)
    n_f, n_poses = len(q), 1 + 2 * len(coord_idx)
    bar = None
    if ctx.transport == "bind":
        with timed(timings, "wrap"):
            carry = bind_transport(ctx.model, sspec, rest, bundle0)
        stage = "wrap"
    else:
        bar = progress(total=n_f * n_poses, desc=f"fibres {mspec.name}", quiet=ctx.quiet, unit="frame")
        carry = decompose_transport(ctx.model, sspec, bundle0, opts, bar)
        stage = "decompose"
    n_fib = bundle0.points.shape[0]
    lengths = np.empty((n_poses, n_f, n_fib))
    points = np.empty((n_f,) + bundle0.points.shape) if ctx.keep_points else None
    # whether the +h / -h pose of each frame switches a conditional path point or leaves a clamped
    # coordinate's range (K, F)
    plus_switch = np.zeros((len(coord_idx), n_f), dtype=bool)
    minus_switch = np.zeros_like(plus_switch)
    surfaces, chunk_notes, steps = [], [], None
    try:
        for rows in _chunks(n_f, n_poses):
            interrupts.check()
            stacked, steps, n_c = stacked_motion(ctx.model, q[rows], ctx.motion.source, coord_idx, ctx.step)
            with timed(timings, stage):
                poses = ctx.poses.get((tuple(coord_idx.tolist()), rows.start, rows.stop),
                                      lambda: motion_pkg.body_poses(ctx.model, stacked))
                got = carry(stacked, keep=n_c if points is not None else 0, poses=poses, frames=n_c)
            with timed(timings, "lengths"):
                lengths[:, rows] = got.lengths.reshape(n_poses, n_c, n_fib)
            if points is not None:
                points[rows] = got.points[:n_c]
            if ctx.keep_surfaces:
                surfaces.append(got.surfaces[:n_c])
            chunk_notes.append(got.notes)
            plus_switch[:, rows], minus_switch[:, rows] = active_set_changes(ctx.model, mspec, stacked.q, n_c)
            out_plus, out_minus = range_limits(ctx.model, stacked.q, n_c, coord_idx)
            plus_switch[:, rows] |= out_plus
            minus_switch[:, rows] |= out_minus
    finally:
        if bar is not None:
            bar.close()
    with timed(timings, "moment_arms"):
        r = difference_quotients(lengths[0], lengths[1::2], lengths[2::2], steps, plus_switch, minus_switch)
    base = lengths[0]
    lines = ctx.lines
    al_len = np.asarray(lines.lengths)[:, line_rows]
    al_r = np.asarray(lines.moment_arms)[:, line_rows][:, :, coord_idx]
    names = tuple(ctx.model.coordinate_names[c] for c in coord_idx)
    notes = tuple(getattr(bundle0, "notes", ()) or ())
    quality = bundle0.quality
    problems = quality.problems() if quality is not None else []
    if problems:
        from fibres.finishing.quality import FibreQualityWarning

        notes += (f"fibre quality below the usual limits: {'; '.join(problems)}",)
        # a dead end beyond a patch (fibres.slicing.harmonic_sections.dead_end_levels) is the
        # likely cause: say so instead of the general advice
        from fibres.slicing.harmonic_sections import DEAD_END_NOTE

        why = [n for n in notes if DEAD_END_NOTE in n]
        warnings.warn(f"{mspec.name}: fibre quality below the usual limits: {'; '.join(problems)}"
                      + (f"; {why[0]}" if why else
                         " (see fibre_quality.csv; try --slicing or another template, and check that"
                         " the origin and insertion lie at the ends of the muscle's mesh)"),
                      FibreQualityWarning, stacklevel=2)
    if getattr(rest, "rest_residual", 0.0):
        notes += (f"rest pose residual {rest.rest_residual:.3g}",)
    rest_lengths = fibre_lengths(bundle0.points)
    warned = tuple(f"warning: {n}" for n in _merged_notes(chunk_notes)) + moment_arm_notes(
        names, r, al_r, mixed_passes=bool(lines.mixes_passes()[line_rows].any()))
    if mspec.mesh is not None:    # a generated belly warns about a short path itself (motion.surface.wrap)
        warned += short_path_notes(ctx.model, mspec.action_lines, al_len)
    for note in warned:
        warnings.warn(f"muscle {mspec.name!r}: {note[len('warning: '):]}", FibreWarning, stacklevel=3)
    result = MuscleResult(
        name=mspec.name, coordinates=names, fibre_lengths=base, fibre_moment_arms=r,
        action_lines=mspec.action_lines, action_line_lengths=al_len, action_line_moment_arms=al_r,
        rest_lengths=rest_lengths, fibre_points=points,
        surface_vertices=np.concatenate(surfaces) if ctx.keep_surfaces else None,
        surface_faces=rest.faces if ctx.keep_surfaces else None, notes=notes + warned,
        quality=None if quality is None else quality.as_dict(),
        optimal_lengths=optimal_lengths(ctx.model, mspec.action_lines, rest_lengths, generated=mspec.mesh is None),
        line_normalized_lengths=line_normalized_lengths(ctx.model, mspec.action_lines, al_len))
    return result, timings
