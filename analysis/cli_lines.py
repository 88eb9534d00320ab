"""``fibres lines MODEL.osim MOTION.mot``: body poses and action lines, like OpenSim's MuscleAnalysis.

Writes into ``--out`` (default ``fibres-out/``), as INTERFACE.md says:

- ``body_poses.csv``: frame, time, body, tx, ty, tz, r00 ... r22 (v_ground = R v_body + t);
- ``action_lines.csv``: frame, time, muscle, action_line, length;
- ``action_line_moment_arms.csv``: frame, time, muscle, action_line, coordinate, moment_arm
  (r = -dL/dq), only for the coordinates each muscle spans.

The columns are those of ``fibres run``'s files of the same names; there ``muscle`` is the fibre
model's muscle and ``action_line`` the OpenSim path behind it, here both are the OpenSim path (each
path is its own muscle), so one reader handles either command's tables.

``frame`` is the 0-based index into the motion rows actually used (after ``--frames``), ``time``
the motion's time column. The output folder is checked before any work; the three files are
written to temporary names and renamed together at the end, so a failed run leaves none of them.
Warnings (unknown or missing motion columns; missing coordinates that the chosen paths span
apart from the others) are printed as one line each on stderr.
"""
from __future__ import annotations

import contextlib
import difflib
import sys
import warnings
from pathlib import Path

import numpy as np

from .errors import InputError
from .frames_option import add_frames_argument, resolve_frames
from .lines_tables import action_lines_table, body_poses_table, moment_arms_table
from .output_files import atomic_path, prepare_out_dir
from .progress import progress

__all__ = ["add_arguments", "execute", "compute_lines", "OUTPUT_FILES"]

OUTPUT_FILES = ("body_poses.csv", "action_lines.csv", "action_line_moment_arms.csv")

#: frames per batch: the progress bar moves once per batch (each batch is one vectorised call)
BATCH_FRAMES = 256


def add_arguments(parser) -> None:
    """Arguments of ``fibres lines``."""
    parser.add_argument("model", metavar="MODEL.osim", help="OpenSim model (.osim, 3.x or 4.x)")
    parser.add_argument("motion", metavar="MOTION.mot", help="motion (.mot or .sto)")
    parser.add_argument("--out", default="fibres-out", metavar="DIR",
                        help="output folder (default: fibres-out)")
    parser.add_argument("--force", action="store_true",
                        help="write into DIR even if it is /, the home folder, or holds a git "
                             "repository or a Python package")
    parser.add_argument("--muscle", action="append", default=None, metavar="NAME",
                        help="only this path force (repeatable; default: every path in the model)")
    add_frames_argument(parser)
    parser.add_argument("--quiet", action="store_true", help="no progress bar and no summary")


def _check_out_dir(out: Path) -> None:
    """Fail early (before any work) if ``out`` can never be written."""
    import os

    if out.exists():
        if not out.is_dir():
            raise InputError("the output folder is a file", file=out,
                             fix="Pass --out a folder name (or remove the file).")
        if not os.access(out, os.W_OK | os.X_OK):
            raise InputError("the output folder is not writable", file=out,
                             fix="Choose a folder you can write to with --out.")
        return
    parent = out.absolute().parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"cannot create the output folder: {parent} is not writable", file=out,
                         fix="Choose a folder you can write to with --out.")


def _select_muscles(model, names, model_file):
    """Model path names to compute, in the order asked (default: all, model order)."""
    if not names:
        return None
    available = tuple(model.path_names)
    chosen = []
    for name in names:
        if name not in available:
            close = difflib.get_close_matches(name, available, n=3)
            hint = (f"Did you mean {', '.join(close)}?" if close else
                    f"The model's paths are: {', '.join(available[:8])}"
                    + (" ..." if len(available) > 8 else "") + ".")
            raise InputError(f"the model has no muscle or path named '{name}'", file=model_file,
                             where=f"--muscle {name}", fix=hint)
        if name not in chosen:
            chosen.append(name)
    return chosen


def compute_lines(model, motion, *, muscles=None, quiet=True):
    """Body poses and action lines for every frame, in batches of `BATCH_FRAMES` frames.

    Parameters
    ----------
    model : motion.Model
    motion : motion.Motion
    muscles : list of str, optional
        Path names (default: all).
    quiet : bool
        No progress bar.

    Returns
    -------
    dict
        ``tf_ground_body`` (F, B, 4, 4), ``body_names`` (B,), ``lengths`` (F, M),
        ``moment_arms`` (F, M, C), ``spanned`` (M, C), ``muscle_names`` (M,),
        ``coordinate_names`` (C,).
    """
    from motion.wrapping.action_lines import action_lines
    from motion.osim.kinematics import body_poses

    starts = np.arange(0, motion.n_frames, BATCH_FRAMES)
    tfs, lengths, arms = [], [], []
    lines = body_names = None
    bar = progress(total=motion.n_frames, desc="action lines", quiet=quiet, unit="frame")
    try:
        for start in starts:  # batches of frames, each one vectorised call
            part = motion.select_frames(slice(start, start + BATCH_FRAMES))
            poses = body_poses(model, part)
            lines = action_lines(model, part, muscles=muscles)
            body_names = poses.body_names
            tfs.append(np.asarray(poses.tf_ground_body))
            lengths.append(np.asarray(lines.lengths))
            arms.append(np.asarray(lines.moment_arms))
            bar.update(part.n_frames)
    finally:
        bar.close()
    return {
        "tf_ground_body": np.concatenate(tfs),
        "body_names": body_names,
        "lengths": np.concatenate(lengths),
        "moment_arms": np.concatenate(arms),
        # INTERFACE.md: a coupler-dependent coordinate is reported against its independent one
        # (whose row holds the total derivative along the coupler), so it gets no rows of its own.
        "spanned": np.asarray(lines.spanned, dtype=bool)
        & (np.asarray(lines.coordinate_status) != "dependent")[None, :],
        "muscle_names": tuple(lines.muscle_names),
        "coordinate_names": tuple(lines.coordinate_names),
    }


def _show_warning(message, category, filename, lineno, file=None, line=None):
    text = " ".join(str(message).split())
    print(f"fibres lines: warning: {text}", file=sys.stderr)


def execute(args) -> int:
    """Run ``fibres lines``; returns the exit status (errors are raised as InputError)."""
    from motion.osim.motion_file import load_motion
    from motion.osim.reader import load_model

    from .out_folder import OutFolderLock, check_out_folder

    out = Path(args.out)
    _check_out_dir(out)
    check_out_folder(out, force=args.force)
    with warnings.catch_warnings():
        warnings.simplefilter("default")
        warnings.showwarning = _show_warning
        model = load_model(args.model)
        muscles = _select_muscles(model, args.muscle, args.model)
        # coordinates the chosen paths span and the file lacks get a warning of their own
        from motion.wrapping.action_lines import coordinates_spanned

        spanned = coordinates_spanned(model, model.path_names if muscles is None else muscles)
        mot = load_motion(args.motion, model, spanned=spanned)
        rows = resolve_frames(args.frames, mot.n_frames, source=args.motion)
        mot = mot.select_frames(rows)
        from .progress import compile_notice

        compile_notice("fibres lines", args.quiet)
        result = compute_lines(model, mot, muscles=muscles, quiet=args.quiet)

    tables = {
        "body_poses.csv": body_poses_table(mot.time, result["tf_ground_body"],
                                           result["body_names"]),
        "action_lines.csv": action_lines_table(mot.time, result["lengths"], result["muscle_names"],
                                               action_lines=result["muscle_names"]),
        "action_line_moment_arms.csv": moment_arms_table(
            mot.time, result["moment_arms"], result["spanned"], result["muscle_names"],
            result["coordinate_names"], action_lines=result["muscle_names"]),
    }
    existed = out.exists()
    prepare_out_dir(out)
    try:
        with OutFolderLock(out), contextlib.ExitStack() as stack:
            # All three go to temporary names first; they are renamed only if all were written.
            for name, table in tables.items():
                tmp = stack.enter_context(atomic_path(out / name))
                table.to_csv(tmp, index=False, float_format="%.12g")
    except BaseException:
        if not existed:
            with contextlib.suppress(OSError):
                out.rmdir()  # only if still empty
        raise
    if not args.quiet:
        print(f"fibres lines: {mot.n_frames} frames, {len(result['muscle_names'])} paths, "
              f"{len(result['body_names'])} bodies -> {out}/{{{','.join(OUTPUT_FILES)}}}")
    return 0
