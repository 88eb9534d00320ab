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
"""
from __future__ import annotations

import contextlib
import os
import shutil
import sys
import tempfile
import time as _time
import warnings
from pathlib import Path

from .errors import FibreWarning, InputError

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


def execute(args) -> int:
    from .output_files import prepare_out_dir
    from .run import _select_muscles, run
    from .spec import load_spec

    spec = Path(args.spec) if args.spec is not None else default_spec()
    for key, val in (("--fibres", args.fibres), ("--resolution", args.resolution), ("--jobs", args.jobs)):
        if val is not None and val < 1:
            raise InputError(f"{key} must be >= 1, got {val}", where=key, fix=f"Give {key} a whole number >= 1.")
    # bad input is reported before the output folder is created
    loaded = load_spec(spec)
    _select_muscles(loaded, args.muscle, fibres=args.fibres, resolution=args.resolution, template=args.template)
    out = prepare_out_dir(args.out)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FibreWarning)      # printed below from the notes, once
        result = run(loaded, args.motion, muscles=args.muscle, fibres=args.fibres, resolution=args.resolution,
                     template=args.template, frames=args.frames, quiet=args.quiet, jobs=args.jobs,
                     transport=args.transport)
    for m in result.muscles:
        for note in m.notes:
            if note.startswith("warning: "):
                print(f"fibres run: warning: muscle {m.name!r}: {note[len('warning: '):]}", file=sys.stderr)
    command = ["fibres"] + sys.argv[1:] if sys.argv and Path(sys.argv[0]).name == "fibres" else None
    write_outputs(result, out, plots=not args.no_plots, sto=args.sto, quiet=args.quiet, command=command)
    if not args.quiet:
        print(f"fibres run: wrote {out}/ ({len(result.muscles)} muscles, {len(result.time)} frames)",
              file=sys.stderr)
    return 0


def write_outputs(result, out_dir, *, plots=True, vtk=True, sto=False, quiet=True, command=None) -> list:
    """Write every output file of a run into ``out_dir`` (staged, then moved into place).

    Returns the final paths written.
    """
    from .progress import progress
    from .run_record import write_run_json
    from .tables import write_tables

    out = Path(out_dir)
    staging = Path(tempfile.mkdtemp(prefix=".fibres-run-", dir=out))
    timings = {}
    try:
        t0 = _time.perf_counter()
        write_tables(result, staging)
        timings["write_tables"] = _time.perf_counter() - t0
        if sto:
            t0 = _time.perf_counter()
            write_sto_files(result, staging)
            timings["write_sto"] = _time.perf_counter() - t0
        if plots:
            t0 = _time.perf_counter()
            _write_plots(result, staging / "plots", quiet=quiet, progress=progress)
            timings["plots"] = _time.perf_counter() - t0
        if vtk and any(m.fibre_points is not None for m in result.muscles):
            t0 = _time.perf_counter()
            _write_vtk(result, staging / "fibres", quiet=quiet, progress=progress)
            timings["vtk_files"] = _time.perf_counter() - t0
        write_run_json(result, staging / "run.json", command=command, extra_timings=timings)
        return _publish(staging, out)
    finally:
        with contextlib.suppress(FileNotFoundError):
            shutil.rmtree(staging)


def _publish(staging: Path, out: Path) -> list:
    """Move every staged file to the same relative place in ``out`` (run.json last)."""
    files = sorted((p for p in staging.rglob("*") if p.is_file()), key=lambda p: p.name == "run.json")
    written = []
    for src in files:
        dst = out / src.relative_to(staging)
        dst.parent.mkdir(parents=True, exist_ok=True)
        os.replace(src, dst)
        written.append(dst)
    return written


def _write_plots(result, folder: Path, *, quiet, progress):
    """Per muscle: fibre-length band over time, moment arm vs coordinate, L/L_rest histogram."""
    from . import plots

    folder.mkdir(parents=True, exist_ok=True)
    motion_types = result.settings.get("motion_types", {})
    for m in progress(result.muscles, desc="plots", quiet=quiet, unit="muscle"):
        cols = [result.coordinate_names.index(c) for c in m.coordinates]
        plots.plot_muscle(folder, m.name, times=result.time, fibre_lengths=m.fibre_lengths,
                          line_lengths=m.action_line_lengths, line_names=m.action_lines,
                          coordinate_values=result.q[:, cols], fibre_moment_arms=m.fibre_moment_arms,
                          line_moment_arms=m.action_line_moment_arms, coordinate_names=m.coordinates,
                          rest_lengths=m.rest_lengths, normalized_lengths=m.normalized_lengths,
                          line_normalized=m.line_normalized_lengths,
                          rotational=[motion_types.get(c, "rotational") != "translational"
                                      for c in m.coordinates])


def _write_vtk(result, folder: Path, *, quiet, progress):
    """``fibres/<muscle>.pvd`` + ``<muscle>_<frame>.vtp`` (cell data ``fibre``, ``length``,
    ``normalized_length``)."""
    from . import vtk_files

    folder.mkdir(parents=True, exist_ok=True)
    for m in progress(result.muscles, desc="3D files", quiet=quiet, unit="muscle"):
        if m.fibre_points is not None:
            vtk_files.write_fibre_frames(folder, m.name, m.fibre_points, times=result.time,
                                         cell_data={"length": m.fibre_lengths,
                                                    "normalized_length": m.normalized_lengths})
        if m.surface_vertices is not None:
            vtk_files.write_surface_frames(folder, m.name, m.surface_vertices, m.surface_faces,
                                           times=result.time)


def write_sto_files(result, folder) -> list:
    """OpenSim .sto copies, named like MuscleAnalysis's: ``MuscleAnalysis_Length.sto`` (columns:
    action lines), ``MuscleAnalysis_MomentArm_<coord>.sto``, and the fibre summaries
    ``FibreAnalysis_Length.sto`` / ``FibreAnalysis_MomentArm_<coord>.sto`` with columns
    ``<muscle>_median``, ``<muscle>_p5``, ``<muscle>_p95`` (SI units, inDegrees=no)."""
    import numpy as np

    from motion import write_sto

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
    tables.update({f"MuscleAnalysis_MomentArm_{c}": v for c, v in arms.items()})
    tables.update({f"FibreAnalysis_MomentArm_{c}": v for c, v in fibre_arms.items()})
    for name, cols in tables.items():
        if cols:
            path = folder / f"{name}.sto"
            write_sto(path, result.time, cols, name=name)
            written.append(path)
    return written
