"""The ``fibres`` command line: parse arguments, call the library, write files, return a code.

Each sub-command lives in its own module (``cli_run``, ``cli_lines``, ``cli_decompose``) with two
functions: ``add_arguments(parser)`` and ``execute(args) -> int``.

Exit status: 0 success, 2 bad usage or bad input (one line on stderr naming the file, the element
and the fix), 1 internal failure, 130 interrupted. No traceback unless ``--debug``.
"""
from __future__ import annotations

import argparse
import importlib
import sys

__all__ = ["main", "build_parser"]

#: sub-command name -> (module, one-line help)
COMMANDS = {
    "run": ("analysis.cli_run", "fibre lengths and moment arms for a fibre model and a motion"),
    "lines": ("analysis.cli_lines", "action lines only: body poses, path lengths, moment arms"),
    "decompose": ("analysis.cli_decompose", "decompose one static muscle surface into fibres"),
    "export-osim": ("analysis.cli_export", "an OpenSim model with one muscle per fibre (polynomial paths)"),
    "render": ("analysis.cli_render", "an off-screen picture (PNG) of one frame of a run's 3D scene"),
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
        try:
            module = importlib.import_module(modname)
        except ModuleNotFoundError as exc:  # sub-command not built yet in this checkout
            if exc.name != modname:
                raise
            p.set_defaults(_module=None)
            continue
        module.add_arguments(p)
        p.set_defaults(_module=module)
    return parser


def _input_error_types():
    import fibres.errors
    import motion.errors

    from . import errors

    return (motion.errors.InputError, fibres.errors.InputError, errors.InputError)


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
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        # `fibres` alone runs the main job on the bundled model, as `fibres run` does.
        args = parser.parse_args(["run"] + list(argv if argv is not None else sys.argv[1:]))
    module = getattr(args, "_module", None)
    if module is None:
        print(f"fibres: error: the '{args.command}' command is not available in this build.",
              file=sys.stderr)
        return 1
    debug = getattr(args, "debug", False)
    import warnings

    saved = warnings.showwarning
    if not debug:
        _one_line_warnings(f"fibres {args.command}")
    try:
        return _execute(module, args, debug)
    finally:
        warnings.showwarning = saved


def _execute(module, args, debug) -> int:
    try:
        return int(module.execute(args) or 0)
    except _input_error_types() as exc:
        if debug:
            raise
        print(f"fibres {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"fibres {args.command}: interrupted; no partial output was left.", file=sys.stderr)
        return 130
    except Exception as exc:  # internal failure: one line, exit 1
        if debug:
            raise
        print(f"fibres {args.command}: internal error: {type(exc).__name__}: {exc}. "
              "Rerun with --debug for the traceback and report it.", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
