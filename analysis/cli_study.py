"""``fibres study STUDY.toml --out DIR [--scheduler ADDRESS] [--workers N] [--engine dask|processes]
[--force] [--quiet]``: run a cohort study (`analysis.study`).

Prints the engine (and Dask's dashboard address) and, away from a terminal, one line per
finished trial on stderr; then the final table (subject, trial, status, time, error) on stdout.
Exit status: 0 when every trial ran or was up to date; 2 when a trial failed on bad input (each
failure is a row of the table with its one-line error; the other trials finished) or the study
file, folder or options are wrong; 1 when a trial failed internally; 130 on Ctrl-C (finished
trials are kept and skipped by the next run).
"""
from __future__ import annotations

import sys

__all__ = ["add_arguments", "execute"]


def add_arguments(parser) -> None:
    parser.add_argument("study", metavar="STUDY.toml", help="the study file: [options] and [subjects.<name>]")
    parser.add_argument("--out", default="study-out", metavar="DIR",
                        help="output folder: DIR/<subject>/<trial>/, DIR/study.parquet/, DIR/study.json "
                             "(default study-out)")
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="a running Dask scheduler (tcp://HOST:PORT); default: a LocalCluster")
    parser.add_argument("--workers", type=int, default=None, metavar="N",
                        help="worker processes of the LocalCluster or process pool (default: one per core)")
    parser.add_argument("--engine", choices=("dask", "processes"), default=None,
                        help="Dask (default when installed) or a local process pool")
    parser.add_argument("--force", action="store_true",
                        help="write into DIR even if it is /, the home folder, or holds a project")
    parser.add_argument("--quiet", action="store_true", help="no progress lines (the final table is printed)")


def execute(args) -> int:
    """Run ``fibres study``; returns the exit status (module docstring)."""
    from .errors import InputError
    from .study import study

    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers must be >= 1, got {args.workers}", where="--workers",
                         fix="Give a whole number of worker processes >= 1.")
    report = study(args.study, args.out, scheduler=args.scheduler, workers=args.workers, engine=args.engine,
                   force=args.force, quiet=args.quiet)
    print(report.table(), flush=True)
    if not report.failed:
        return 0
    print(f"fibres study: {len(report.failed)} of {len(report.trials)} trials failed (see the table; "
          f"{report.out / 'study.json'} has each error and warning)", file=sys.stderr)
    return 1 if any(t.kind != "input" for t in report.failed) else 2
