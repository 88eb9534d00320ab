"""`analysis.run`: the whole per-motion fibre study of a fibre model, in memory.

The chain (DESIGN.md), per muscle:

1. Poses and action lines for all frames (``motion.wrapping.action_lines``: lengths and exact moment arms
   r = -dL/dq of the OpenSim paths, and which coordinates each path spans).
2. The muscle surface wrapped at every frame (``motion.wrap_surfaces``): same topology as the rest
   surface, attachments riding their bodies.
3. Fibres: ``fibres.decompose`` once on the rest surface, carried to every frame
   (`analysis.fibre_transport`: ``"bind"`` by default, or ``"decompose"`` per frame) and measured
   there (arc lengths), streamed in chunks of frames (`analysis.muscle_chain`).
4. Fibre moment arms r = -dL/dq by central differences of the whole chain
   (`analysis.fibre_moment_arms`).

Muscles run one after another, or ``jobs`` at a time in threads (numpy and the compiled kernels
release the GIL in the heavy parts).
"""
from __future__ import annotations

import concurrent.futures
import dataclasses
import time as _time
from pathlib import Path

import numpy as np

from fibres.threads import blas_single

from . import budget, interrupts
from .errors import InputError
from .fibre_moment_arms import FD_STEP
from .fibre_transport import TRANSPORTS, fibre_lengths
from .muscle_chain import Ctx, run_muscle, spanned_coordinates, timed
from .progress import progress, stage_notice
from .result import RunResult
from .spec import FibreModelSpec, load_spec

__all__ = ["run", "FD_STEP", "fibre_lengths", "select_frames", "read_motion"]

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



def read_motion(spec, motion, mspecs, frames, limit) -> tuple:
    """The motion of a run and its rows: ``(path or None, motion.Motion, rows)``.

    ``motion`` is a path, a ``motion.Motion`` or None (the fibre model's ``motion`` key); a file
    is checked against the memory budget ``limit`` (bytes) and read with the coordinates that
    the action lines of ``mspecs`` span, so that a missing one is named in a warning of its own
    (`motion.load_motion`). ``frames`` as in `select_frames`. Bad input raises InputError.
    """
    import motion as motion_pkg
    from motion.wrapping.action_lines import coordinates_spanned

    if motion is not None and not isinstance(motion, (str, Path)):
        return None, motion, select_frames(frames, len(motion.time))
    mot_path = Path(motion) if motion is not None else spec.motion_path
    if mot_path is None:
        raise InputError("no motion given and the fibre model has no 'motion' key", file=spec.file,
                         where="motion", fix="Pass --motion FILE or add motion = \"<file>.mot\".")
    budget.check_motion_file(mot_path, limit)
    spanned = coordinates_spanned(spec.model, dict.fromkeys(n for m in mspecs for n in m.action_lines))
    full = motion_pkg.load_motion(mot_path, spec.model, spanned=spanned)
    return mot_path, full, select_frames(frames, len(full.time), file=mot_path)


@blas_single
def run(spec_path, motion=None, *, muscles=None, fibres=None, resolution=None, template=None,
        frames=None, quiet=True, jobs=1, step=None, keep_points=True, keep_surfaces=False,
        transport="bind", slicing=None, max_memory=None, out_dir=None, on_muscle=None) -> RunResult:
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
    on_muscle : callable, optional, keyword-only
        ``on_muscle(time, muscle_result) -> muscle_result``, called in this thread as each
        muscle is done (in the order of the muscles); what it returns is kept in the result.
        ``fibres run`` writes a muscle's 3D files there and keeps only the scene's frames of its
        fibre points and surfaces, so a whole model's points are never in memory at once.

    Returns
    -------
    RunResult
    """
    import motion as motion_pkg

    if transport not in TRANSPORTS:
        raise ValueError(f"transport must be one of {TRANSPORTS}, got {transport!r}")
    timings = {}
    t_start, c_start = _time.perf_counter(), _time.process_time()
    limit = budget.default_budget() if max_memory is None else int(max_memory)
    with timed(timings, "load"):
        spec = spec_path if isinstance(spec_path, FibreModelSpec) else load_spec(spec_path)
        model = spec.model
        mspecs = _select_muscles(spec, muscles, fibres=fibres, resolution=resolution, template=template,
                                 slicing=slicing)
        mot_path, full, rows = read_motion(spec, motion, mspecs, frames, limit)
        mot = motion_pkg.Motion.from_array(model, full.time[rows], full.q[rows], source=full.source)
    names = tuple(dict.fromkeys(n for m in mspecs for n in m.action_lines))
    budget.check_lines(len(rows), len(names), len(model.coordinates), limit)
    interrupts.check()
    with timed(timings, "action_lines"):
        lines = motion_pkg.action_lines(model, mot, muscles=names)
    stage_notice(f"action lines: {len(names)} paths, {len(rows)} frames", timings["action_lines"], quiet)
    interrupts.check()
    ctx = Ctx(spec=spec, model=model, motion=mot, lines=lines, quiet=quiet, keep_points=keep_points,
               keep_surfaces=keep_surfaces, step=dict(FD_STEP, **(step or {})), transport=transport)
    costs = [budget.muscle_costs(m, len(rows), len(spanned_coordinates(ctx, m)[0]), transport)
             for m in mspecs]
    estimate = budget.check_budget(costs, budget=limit, jobs=jobs, out_dir=out_dir)
    results, muscle_timings = [None] * len(mspecs), []
    bar = progress(total=len(mspecs), desc="wrap + fibres", quiet=quiet, unit="muscle")
    try:
        if jobs > 1 and len(mspecs) > 1:
            interrupts.check()
            pool = concurrent.futures.ThreadPoolExecutor(max_workers=jobs)
            futures = [pool.submit(run_muscle, ctx, m) for m in mspecs]
            try:
                for i, fut in enumerate(futures):
                    results[i], t = fut.result()
                    futures[i] = None                  # the future no longer holds the result
                    results[i] = on_muscle(mot.time, results[i]) if on_muscle else results[i]
                    muscle_timings.append(t)
                    bar.update(1)
            except BaseException:   # Ctrl-C or a failed muscle: do not wait for the others
                pool.shutdown(wait=False, cancel_futures=True)
                raise
            pool.shutdown(wait=True)
        else:
            for i, m in enumerate(mspecs):
                interrupts.check()
                results[i], t = run_muscle(ctx, m)
                results[i] = on_muscle(mot.time, results[i]) if on_muscle else results[i]
                muscle_timings.append(t)
                bar.update(1)
    finally:
        bar.close()
    for t in muscle_timings:   # per-muscle stages summed (thread time when jobs > 1)
        for k, v in t.items():
            timings[k] = timings.get(k, 0.0) + v
    timings["total"] = _time.perf_counter() - t_start
    timings["total_cpu"] = _time.process_time() - c_start     # every thread of the process
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
            owners = [m.name for m in spec.muscles if unknown[0] in m.action_lines]
            hint = (f"'{unknown[0]}' is an OpenSim muscle, an action line of {', '.join(owners)}: use "
                    f"--muscle {owners[0]}" if owners else f"Use one of: {', '.join(spec.muscle_names)}")
            raise InputError(f"no muscle '{unknown[0]}' in the fibre model", file=spec.file, where="--muscle",
                             fix=hint + ".")
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
    """Read every mesh and bone file of the muscles once (`fibres.mesh.surface.read_mesh`), so that a
    damaged file is reported before any work or output folder (the run reads them again)."""
    from fibres.mesh.surface import read_mesh

    for m in mspecs:
        for path in ([m.mesh] if m.mesh is not None else []) + [p for _, p in m.bones]:
            read_mesh(path)
