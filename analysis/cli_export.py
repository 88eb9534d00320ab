"""``fibres export-osim [SPEC] [--motion FILE] [--frames START:STOP:STEP] [--muscle NAME]...
[--fibres N] [--resolution R] [--template NAME] [--transport bind|decompose] [--out MODEL.osim]
[--keep-original] [--muscle-class CLASS] [--max-order N] [--seed S] [--quiet]``.

Runs the fibre study over the motion (its frames fix the range of poses sampled), fits one
polynomial path function per fibre (`analysis.fibre_paths`) and writes the fibre-resolved OpenSim
model (`analysis.osim_export`): ``MODEL.osim`` (default ``<model>_fibres.osim`` in the current
folder) and beside it ``MODEL.fit.json``, the per-fibre fit report (order, samples, errors) and
the muscle-parameter rules. ``fibres run --osim`` does the same inside a run's output folder.
"""
from __future__ import annotations

import json
import os
import sys
from pathlib import Path

from .errors import InputError

__all__ = ["add_arguments", "execute", "add_export_options"]


def add_export_options(parser) -> None:
    """The options shared with ``fibres run --osim``."""
    parser.add_argument("--keep-original", action="store_true",
                        help="keep the muscles' action lines beside their fibres (default: replace them)")
    parser.add_argument("--muscle-class", default=None, metavar="CLASS",
                        help="OpenSim class of the fibre muscles, e.g. DeGrooteFregly2016Muscle "
                             "(default: the class of the muscle's first action line)")
    parser.add_argument("--max-order", type=int, default=8, metavar="N",
                        help="highest polynomial order tried per fibre (default 8)")


def add_arguments(parser) -> None:
    from .cli_run import add_model_arguments
    from .frames_option import add_frames_argument

    add_model_arguments(parser, verb="export", out_metavar="MODEL.osim",
                        motion_help="motion whose range the path functions cover; default: the fibre model's",
                        out_help="model to write (default: <model>_fibres.osim in the current folder)")
    add_frames_argument(parser)
    parser.add_argument("--transport", choices=("bind", "decompose"), default="bind",
                        help="how the rest fibres reach each pose (as fibres run)")
    add_export_options(parser)
    parser.add_argument("--seed", type=int, default=0, metavar="S", help="sampling seed (default 0)")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")


def check_export_options(args) -> None:
    """Validate the export options before any long computation."""
    if args.max_order < 1:
        raise InputError(f"--max-order must be >= 1, got {args.max_order}", where="--max-order",
                         fix="Give a whole number >= 1 (OpenSim's PolynomialPathFitter uses up to 6).")
    cls = args.muscle_class
    if cls is not None and not (cls.isidentifier() and cls[0].isupper()):
        raise InputError(f"--muscle-class {cls!r} is not an OpenSim class name", where="--muscle-class",
                         fix="Give a Muscle class such as Thelen2003Muscle, Millard2012EquilibriumMuscle or "
                             "DeGrooteFregly2016Muscle.")


def announcer(quiet: bool):
    """A function printing one progress line to stderr (None when quiet)."""
    if quiet:
        return None

    def say(text):
        print(f"fibres: {text}", file=sys.stderr, flush=True)

    return say


def execute(args) -> int:
    from .cli_run import default_spec
    from .osim_export import export_osim
    from .output_files import write_text
    from .run import _select_muscles, run
    from .spec import load_spec

    check_export_options(args)
    spec = load_spec(Path(args.spec) if args.spec is not None else default_spec())
    _select_muscles(spec, args.muscle, fibres=args.fibres, resolution=args.resolution, template=args.template)
    out = Path(args.out) if args.out else Path.cwd() / f"{Path(spec.model_path).stem}_fibres.osim"
    if out.suffix.lower() != ".osim":
        raise InputError("the exported model must be a .osim file", file=out, where="--out",
                         fix="Give --out a name ending in .osim.")
    if not out.parent.is_dir():
        raise InputError("the folder of the exported model does not exist", file=out.parent, where="--out",
                         fix="Create it first or choose another --out.")
    if out.is_dir():
        raise InputError("the exported model's name is a folder", file=out, where="--out",
                         fix="Give --out a file name ending in .osim.")
    if not os.access(out.parent, os.W_OK | os.X_OK):     # before the long computation, not after it
        raise InputError("the folder of the exported model is not writable", file=out.parent, where="--out",
                         fix="Choose a folder you can write to with --out.")
    say = announcer(args.quiet)
    from .progress import start_notice

    start_notice("exporting the fibres as an OpenSim model", args.quiet)
    if say:
        say("computing the fibres over the motion")
    result = run(spec, args.motion, muscles=args.muscle, fibres=args.fibres, resolution=args.resolution,
                 template=args.template, frames=args.frames, quiet=True, keep_points=False,
                 transport=args.transport)
    record = export_osim(spec, result, out, keep_original=args.keep_original, muscle_class=args.muscle_class,
                         max_order=args.max_order, seed=args.seed, announce=say)
    report = out.with_suffix(".fit.json")
    write_text(json.dumps(record, indent=1) + "\n", report)
    if say:
        bad = [n for n, r in record["muscles"].items() if not r["within_tolerance"]]
        say(f"wrote {out} and {report.name}" + (f"; fits outside tolerance for: {', '.join(bad)} "
                                                  "(see the report)" if bad else ""))
    return 0
