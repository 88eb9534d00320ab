"""``run.json``: what a `fibres run` was made from (inputs with sha256), with which software
versions and settings, and how long each stage took — enough to reproduce or audit a result.

Layout::

    {
      "tool": "musclefibres",
      "created_utc": "2026-01-01T12:00:00Z",
      "command": ["fibres", "run", ...] | null,
      "inputs": {"<role>": {"path": "...", "sha256": "..."}, ...},
      "versions": {"python": "3.11.7", "numpy": "...", ...},
      "settings": {..., "estimate": {"memory_bytes": ..., "disk_bytes": ..., "max_memory_bytes": ...}},
      "timings_s": {"<stage>": seconds, ...},
      "frames": {"count": F, "motion_rows": [first, last], "time": [t0, t1]},
      "muscles": {"<name>": {"n_fibres": N, "coordinates": [...], "action_lines": [...]}},
      "files": ["fibre_lengths.csv", ..., "run.json"],          # fibres run: what it wrote
      "file_names": {"muscles": {"<name>": "<file stem>"}, "coordinates": {...}}
    }

``files`` is the manifest of the run (paths relative to the output folder; the next run into
the folder removes those it does not write again, `analysis.out_folder`); ``file_names`` maps
every muscle and coordinate name to the stem its files are named with (`analysis.file_names`:
the name itself unless it is unsafe as a file name).
"""
from __future__ import annotations

import datetime as _dt
import hashlib
import json
import platform
import sys
from importlib import metadata
from pathlib import Path

__all__ = ["sha256_file", "software_versions", "run_record", "write_run_json"]

_PACKAGES = ("musclefibres", "numpy", "scipy", "pandas", "pyarrow", "trimesh", "pyvista", "matplotlib",
             "numba", "tqdm", "opensim")


def sha256_file(path) -> str:
    """Hex sha256 of a file's bytes (read in 1 MiB blocks)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def software_versions() -> dict:
    """Python, platform and the installed versions of the packages the run depends on."""
    out = {"python": platform.python_version(), "platform": platform.platform()}
    for name in _PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def _jsonable(value):
    import numpy as np

    if isinstance(value, dict) or hasattr(value, "items"):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    return value


def run_record(result, *, command=None) -> dict:
    """The run.json content for a `RunResult` (inputs hashed now)."""
    inputs = {}
    for role, path in result.inputs.items():
        p = Path(path)
        inputs[role] = {"path": str(p), "sha256": sha256_file(p) if p.is_file() else None}
    n_f = len(result.time)
    return {
        "tool": "musclefibres",
        "created_utc": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "command": list(command) if command is not None else None,
        "inputs": inputs,
        "versions": software_versions(),
        "settings": _jsonable(result.settings),
        "timings_s": {k: round(float(v), 6) for k, v in result.timings.items()},
        "frames": {"count": n_f,
                   "motion_rows": [int(result.frames[0]), int(result.frames[-1])] if n_f else [],
                   "time": [float(result.time[0]), float(result.time[-1])] if n_f else []},
        "muscles": {m.name: {"n_fibres": m.n_fibres, "coordinates": list(m.coordinates),
                             "action_lines": list(m.action_lines), "notes": list(m.notes),
                             "quality": _jsonable(getattr(m, "quality", None))}
                    for m in result.muscles},
    }


def write_run_json(result, path, *, command=None, extra_timings=None, extra=None) -> dict:
    """Write ``run.json`` atomically; ``extra_timings`` adds stages timed after the run (writing),
    ``extra`` adds top-level sections (e.g. ``osim_export``; `fibres run`: ``files``, ``file_names``)."""
    from .output_files import write_text

    record = run_record(result, command=command)
    if extra_timings:
        record["timings_s"].update({k: round(float(v), 6) for k, v in extra_timings.items()})
    if extra:
        record.update(_jsonable(extra))
    write_text(json.dumps(record, indent=2, allow_nan=True) + "\n", path)
    return record


if __name__ == "__main__":  # pragma: no cover
    json.dump(software_versions(), sys.stdout, indent=2)
