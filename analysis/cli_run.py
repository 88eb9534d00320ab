"""``fibres run [SPEC] [--motion FILE] [--out DIR] [--muscle NAME]... [--fibres N] [--resolution R]
[--template NAME] [--frames START:STOP:STEP] [--jobs N] [--transport bind|decompose] [--no-plots]
[--sto] [--quiet]``.

Runs `analysis.run` and writes into DIR (default ``fibres-out/``) the files of INTERFACE.md:
the four CSV tables, ``summary.csv``, ``run.json``, ``plots/*.png`` and ``fibres/<muscle>.pvd`` +
``fibres/<muscle>_<frame>.vtp`` (plus, with ``--sto``, OpenSim ``.sto`` copies of the
action-line and fibre-summary tables).

No partial output: everything is first written into a hidden staging folder inside DIR and
moved into place (``os.replace``, one file at a time, atomic each) only after every file was
written; on any failure or Ctrl-C the staging folder is removed, so DIR holds either the
previous run's files or this run's, and a rerun works. The output folder is checked before the
long computation starts.

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
import shutil
import sys
import tempfile
import time as _time
import warnings
from pathlib import Path

from .errors import InputError

__all__ = ["add_arguments", "execute", "default_spec", "write_outputs"]


def default_spec() -> Path:
    """The bundled example fibre model in ``models/`` next to the package sources."""
    import analysis

    models = Path(analysis.__file__).resolve().parents[1] / "models"
    preferred = models / "arm_example.toml"
    if preferred.is_file():
        return preferred
    found = sorted(models.glob("*.toml"))
    if not found:
        raise InputError("no SPEC given and the bundled example model is missing", file=models,
                         fix="Pass a fibre-model .toml file: fibres run MODEL.toml.")
    return found[0]


def add_arguments(parser) -> None:
    from .frames_option import add_frames_argument

    parser.add_argument("spec", nargs="?", default=None, metavar="SPEC",
                        help="fibre model (.toml); default: the bundled example in models/")
    parser.add_argument("--motion", default=None, metavar="FILE",
                        help="motion (.mot/.sto); default: the 'motion' of the fibre model")
    parser.add_argument("--out", default="fibres-out", metavar="DIR", help="output folder (default fibres-out)")
    parser.add_argument("--muscle", action="append", default=None, metavar="NAME",
                        help="run only this muscle of the fibre model (repeatable)")
    parser.add_argument("--fibres", type=int, default=None, metavar="N", help="fibres per muscle")
    parser.add_argument("--resolution", type=int, default=None, metavar="R", help="segments per fibre")
    parser.add_argument("--template", default=None, metavar="NAME", help="fibre template for every muscle")
    add_frames_argument(parser)
    parser.add_argument("--jobs", type=int, default=1, metavar="N", help="muscles in parallel (default 1)")
    parser.add_argument("--transport", choices=("bind", "decompose"), default="bind",
                        help="how the rest fibres reach each frame: bound to the action lines with the "
                             "surface (default) or decomposed again per frame with the rest plan")
    parser.add_argument("--no-plots", action="store_true", help="do not draw plots/*.png")
    parser.add_argument("--sto", action="store_true",
                        help="also write OpenSim .sto copies of the action-line and fibre-summary tables")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    parser.add_argument("--force", action="store_true",
                        help="write into DIR even if it is /, the home folder, or holds a git "
                             "repository or a Python package")
    parser.add_argument("--max-memory", default=None, metavar="SIZE",
                        help="refuse a run estimated to need more memory than SIZE (e.g. 8G, 500M; "
                             "default: 80%% of the physical memory)")


def execute(args) -> int:
    """Run ``fibres run``; returns the exit status (errors are raised as InputError). Warnings of
    the readers are printed as one line each."""
    with warnings.catch_warnings():
        warnings.showwarning = _show_warning
        return _execute(args)


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """Warnings of the readers (motion header counts, ranges, surface repairs) as one line each."""
    text = " ".join(str(message).split())
    print(f"fibres run: warning: {text}", file=sys.stderr)


def _execute(args) -> int:
    from .budget import parse_size
    from .out_folder import OutFolderLock, check_out_folder, clean_stale
    from .output_files import prepare_out_dir
    from .run import _select_muscles, check_mesh_files, run
    from .spec import load_spec

    spec = Path(args.spec) if args.spec is not None else default_spec()
    for key, val in (("--fibres", args.fibres), ("--resolution", args.resolution), ("--jobs", args.jobs)):
        if val is not None and val < 1:
            raise InputError(f"{key} must be >= 1, got {val}", where=key, fix=f"Give {key} a whole number >= 1.")
    max_memory = parse_size(args.max_memory, where="--max-memory")
    check_out_folder(args.out, force=args.force)
    lock = OutFolderLock(args.out)
    if Path(args.out).is_dir():   # a second run into a busy folder refuses before any work
        lock.acquire()
    try:
        # bad input is reported before the output folder is created
        loaded = load_spec(spec)
        chosen = _select_muscles(loaded, args.muscle, fibres=args.fibres, resolution=args.resolution,
                                 template=args.template)
        check_mesh_files(chosen)
        out = prepare_out_dir(args.out)
        if lock.fd is None:
            lock.acquire()
        clean_stale(out)
        result = run(loaded, args.motion, muscles=args.muscle, fibres=args.fibres, resolution=args.resolution,
                     template=args.template, frames=args.frames, quiet=args.quiet, jobs=args.jobs,
                     transport=args.transport, max_memory=max_memory, out_dir=out)
        command = ["fibres"] + sys.argv[1:] if sys.argv and Path(sys.argv[0]).name == "fibres" else None
        write_outputs(result, out, plots=not args.no_plots, sto=args.sto, quiet=args.quiet, command=command)
    finally:
        lock.release()
    if not args.quiet:
        print(f"fibres run: wrote {out}/ ({len(result.muscles)} muscles, {len(result.time)} frames)",
              file=sys.stderr)
    return 0


def write_outputs(result, out_dir, *, plots=True, vtk=True, sto=False, quiet=True, command=None) -> list:
    """Write every output file of a run into ``out_dir`` (staged, then moved into place).

    Muscle and coordinate names become file names only through `analysis.file_names.file_stems`
    (the mapping is ``file_names`` in run.json); every path is checked to stay inside the staging
    folder (`output_files.confined_to`). Files of the previous run in ``out_dir`` that this run
    does not write are removed (`out_folder.publish`; the list is ``files`` in run.json).
    Returns the final paths written.
    """
    from . import interrupts
    from .file_names import file_stems
    from .out_folder import STAGING_PREFIX, publish, staged_files
    from .output_files import confined_to
    from .progress import progress
    from .run_record import write_run_json
    from .tables import write_tables

    out = Path(out_dir)
    stems = file_stems(m.name for m in result.muscles)
    coord_stems = file_stems(c for m in result.muscles for c in m.coordinates)
    staging = Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, dir=out))
    timings = {}
    try:
        with confined_to(staging):
            t0 = _time.perf_counter()
            write_tables(result, staging)
            timings["write_tables"] = _time.perf_counter() - t0
            interrupts.check()
            if sto:
                t0 = _time.perf_counter()
                write_sto_files(result, staging, coordinate_stems=coord_stems)
                timings["write_sto"] = _time.perf_counter() - t0
            if plots:
                t0 = _time.perf_counter()
                _write_plots(result, staging / "plots", stems, quiet=quiet, progress=progress)
                timings["plots"] = _time.perf_counter() - t0
            interrupts.check()
            if vtk and any(m.fibre_points is not None for m in result.muscles):
                t0 = _time.perf_counter()
                _write_vtk(result, staging / "fibres", stems, quiet=quiet, progress=progress)
                timings["vtk_files"] = _time.perf_counter() - t0
            files = [f for f in staged_files(staging) if f != "run.json"] + ["run.json"]
            write_run_json(result, staging / "run.json", command=command, extra_timings=timings,
                           extra={"files": files,
                                  "file_names": {"muscles": stems, "coordinates": coord_stems}})
        interrupts.check()
        return publish(staging, out)
    finally:
        with contextlib.suppress(FileNotFoundError):
            shutil.rmtree(staging)


def _write_plots(result, folder: Path, stems, *, quiet, progress):
    """Per muscle: fibre-length band over time, moment arm vs coordinate, L/L_rest histogram."""
    from . import plots

    from . import interrupts

    folder.mkdir(parents=True, exist_ok=True)
    motion_types = result.settings.get("motion_types", {})
    for m in progress(result.muscles, desc="plots", quiet=quiet, unit="muscle"):
        interrupts.check()
        cols = [result.coordinate_names.index(c) for c in m.coordinates]
        plots.plot_muscle(folder, m.name, times=result.time, fibre_lengths=m.fibre_lengths,
                          line_lengths=m.action_line_lengths, line_names=m.action_lines,
                          coordinate_values=result.q[:, cols], fibre_moment_arms=m.fibre_moment_arms,
                          line_moment_arms=m.action_line_moment_arms, coordinate_names=m.coordinates,
                          rest_lengths=m.rest_lengths, stem=stems[m.name],
                          rotational=[motion_types.get(c, "rotational") != "translational"
                                      for c in m.coordinates])


def _write_vtk(result, folder: Path, stems, *, quiet, progress):
    """``fibres/<stem>.pvd`` + ``<stem>_<frame>.vtp`` (cell data ``fibre``, ``length``)."""
    from . import interrupts, vtk_files

    folder.mkdir(parents=True, exist_ok=True)
    for m in progress(result.muscles, desc="3D files", quiet=quiet, unit="muscle"):
        interrupts.check()
        if m.fibre_points is not None:
            vtk_files.write_fibre_frames(folder, stems[m.name], m.fibre_points, times=result.time,
                                         cell_data={"length": m.fibre_lengths})
        if m.surface_vertices is not None:
            vtk_files.write_surface_frames(folder, stems[m.name], m.surface_vertices, m.surface_faces,
                                           times=result.time)


def write_sto_files(result, folder, *, coordinate_stems=None) -> list:
    """OpenSim .sto copies, named like MuscleAnalysis's: ``MuscleAnalysis_Length.sto`` (columns:
    action lines), ``MuscleAnalysis_MomentArm_<coord>.sto``, and the fibre summaries
    ``FibreAnalysis_Length.sto`` / ``FibreAnalysis_MomentArm_<coord>.sto`` with columns
    ``<muscle>_median``, ``<muscle>_p5``, ``<muscle>_p95`` (SI units, inDegrees=no).
    ``<coord>`` is the coordinate's safe file stem (`analysis.file_names`)."""
    import numpy as np

    from motion import write_sto

    from .file_names import file_stems
    from .output_files import checked_path

    if coordinate_stems is None:
        coordinate_stems = file_stems(c for m in result.muscles for c in m.coordinates)

    folder = Path(folder)
    written = []
    lengths, fibre_len = {}, {}
    arms, fibre_arms = {}, {}
    for m in result.muscles:
        for i, name in enumerate(m.action_lines):
            lengths[name] = m.action_line_lengths[:, i]
        for q, v in zip(("p5", "median", "p95"), np.percentile(m.fibre_lengths, [5, 50, 95], axis=1)):
            fibre_len[f"{m.name}_{q}"] = v
        for c, coord in enumerate(m.coordinates):
            for i, name in enumerate(m.action_lines):
                arms.setdefault(coord, {})[name] = np.nan_to_num(m.action_line_moment_arms[:, i, c])
            pct = np.percentile(m.fibre_moment_arms[:, :, c], [5, 50, 95], axis=1)
            for q, v in zip(("p5", "median", "p95"), pct):
                fibre_arms.setdefault(coord, {})[f"{m.name}_{q}"] = v
    tables = {"MuscleAnalysis_Length": lengths, "FibreAnalysis_Length": fibre_len}
    tables.update({f"MuscleAnalysis_MomentArm_{coordinate_stems[c]}": v for c, v in arms.items()})
    tables.update({f"FibreAnalysis_MomentArm_{coordinate_stems[c]}": v for c, v in fibre_arms.items()})
    for name, cols in tables.items():
        if cols:
            path = checked_path(folder / f"{name}.sto")
            write_sto(path, result.time, cols, name=name)
            written.append(path)
    return written
