"""``fibres run [SPEC] [--motion FILE] [--out DIR] [--muscle NAME]... [--fibres N] [--resolution R]
[--template NAME] [--frames START:STOP:STEP] [--jobs N] [--transport bind|decompose] [--no-plots]
[--setup SETUP.xml] [--sto | --no-sto] [--sto-fibres] [--osim [--keep-original] [--muscle-class CLASS] [--max-order N]]
[--quiet]``.

Runs `analysis.run` and writes into DIR (default ``fibres-out/``) the files of INTERFACE.md:
the four tables and ``summary`` (``.csv`` and ``.parquet``), ``run.json``, ``plots/*.png``,
``fibres/<muscle>.pvd`` + ``fibres/<muscle>_<frame>.vtp``, OpenSim ``.sto`` copies of the
action-line and fibre tables (`analysis.sto_files`; ``--no-sto`` leaves them out) and, with
``--osim``, the fibre-resolved OpenSim model (`analysis.osim_export`).

No partial output: everything is first written into a hidden staging folder inside DIR and
moved into place (``os.replace``, one file at a time, atomic each) only after every file was
written; on any failure or Ctrl-C the staging folder is removed, so DIR holds either the
previous run's files or this run's, and a rerun works. The fibre model, its meshes and the motion
(with ``--frames``) are read, and the output folder is checked, before the start line is printed
and the long computation starts: an input error ends the run before its start line.

The run owns DIR while it works (`analysis.out_folder`): it refuses ``/``, the home folder and
folders holding a git repository or a Python package unless ``--force``; it locks DIR against a
second run; it removes the files of the previous run (listed in its ``run.json``) that it does not
write again; it cleans staging folders of killed runs. Names from the input files become file
names only through `analysis.file_names` (mapping in ``run.json``), and every path written is
checked to stay inside the staging folder. Memory is estimated before the long computation
(`analysis.budget`, ``--max-memory``).
"""
from __future__ import annotations

import contextlib
import contextvars
import shutil
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

from .errors import FibreWarning, InputError
from .muscle_chain import timed
from .sto_files import write_sto_files

__all__ = ["add_arguments", "execute", "default_spec", "write_outputs", "add_model_arguments"]


def default_spec() -> Path:
    """The bundled example fibre model: ``models/`` next to the package sources (a clone or an
    editable install), else the copy installed as package data (``analysis/example/``)."""
    import analysis

    here = Path(analysis.__file__).resolve().parent
    for models in (here.parent / "models", here / "example"):
        preferred = models / "arm_example.toml"
        if preferred.is_file():
            return preferred
    for models in (here.parent / "models", here / "example"):
        found = sorted(models.glob("*.toml"))
        if found:
            return found[0]
    raise InputError("no SPEC given and the bundled example model is missing", file=here / "example",
                     fix="Pass a fibre-model .toml file: fibres run MODEL.toml (or reinstall musclefibres).")


def add_model_arguments(parser, *, verb: str, motion_help: str, out_help: str, out_default=None,
                        out_metavar="DIR") -> None:
    """The arguments ``fibres run`` and ``fibres export-osim`` share: SPEC, --motion, --out,
    --muscle, --fibres, --resolution, --template (``verb`` and the helps are the command's)."""
    parser.add_argument("spec", nargs="?", default=None, metavar="SPEC",
                        help="fibre model (.toml); default: the bundled example in models/")
    parser.add_argument("--motion", default=None, metavar="FILE", help=motion_help)
    parser.add_argument("--out", default=out_default, metavar=out_metavar, help=out_help)
    parser.add_argument("--muscle", action="append", default=None, metavar="NAME",
                        help=f"{verb} only this muscle of the fibre model (repeatable)")
    parser.add_argument("--fibres", type=int, default=None, metavar="N", help="fibres per muscle")
    parser.add_argument("--resolution", type=int, default=None, metavar="R", help="segments per fibre")
    parser.add_argument("--template", default=None, metavar="NAME", help="fibre template for every muscle")


def add_arguments(parser) -> None:
    from .frames_option import add_frames_argument

    add_model_arguments(parser, verb="run", out_default="fibres-out",
                        motion_help="motion (.mot/.sto); default: the 'motion' of the fibre model",
                        out_help="output folder (default fibres-out)")
    parser.add_argument("--setup", default=None, metavar="SETUP.xml",
                        help="an OpenSim AnalyzeTool setup: its coordinates_file, initial/final time and "
                             "MuscleAnalysis muscle list in place of --motion/--frames (analysis/setup_file.py)")
    parser.add_argument("--slicing", default=None, choices=("harmonic", "planes"),
                        help="cross-sections for every muscle: isolines of a harmonic field or parallel "
                             "planes (Kohout 2012); default: each muscle's slicing in the TOML, else "
                             "harmonic with a mesh and planes for a generated surface")
    add_frames_argument(parser)
    parser.add_argument("--jobs", type=int, default=1, metavar="N", help="muscles in parallel (default 1)")
    parser.add_argument("--transport", choices=("bind", "decompose"), default="bind",
                        help="how the rest fibres reach each frame: bound to the action lines with the "
                             "surface (default) or decomposed again per frame with the rest plan")
    parser.add_argument("--no-plots", action="store_true", help="do not draw plots/*.png")
    parser.add_argument("--sto", dest="sto", action="store_true", default=True,
                        help="write OpenSim .sto copies of the action-line and fibre-summary tables, "
                             "MuscleAnalysis names (the default)")
    parser.add_argument("--no-sto", dest="sto", action="store_false", help="do not write the .sto files")
    parser.add_argument("--sto-fibres", action="store_true",
                        help="also write one .sto per muscle with a column per fibre (FibreAnalysis_<muscle>_*.sto)")
    parser.add_argument("--no-scene", action="store_true",
                        help="do not write scene/ (bones, surfaces, action lines and fibres per frame in one .pvd)")
    parser.add_argument("--scene-step", type=int, default=None, metavar="K",
                        help="write every K-th frame to scene/ (default: at most 100 frames)")
    parser.add_argument("--osim", action="store_true",
                        help="also write <model>_fibres.osim: the OpenSim model with one muscle per fibre "
                             "(see fibres export-osim; fit report in run.json)")
    from .cli_export import add_export_options

    add_export_options(parser)
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    parser.add_argument("--force", action="store_true",
                        help="write into DIR even if it is /, the home folder, or holds a git "
                             "repository or a Python package")
    parser.add_argument("--max-memory", default=None, metavar="SIZE",
                        help="refuse a run estimated to need more memory than SIZE (e.g. 8G, 500M; "
                             "default: 80%% of the physical memory)")


def execute(args) -> int:
    """Run ``fibres run``; returns the exit status (errors are raised as InputError)."""
    from .budget import parse_size
    from .out_folder import OutFolderLock, check_out_folder

    spec = Path(args.spec) if args.spec is not None else default_spec()
    for key, val in (("--fibres", args.fibres), ("--resolution", args.resolution), ("--jobs", args.jobs),
                     ("--scene-step", args.scene_step)):
        if val is not None and val < 1:
            raise InputError(f"{key} must be >= 1, got {val}", where=key, fix=f"Give {key} a whole number >= 1.")
    max_memory = parse_size(args.max_memory, where="--max-memory")
    check_out_folder(args.out, force=args.force)
    lock = OutFolderLock(args.out)
    existed = Path(args.out).exists()
    if Path(args.out).is_dir():   # a second run into a busy folder refuses before any work
        lock.acquire()
    try:
        return _execute(args, spec, lock, existed, max_memory)
    finally:
        lock.release()


def _execute(args, spec, lock, existed, max_memory) -> int:
    from .out_folder import clean_stale
    from .output_files import prepare_out_dir
    from . import budget
    from .run import _select_muscles, check_mesh_files, read_motion, run
    from .spec import load_spec

    # bad input is reported before the output folder is created
    loaded = load_spec(spec)
    if args.osim:
        from .cli_export import check_export_options

        check_export_options(args)
    motion_arg, frames_arg, muscles_arg = args.motion, args.frames, args.muscle
    if getattr(args, "setup", None):
        from .setup_file import apply_setup, read_setup

        if args.motion is not None or args.frames is not None:
            raise InputError("--setup gives the motion and the time range", where="--setup",
                             fix="Give either --setup SETUP.xml or --motion/--frames, not both.")
        plan = apply_setup(read_setup(args.setup), loaded)
        motion_arg, frames_arg = plan["motion"], plan["frames"]
        muscles_arg = args.muscle or plan["muscles"]
    chosen = _select_muscles(loaded, muscles_arg, fibres=args.fibres, resolution=args.resolution,
                             template=args.template, slicing=args.slicing)
    check_mesh_files(chosen)
    # the motion too: its errors and warnings come before the start line, and no folder is made
    limit = budget.default_budget() if max_memory is None else int(max_memory)
    mot_path, motion, _rows = read_motion(loaded, motion_arg, chosen, frames_arg, limit)
    out = prepare_out_dir(args.out)
    staging = tables = None
    try:
        if lock.fd is None:
            lock.acquire()
        clean_stale(out)
        from .progress import start_notice

        start_notice(f"{len(chosen)} muscle(s): moving, wrapping and decomposing the surfaces", args.quiet)
        staging = open_staging(out)
        if len(chosen) > 1:    # the per-muscle tables are written as the muscles are done
            from .output_files import confined_to
            from .tables import TableStreams

            with confined_to(staging):
                tables = TableStreams(staging)
        on_muscle = muscle_files_writer(staging, [m.name for m in chosen], scene_step=args.scene_step,
                                        scene=not args.no_scene, tables=tables)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FibreWarning)      # printed below from the notes, once
            result = run(loaded, motion, muscles=muscles_arg, fibres=args.fibres,
                         resolution=args.resolution, template=args.template, frames=frames_arg,
                         quiet=args.quiet, jobs=args.jobs, transport=args.transport,
                         keep_surfaces=not args.no_scene, slicing=args.slicing,
                         max_memory=max_memory, out_dir=out, on_muscle=on_muscle)
        for m in result.muscles:
            for note in m.notes:
                if note.startswith("warning: "):
                    print(f"fibres run: warning: muscle {m.name!r}: {note[len('warning: '):]}",
                          file=sys.stderr)
        import dataclasses

        # run() got the motion read above: run.json names (and hashes) its file, and the setup's
        inputs = dict(result.inputs)
        if mot_path is not None:
            inputs = {"spec": inputs.pop("spec"), "model": inputs.pop("model"),
                      "motion": Path(mot_path).resolve(), **inputs}
        if getattr(args, "setup", None):
            inputs["setup"] = Path(args.setup).resolve()
        result = dataclasses.replace(result, inputs=inputs)
        command = ["fibres"] + sys.argv[1:] if sys.argv and Path(sys.argv[0]).name == "fibres" else None
        osim = None
        if args.osim:
            from .cli_export import announcer

            osim = {"spec": loaded, "keep_original": args.keep_original, "muscle_class": args.muscle_class,
                    "max_order": args.max_order, "announce": announcer(args.quiet)}
        scene = None if args.no_scene else {"spec": loaded, "step": args.scene_step}
        write_outputs(result, out, plots=not args.no_plots, sto=args.sto, sto_fibres=args.sto_fibres,
                      quiet=args.quiet, command=command, osim=osim, scene=scene, staging=staging,
                      tables=tables)
    except BaseException:
        if tables is not None:
            tables.abort()
        if staging is not None:
            shutil.rmtree(staging, ignore_errors=True)
        lock.release()
        if not existed:    # a failed run leaves no empty output folder behind
            with contextlib.suppress(OSError):
                out.rmdir()
        raise
    if not args.quiet:
        print(f"fibres run: wrote {out}/ ({len(result.muscles)} muscles, {len(result.time)} frames)",
              file=sys.stderr)
    return 0


def write_outputs(result, out_dir, *, plots=True, vtk=True, sto=True, sto_fibres=False, quiet=True,
                  command=None, osim=None, scene=None, staging=None, tables=None) -> list:
    """Write every output file of a run into ``out_dir`` (staged, then moved into place).

    ``scene``: None, or ``{"spec": FibreModelSpec, "step": K or None}`` to write ``scene/``
    (`analysis.scene`).
    ``osim``: None, or the keyword arguments of `analysis.osim_export.export_osim` (with ``spec``)
    to also write ``<model>_fibres.osim``; its record goes into run.json under ``osim_export``.

    ``staging``: a staging folder made by `open_staging` that already holds the muscles' 3D files
    (`muscle_files_writer`, written during the run); they are not written again. ``tables``: the
    `analysis.tables.TableStreams` in it that received every muscle during the run (finished here).

    Muscle and coordinate names become file names only through `analysis.file_names.file_stems`
    (the mapping is ``file_names`` in run.json); every path is checked to stay inside the staging
    folder (`output_files.confined_to`). Files of the previous run in ``out_dir`` that this run
    does not write are removed (`out_folder.publish`; the list is ``files`` in run.json).
    Returns the final paths written.
    """
    from . import interrupts
    from .file_names import file_stems
    from .out_folder import publish, staged_files
    from .output_files import confined_to
    from .progress import progress
    from .run_record import write_run_json
    from .tables import write_tables

    out = Path(out_dir)
    stems = file_stems(m.name for m in result.muscles)
    coord_stems = file_stems(c for m in result.muscles for c in m.coordinates)
    streamed = staging is not None
    staging = Path(staging) if streamed else open_staging(out)
    timings = {}
    plotting = None
    try:
        with confined_to(staging):
            if plots:   # worker processes draw while this process writes the tables and the scene
                plotting = _start_plots(result, staging / "plots", stems, quiet=quiet, progress=progress)
            with timed(timings, "write_tables", process=True):
                write_tables(result, staging, streamed=tables)
            interrupts.check()
            if sto:
                with timed(timings, "write_sto", process=True):
                    write_sto_files(result, staging, per_fibre=sto_fibres, muscle_stems=stems,
                                    coordinate_stems=coord_stems)
            interrupts.check()
            if vtk and not streamed and any(m.fibre_points is not None for m in result.muscles):
                with timed(timings, "vtk_files", process=True):
                    _write_vtk(result, staging / "fibres", stems, quiet=quiet, progress=progress)
            interrupts.check()
            if scene is not None:
                from .scene import write_scene

                with timed(timings, "scene", process=True):
                    write_scene(staging / "scene", result, scene["spec"], step=scene.get("step"))
            extra = {}
            if osim is not None:
                from .osim_export import export_osim

                interrupts.check()
                with timed(timings, "osim_export", process=True):
                    kw = dict(osim)
                    spec = kw.pop("spec")
                    name = f"{Path(spec.model_path).stem}_fibres.osim"
                    extra = {"osim_export": export_osim(spec, result, staging / name, final_folder=out, **kw)}
                    extra["osim_export"]["file"] = name
            if plotting is not None:
                with timed(timings, "plots", process=True):   # this process' share: the waiting
                    plotting, finish = None, plotting
                    finish()
            extra["files"] = [f for f in staged_files(staging) if f != "run.json"] + ["run.json"]
            extra["file_names"] = {"muscles": stems, "coordinates": coord_stems}
            write_run_json(result, staging / "run.json", command=command, extra_timings=timings, extra=extra)
        interrupts.check()
        return publish(staging, out)
    finally:
        if plotting is not None:       # failed or interrupted before the plots were collected
            plotting(cancel=True)
        with contextlib.suppress(FileNotFoundError):
            shutil.rmtree(staging)


#: muscles from which the plots are drawn in worker processes (fewer: in this process)
PARALLEL_PLOTS_FROM = 4
#: True in a context (thread or task) whose runs draw their plots in this process whatever the
#: number of muscles: a study's trials, which already keep every core busy, in Dask workers
#: that may not start processes (`analysis.study_tasks`)
PLOTS_IN_THIS_PROCESS = contextvars.ContextVar("PLOTS_IN_THIS_PROCESS", default=False)


def _plot_tasks(result, folder: Path, stems) -> list:
    """The keyword arguments of `plots.plot_muscle` for every muscle (plain arrays)."""
    motion_types = result.settings.get("motion_types", {})
    tasks = []
    for m in result.muscles:
        cols = [result.coordinate_names.index(c) for c in m.coordinates]
        tasks.append(dict(out_dir=folder, muscle=m.name, times=result.time, fibre_lengths=m.fibre_lengths,
                          line_lengths=m.action_line_lengths, line_names=m.action_lines,
                          coordinate_values=result.q[:, cols], fibre_moment_arms=m.fibre_moment_arms,
                          line_moment_arms=m.action_line_moment_arms, coordinate_names=m.coordinates,
                          rest_lengths=m.rest_lengths, normalized_lengths=m.normalized_lengths,
                          line_normalized=m.line_normalized_lengths, stem=stems[m.name],
                          rotational=[motion_types.get(c, "rotational") != "translational"
                                      for c in m.coordinates]))
    return tasks


def _start_plots(result, folder: Path, stems, *, quiet, progress):
    """Start drawing the plots of every muscle (fibre-length band over time, moment arm vs
    coordinate, L/L_rest histogram); returns ``finish(cancel=False)``, which waits for them (or,
    with ``cancel``, cancels the pending ones and waits for the running ones).

    From `PARALLEL_PLOTS_FROM` muscles on, the muscles are drawn in worker processes (one per
    core, at most 4; matplotlib holds the GIL while drawing, so threads would not help), which
    run while the caller writes the other files; fewer muscles are drawn in this process by
    ``finish``. Workers are spawned (not forked from this multi-threaded process) and only write
    files; Ctrl-C cancels the pending ones."""
    import concurrent.futures
    import multiprocessing
    import os

    from . import interrupts, plots

    folder.mkdir(parents=True, exist_ok=True)
    tasks = _plot_tasks(result, folder, stems)
    workers = min(os.cpu_count() or 1, 4, len(tasks))
    if len(tasks) < PARALLEL_PLOTS_FROM or workers < 2 or PLOTS_IN_THIS_PROCESS.get():
        def finish_here(cancel=False):
            if cancel:
                return
            bar = progress(total=len(tasks), desc="plots", quiet=quiet, unit="muscle")
            try:
                for kw in tasks:
                    interrupts.check()
                    plots.plot_muscle(**kw)
                    bar.update(1)
            finally:
                bar.close()
        return finish_here
    pool = concurrent.futures.ProcessPoolExecutor(max_workers=workers,
                                                  mp_context=multiprocessing.get_context("spawn"))
    futures = [pool.submit(plots.plot_muscle, **kw) for kw in tasks]

    def finish(cancel=False):
        if cancel:
            pool.shutdown(wait=True, cancel_futures=True)   # no worker writes after we return
            return
        bar = progress(total=len(tasks), desc="plots", quiet=quiet, unit="muscle")
        try:
            for fut in concurrent.futures.as_completed(futures):
                fut.result()
                bar.update(1)
                interrupts.check()
        except BaseException:
            pool.shutdown(wait=True, cancel_futures=True)
            raise
        finally:
            bar.close()
        pool.shutdown(wait=True)

    return finish


def open_staging(out) -> Path:
    """A new staging folder inside ``out`` (`out_folder.STAGING_PREFIX`): the run's files are
    written there and published by `write_outputs`; whoever opens it removes it on failure."""
    from .out_folder import STAGING_PREFIX

    return Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, dir=out))


def muscle_files_writer(staging: Path, names, *, scene_step=None, scene=True, tables=None):
    """The ``on_muscle`` hook of `analysis.run` for ``fibres run``: writes each muscle's 3D files
    (``fibres/``, `_write_vtk`) into ``staging`` as soon as the muscle is done, then keeps only
    what the scene needs of its fibre points and surfaces (the scene's frames,
    `scene.scene_frames`; nothing without a scene), so a whole model's points and surfaces are
    never in memory at once. ``tables``: an `analysis.tables.TableStreams` each muscle is added to."""
    import dataclasses

    from . import vtk_files
    from .file_names import file_stems
    from .output_files import confined_to
    from .scene import scene_frames

    stems = file_stems(names)
    folder = Path(staging) / "fibres"

    def on_muscle(time, m):
        folder.mkdir(parents=True, exist_ok=True)
        with confined_to(staging):
            _write_muscle_vtk(vtk_files, folder, stems[m.name], m, time)
            if tables is not None:
                tables.add(time, m)
        keep = scene_frames(len(time), scene_step) if scene else None

        def kept(a):
            return None if a is None or keep is None else np.ascontiguousarray(a[keep])

        return dataclasses.replace(m, fibre_points=kept(m.fibre_points), surface_vertices=kept(m.surface_vertices))

    return on_muscle


def _write_muscle_vtk(vtk_files, folder, stem, m, time):
    """The fibres of one muscle per frame (the wrapped surfaces are drawn by the scene only:
    docs/decisions.md, "A whole model over a whole trial")."""
    if m.fibre_points is not None:
        vtk_files.write_fibre_frames(folder, stem, m.fibre_points, times=time,
                                     cell_data={"length": m.fibre_lengths,
                                                "normalized_length": m.normalized_lengths})


def _write_vtk(result, folder: Path, stems, *, quiet, progress):
    """``fibres/<stem>.pvd`` + ``<stem>_<frame>.vtp`` (cell data ``fibre``, ``length``,
    ``normalized_length``)."""
    from . import interrupts, vtk_files

    folder.mkdir(parents=True, exist_ok=True)
    for m in progress(result.muscles, desc="3D files", quiet=quiet, unit="muscle"):
        interrupts.check()
        _write_muscle_vtk(vtk_files, folder, stems[m.name], m, result.time)
