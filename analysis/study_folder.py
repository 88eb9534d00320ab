"""The output folder of ``fibres study``: which trials are up to date, the study's record
(``DIR/study.json``) and the study-wide Parquet dataset (``DIR/study.parquet/``).

Layout::

    DIR/study.json                        # the record below (written after every finished trial)
    DIR/<subject>/<trial>/...             # exactly what `fibres run` writes (its own run.json)
    DIR/study.parquet/<table>/subject=<subject>/trial=<trial>/part-0.parquet

``<table>`` is each per-fibre and action-line table of `fibres run` (`DATASET_TABLES`); each
partition is a byte copy of the trial's own ``<table>.parquet`` (same columns, full precision),
so ``pandas.read_parquet(DIR / "study.parquet" / "fibre_lengths")`` gives one frame of the whole
study with ``subject`` and ``trial`` columns (hive partitioning; also ``dask.dataframe``). The
partition values are the folder names (the names themselves unless unsafe as file names). The
dataset holds exactly the trials that are up to date after the study: a trial that failed or left
the study file loses its partitions (a failed trial's folder keeps its previous files: the staging
rule of `fibres run`).

Record::

    {"tool": "musclefibres", "study": "<study file>",
     "trials": {"<subject>/<trial>": {"subject", "trial", "folder", "status": "ok" | "failed",
                "seconds", "error", "warnings": [...], "settings": {...}, "shared_rest": n,
                "finished_utc"}}}

``shared_rest``: the trial's rest-pose decompositions taken from its subject's shared tasks
(`analysis.study_tasks`; the others were computed by the trial itself).

Up to date (`is_up_to_date`, the resume rule): the record holds the trial with status ``ok`` and
the same ``settings`` (`trial_settings`: fibre model and motion paths, the options, the
musclefibres version), the trial folder's ``run.json`` is a musclefibres record of that motion,
every file its manifest lists exists, and every input it lists (fibre model, .osim, motion,
meshes, landmark files) still has the sha256 recorded there. Hashes are computed once per file
and study (`Hashes`); ``touch`` alone (same bytes) does not make a trial stale, an edit does.
"""
from __future__ import annotations

import contextlib
import datetime as _dt
import json
import shutil
from pathlib import Path

__all__ = ["DATASET_TABLES", "DATASET_NAME", "RECORD_NAME", "Hashes", "trial_settings", "is_up_to_date",
           "read_record", "record_entry", "write_record", "publish_partitions", "has_partitions", "drop_partitions", "prune_dataset"]

RECORD_NAME = "study.json"
DATASET_NAME = "study.parquet"
#: the tables of `fibres run` gathered into the study dataset (per fibre, per action line, and
#: their per-frame summary and the fibres' quality)
DATASET_TABLES = ("fibre_lengths", "fibre_moment_arms", "action_lines", "action_line_moment_arms",
                  "summary", "fibre_quality")


def _version() -> str | None:
    from importlib import metadata

    try:
        return metadata.version("musclefibres")
    except metadata.PackageNotFoundError:
        return None


def trial_settings(trial) -> dict:
    """What a trial's results depend on besides the input files' bytes (a `StudyTrial`)."""
    return {"spec": str(trial.spec), "motion": str(trial.motion), "options": dict(sorted(trial.options.items())),
            "musclefibres": _version()}


class Hashes:
    """sha256 of input files, each file hashed at most once (a study shares meshes and models)."""

    def __init__(self):
        self._seen = {}

    def __call__(self, path) -> str | None:
        from .run_record import sha256_file

        key = str(path)
        if key not in self._seen:
            try:
                self._seen[key] = sha256_file(path)
            except OSError:
                self._seen[key] = None
        return self._seen[key]


def _read_json(path: Path):
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def is_up_to_date(out, trial, record: dict, hashes: Hashes) -> bool:
    """Whether ``trial`` can be skipped (module docstring, "Up to date")."""
    entry = record.get("trials", {}).get(trial.label)
    if not isinstance(entry, dict) or entry.get("status") != "ok" or entry.get("settings") != trial_settings(trial):
        return False
    folder = Path(out) / trial.folder
    run = _read_json(folder / "run.json")
    if not isinstance(run, dict) or run.get("tool") != "musclefibres":
        return False
    inputs, files = run.get("inputs"), run.get("files")
    if not isinstance(inputs, dict) or not isinstance(files, list):
        return False
    motion = inputs.get("motion")
    if not isinstance(motion, dict) or motion.get("path") != str(trial.motion):
        return False
    if not all(isinstance(f, str) and (folder / f).is_file() for f in files):
        return False
    for item in inputs.values():
        if not isinstance(item, dict) or not item.get("sha256") or not isinstance(item.get("path"), str):
            return False
        if hashes(item["path"]) != item["sha256"]:
            return False
    return True


def read_record(out) -> dict:
    """The study record in ``out`` (an empty one if absent or unreadable)."""
    data = _read_json(Path(out) / RECORD_NAME)
    if not isinstance(data, dict) or data.get("tool") != "musclefibres" or not isinstance(data.get("trials"), dict):
        return {"tool": "musclefibres", "trials": {}}
    return data


def record_entry(trial, outcome: dict) -> dict:
    """The record of a finished trial (``outcome``: `analysis.study_tasks.run_trial`'s result)."""
    return {"subject": trial.subject, "trial": trial.trial, "folder": trial.folder,
            "status": outcome["status"], "seconds": round(float(outcome.get("seconds", 0.0)), 3),
            "error": outcome.get("error"), "warnings": list(outcome.get("warnings", ())),
            "settings": trial_settings(trial), "shared_rest": outcome.get("shared"),
            "finished_utc": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")}


def write_record(out, record: dict) -> None:
    """Write ``DIR/study.json`` atomically."""
    from .output_files import write_text

    write_text(json.dumps(record, indent=2) + "\n", Path(out) / RECORD_NAME)


def _partition(out, trial, table: str) -> Path:
    subject, name = trial.folder.split("/")
    return Path(out) / DATASET_NAME / table / f"subject={subject}" / f"trial={name}"


def publish_partitions(out, trial) -> int:
    """Copy the trial's tables into the study dataset (each file atomically); returns how many."""
    from .output_files import atomic_path

    n = 0
    for table in DATASET_TABLES:
        src = Path(out) / trial.folder / f"{table}.parquet"
        dst = _partition(out, trial, table)
        if not src.is_file():
            shutil.rmtree(dst, ignore_errors=True)
            continue
        dst.mkdir(parents=True, exist_ok=True)
        with atomic_path(dst / "part-0.parquet") as tmp:
            shutil.copyfile(src, tmp)
        n += 1
    return n


def has_partitions(out, trial) -> bool:
    """Whether the dataset holds every table the trial's folder has."""
    return all(not (Path(out) / trial.folder / f"{t}.parquet").is_file()
               or (_partition(out, trial, t) / "part-0.parquet").is_file() for t in DATASET_TABLES)


def drop_partitions(out, trial) -> None:
    """Remove the trial from the study dataset."""
    for table in DATASET_TABLES:
        shutil.rmtree(_partition(out, trial, table), ignore_errors=True)


def prune_dataset(out, keep) -> None:
    """Remove every partition of the dataset whose ``<subject>/<trial>`` folder is not in ``keep``,
    left-over ``.part`` files, and folders that became empty."""
    root = Path(out) / DATASET_NAME
    if not root.is_dir():
        return
    keep = set(keep)
    for table_dir in [p for p in root.iterdir() if p.is_dir()]:
        for subject_dir in [p for p in table_dir.iterdir() if p.is_dir()]:
            for trial_dir in [p for p in subject_dir.iterdir() if p.is_dir()]:
                subject = subject_dir.name.partition("=")[2]
                trial = trial_dir.name.partition("=")[2]
                if f"{subject}/{trial}" not in keep:
                    shutil.rmtree(trial_dir, ignore_errors=True)
                    continue
                for stale in trial_dir.glob(".part-0.*.part"):
                    with contextlib.suppress(OSError):
                        stale.unlink()
            with contextlib.suppress(OSError):
                subject_dir.rmdir()
        with contextlib.suppress(OSError):
            table_dir.rmdir()
    with contextlib.suppress(OSError):
        root.rmdir()
