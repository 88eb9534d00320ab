"""The ``fibres`` command line: parse arguments, call the library, write files, return a code.

Each sub-command lives in its own module (``cli_run``, ``cli_lines``, ``cli_decompose``) with two
functions: ``add_arguments(parser)`` and ``execute(args) -> int``.

Exit status: 0 success, 2 bad usage or bad input (one line on stderr naming the file, the element
and the fix), 1 internal failure, 130 interrupted. No traceback unless ``--debug``.

Ctrl-C: `main` settles, before any work, the error classes it will catch and the modules the
command imports later (`SETTLE`), so that an interrupt cannot land in a half-imported package
(it used to give "module 'motion' has no attribute 'errors'") or be swallowed by a third-party
``except BaseException`` inside a lazy import; SIGINT is handled by `analysis.interrupts`, whose
flag makes the command return 130 even if a library swallowed the KeyboardInterrupt.
"""
from __future__ import annotations

import argparse
import importlib
import sys
import warnings

__all__ = ["main", "build_parser"]

#: sub-command name -> (module, one-line help)
COMMANDS = {
    "run": ("analysis.cli_run", "fibre lengths and moment arms for a fibre model and a motion"),
    "lines": ("analysis.cli_lines", "action lines only: body poses, path lengths, moment arms"),
    "decompose": ("analysis.cli_decompose", "decompose one static muscle surface into fibres"),
    "export-osim": ("analysis.cli_export", "an OpenSim model with one muscle per fibre (polynomial paths)"),
    "render": ("analysis.cli_render", "an off-screen picture (PNG) of one frame of a run's 3D scene"),
    "study": ("analysis.cli_study", "a cohort: fibres run of many subjects x trials on Dask, resumable"),
}


class _Parser(argparse.ArgumentParser):
    """argparse with usage errors as one line and exit status 2."""

    def error(self, message):  # noqa: D401 - argparse API
        self.exit(2, f"{self.prog}: error: {message}. See '{self.prog} --help'.\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="fibres", description="Muscle fibres in musculoskeletal models.")
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name, (modname, help_text) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        p.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                       help="show tracebacks on errors")
        module = importlib.import_module(modname)
        module.add_arguments(p)
        p.set_defaults(_module=module)
    return parser


#: modules imported lazily during a command, imported up front instead (module docstring)
SETTLE = {
    "run": ("numpy", "scipy.spatial", "scipy.stats", "scipy.sparse.csgraph", "pandas", "trimesh",
            "matplotlib", "matplotlib.figure", "matplotlib.backends.backend_agg", "numba", "tqdm",
            "motion", "fibres", "analysis.run", "analysis.tables", "analysis.plots",
            "analysis.vtk_files", "analysis.run_record", "analysis.out_folder", "analysis.budget",
            "motion.surface.rest", "fibres.decompose"),
    "lines": ("numpy", "pandas", "motion", "analysis.lines_tables"),
    "decompose": ("numpy", "trimesh", "fibres", "fibres.decompose", "fibres.fit.fitting"),
    "study": ("numpy", "pandas", "motion", "fibres", "analysis.run", "analysis.study", "analysis.study_file",
              "analysis.study_folder", "analysis.study_tasks", "analysis.cli_run"),
}


#: the plotting modules of `SETTLE`: a run with ``--no-plots`` never imports them (~0.4 s CPU)
PLOTTING = ("matplotlib", "matplotlib.figure", "matplotlib.backends.backend_agg", "analysis.plots")


def _settle(command: str, plots: bool = True) -> None:
    """Import the command's modules now (optional ones may be missing); the `PLOTTING` ones
    only with ``plots``."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name in SETTLE.get(command, ()):
            if not plots and name in PLOTTING:
                continue
            try:
                importlib.import_module(name)
            except ImportError:
                pass


def _input_error_types():
    from . import errors

    # one class for the three packages (fibres.errors); a missing optional dependency that an
    # option needs (`--scheduler` without Dask) is the user's setup: one line naming the extra
    return (errors.InputError, errors.MissingDependencyError)


def _one_line_warnings(prefix: str) -> None:
    """Print every warning as one line ``<prefix>: warning: <message>`` on stderr, without the
    Python file and source line that the default format adds (``--debug`` keeps the default),
    and each distinct message once."""
    import warnings

    seen = set()

    def show(message, category, filename, lineno, file=None, line=None):
        text = " ".join(str(message).split())
        if text in seen:
            return
        seen.add(text)
        print(f"{prefix}: warning: {text}", file=file or sys.stderr, flush=True)

    warnings.showwarning = show


def main(argv=None) -> int:
    """Run the command line (``argv`` default: ``sys.argv[1:]``); return the exit status."""
    from . import interrupts

    try:
        with interrupts.honoured():
            try:
                code = _main(argv)
            except KeyboardInterrupt:
                code = 130
            if interrupts.requested():
                code = 130
    except KeyboardInterrupt:   # a second Ctrl-C while leaving
        code = 130
    if code == 130:
        command = _command_name(argv)
        print(f"fibres {command}: interrupted; no partial output was left.", file=sys.stderr)
    if argv is None and interrupts.is_the_command():
        interrupts.exit_now(code)       # no slow finalization with SIGINT at its default
    return code


def _command_name(argv) -> str:
    words = list(sys.argv[1:] if argv is None else argv)
    return next((w for w in words if w in COMMANDS), "run")


def _main(argv) -> int:
    errors = _input_error_types()           # settled before any work (module docstring)
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        # `fibres` alone runs the main job on the bundled model, as `fibres run` does.
        args = parser.parse_args(["run"] + list(argv if argv is not None else sys.argv[1:]))
    module = args._module
    debug = getattr(args, "debug", False)
    import warnings

    saved = warnings.showwarning
    if not debug:
        _one_line_warnings(f"fibres {args.command}")
    try:
        return _execute(module, args, debug, errors)
    finally:
        warnings.showwarning = saved


def _execute(module, args, debug, errors) -> int:
    from . import interrupts

    try:
        _settle(args.command, plots=not getattr(args, "no_plots", False))
        interrupts.check()
        return int(module.execute(args) or 0)
    except KeyboardInterrupt:
        raise
    except errors as exc:
        if debug:
            raise
        print(f"fibres {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except Exception as exc:  # internal failure: one line, exit 1
        if interrupts.requested():
            # after a Ctrl-C, an error is its echo (a third-party import that caught the
            # KeyboardInterrupt and left a half-made module): the run was interrupted
            return 130
        if debug:
            raise
        print(f"fibres {args.command}: internal error: {type(exc).__name__}: {exc}. "
              "Rerun with --debug for the traceback and report it.", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
