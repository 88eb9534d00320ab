"""Ctrl-C and SIGKILL at random moments of `fibres run` (issue 16), counted.

    python bench/interrupts.py [--ctrl-c 30] [--kills 10] [--seed 16]

Runs the bundled example (a private copy) as a child process, ``python -m analysis.cli run``:

1. One complete run into ``OUT`` (the "previous outputs"), timed.
2. ``--ctrl-c`` runs into the same ``OUT`` with other settings (``--frames 0:27:2``), half of them
   with ``--jobs 2``, each sent SIGINT at a moment drawn uniformly between 0.02 s and 95 % of the
   complete run's duration (from the interpreter loading the packages to writing the files); a
   run that ended before its signal (the machine was faster than when timed) is drawn again. Each must exit 130 with no traceback, and ``OUT`` must hold exactly
   the previous run's files (byte for byte) -- or, if the signal landed while the finished files
   were being moved into place, exactly the new run's files (its run.json manifest) -- and no
   debris (staging folders, lock, journal, ``.part`` files).
3. ``--kills`` runs sent SIGKILL at a random moment; after each, the next run must succeed and
   leave the folder holding exactly its manifest, with no debris.

Prints one line per trial and the counts; exit status 1 if any trial failed. About 5 minutes.
(A SIGINT in the interpreter's own first ~20 ms, before any of our code runs, is Python's.)
"""
from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _files(out: Path) -> dict:
    return {p.relative_to(out).as_posix(): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}


def _debris(out: Path) -> list:
    return sorted(p.relative_to(out).as_posix() for p in out.rglob(".*"))


def _manifest_ok(out: Path) -> bool:
    try:
        record = json.loads((out / "run.json").read_text())
    except (OSError, ValueError):
        return False
    return sorted(record.get("files", [])) == sorted(_files(out))


def _start(toml, out, *extra):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    cmd = [sys.executable, "-m", "analysis.cli", "run", str(toml), "--out", str(out), "--quiet", *extra]
    return subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            cwd=out.parent)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ctrl-c", type=int, default=30)
    ap.add_argument("--kills", type=int, default=10)
    ap.add_argument("--seed", type=int, default=16)
    args = ap.parse_args(argv)
    rng = random.Random(args.seed)
    tmp = Path(tempfile.mkdtemp(prefix="fibres-interrupts-"))
    failures = 0
    try:
        models = tmp / "models"
        shutil.copytree(ROOT / "models", models, ignore=shutil.ignore_patterns("*.py", "__pycache__"))
        toml, out = models / "arm_example.toml", tmp / "out"
        t0 = time.perf_counter()
        first = _start(toml, out)
        _, err = first.communicate()
        duration = time.perf_counter() - t0
        assert first.returncode == 0, err.decode()
        previous = _files(out)
        print(f"complete run: {duration:.1f} s, {len(previous)} files")
        # the interrupted runs have other settings: time them (one each) so that every signal
        # lands while the process still runs; the folder is restored to the complete run after
        durations = {}
        for jobs in ([], ["--jobs", "2"]):
            t0 = time.perf_counter()
            proc = _start(toml, out, "--frames", "0:27:2", *jobs)
            proc.communicate()
            durations[bool(jobs)] = time.perf_counter() - t0
        restore = _start(toml, out)
        restore.communicate()
        previous = _files(out)
        print(f"interrupted settings, complete: {durations[False]:.1f} s (--jobs 1), "
              f"{durations[True]:.1f} s (--jobs 2)")

        counts = {"ctrl_c": 0, "exit_130": 0, "no_traceback": 0, "previous_intact": 0,
                  "new_complete": 0, "no_debris": 0}
        late = 0
        for k in range(args.ctrl_c):
            jobs = ["--jobs", "2"] if k % 2 else []
            while True:       # a run that ended before its signal (machine load) is drawn again
                delay = rng.uniform(0.02, 0.95 * durations[bool(jobs)])
                proc = _start(toml, out, "--frames", "0:27:2", *jobs)
                time.sleep(delay)
                if proc.poll() is None:
                    break
                late += 1
                previous = _files(out)       # it completed: its files are the previous ones now
            proc.send_signal(signal.SIGINT)
            _, err = proc.communicate()
            text = err.decode(errors="replace")
            now = _files(out)
            intact = now == previous
            complete = not intact and _manifest_ok(out)
            clean = not _debris(out)
            ok = proc.returncode == 130 and "Traceback" not in text and (intact or complete) and clean
            counts["ctrl_c"] += 1
            counts["exit_130"] += proc.returncode == 130
            counts["no_traceback"] += "Traceback" not in text
            counts["previous_intact"] += intact
            counts["new_complete"] += complete
            counts["no_debris"] += clean
            failures += not ok
            print(f"Ctrl-C {k + 1:2d} at {delay:5.2f} s {'--jobs 2' if jobs else '        '}: "
                  f"exit {proc.returncode}, {'previous intact' if intact else 'new complete' if complete else 'MIXED'}"
                  f"{'' if clean else ', debris ' + str(_debris(out))}"
                  f"{', TRACEBACK' if 'Traceback' in text else ''}{'' if ok else '  <-- FAIL'}")
            if not ok:
                print("    stderr: " + "\n    stderr: ".join(text.strip().splitlines()[-12:]))
            if complete:                       # the new run won the race: it is the previous one now
                previous = now
        kills = {"sigkill": 0, "next_run_ok": 0, "no_debris": 0}
        late_kills = 0
        for k in range(args.kills):
            while True:       # as above: a run that ended before its signal is drawn again
                delay = rng.uniform(0.02, 0.95 * durations[bool(k % 2)])
                proc = _start(toml, out, "--frames", "0:27:2", *(["--jobs", "2"] if k % 2 else []))
                time.sleep(delay)
                if proc.poll() is None:
                    break
                late_kills += 1
            proc.kill()
            proc.communicate()
            left = _debris(out)
            nxt = _start(toml, out, "--frames", "0:4")
            _, err = nxt.communicate()
            ok_run = nxt.returncode == 0
            clean = not _debris(out) and _manifest_ok(out)
            kills["sigkill"] += 1
            kills["next_run_ok"] += ok_run
            kills["no_debris"] += clean
            failures += not (ok_run and clean)
            print(f"SIGKILL {k + 1:2d} at {delay:5.2f} s: left {left or 'nothing'}; next run exit "
                  f"{nxt.returncode}, {'no debris' if clean else 'DEBRIS ' + str(_debris(out))}")
        counts["redrawn_runs_that_ended_before_their_signal"] = late
        print("Ctrl-C:", json.dumps(counts))
        kills["redrawn_runs_that_ended_before_their_signal"] = late_kills
        print("SIGKILL:", json.dumps(kills))
        print("failures:", failures)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
