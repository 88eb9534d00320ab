"""An up-front estimate of a run's memory and disk use, and the refusal of runs above the budget.

A run's size is frames x fibres x points x poses: every fibre point of every frame is carried
through the wrapping once per pose (the frame itself and +-h for each of the K coordinates the
muscle spans, so ``1 + 2K`` poses), and the tables hold a row per frame x fibre (x coordinate).
A million-frame motion used to grow `fibres run` past 5 GB before a MemoryError; now the run is
refused before the long computation, with the numbers, when the estimate exceeds the budget.

Memory model (bytes; F frames, N fibres, R segments, V surface vertices, K coordinates, per muscle)

- reading the motion file: ``MOTION_PARSE_BYTES_PER_BYTE`` x its size (measured: 17 for a
  two-column .mot; Python keeps every number's text while parsing);
- the action lines: ``F x (1 + M C) x 8 x LINES_COPIES`` (lengths and moment arms of the M
  paths about C coordinates, with their derivatives' work arrays);
- wrapping one muscle (``bind`` transport): ``P x (V + N (2R + 1)) x 3 x 8 x WRAP_COPIES`` with
  P = the poses carried at once, ``F (1 + 2K)`` up to ``POSES_PER_CHUNK`` (the frames are streamed
  in chunks of whole frames)
  (the surface and the fibres' material points at every pose; ``decompose`` transport: ``V``
  plus ``N (R + 1)`` points); ``--jobs J`` muscles at a time;
- kept for the files: ``F N (R + 1) x 3 x 8`` fibre points per muscle;
- the tables: ``TABLE_BYTES_PER_ROW`` per row of ``fibre_lengths`` / ``fibre_moment_arms``
  (pandas columns and the CSV formatting);

plus the memory the process already holds (its resident size when the estimate is made).
``WRAP_COPIES`` (the wrapping's working arrays) was calibrated on the bundled example with
``bench/budget.py``: measured peak growth / estimate 0.93 (200 frames x 100 fibres), 0.64
(400 x 300), 0.39 (200 x 300 with ``--jobs 2``, whose two muscles' peaks rarely coincide). It is
a guard against runs that cannot fit, erring on the safe side, not a precise forecast.

Disk: the CSV rows (``CSV_BYTES_PER_ROW``), the ``.vtp`` files (``F x N (R + 1) x 16`` bytes of
float32 points and int32 connectivity, plus a header per frame) and about ``PLOT_BYTES`` per muscle
for the plots; refused when above the free space of the output folder's file system.

The budget: ``--max-memory SIZE`` (``8G``, ``500M``, ``1.5GiB``, plain bytes); default 80 % of the
machine's physical memory (8 GiB where that is unknown).
"""
from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

from .errors import InputError

__all__ = ["parse_size", "default_budget", "format_size", "resident_bytes", "check_motion_file",
           "lines_memory", "check_lines", "muscle_costs", "estimate", "check_budget",
           "MOTION_PARSE_BYTES_PER_BYTE", "WRAP_COPIES"]

MOTION_PARSE_BYTES_PER_BYTE = 20
#: poses (frames x (1 + 2K)) a muscle carries through the wrapping at once: bounded memory
#: (about 0.2 GB of working arrays) and the fastest chunk measured (docs/decisions.md)
POSES_PER_CHUNK = 512
LINES_COPIES = 6
WRAP_COPIES = 12
TABLE_BYTES_PER_ROW = 220
CSV_BYTES_PER_ROW = 80
PLOT_BYTES = 400_000
DEFAULT_FRACTION = 0.8
_UNITS = {"": 1, "b": 1, "k": 2**10, "kb": 10**3, "kib": 2**10, "m": 2**20, "mb": 10**6, "mib": 2**20,
          "g": 2**30, "gb": 10**9, "gib": 2**30, "t": 2**40, "tb": 10**12, "tib": 2**40}
_SIZE = re.compile(r"\s*([0-9]*\.?[0-9]+)\s*([a-zA-Z]*)\s*\Z")


def parse_size(text, *, where="--max-memory"):
    """Bytes from ``"8G"``, ``"500M"``, ``"1.5GiB"``, ``"4GB"`` or ``"123456"``; None for None.

    ``K``/``M``/``G``/``T`` alone are binary (2^10 ...), ``KB``/``MB``/``GB`` decimal."""
    if text is None:
        return None
    m = _SIZE.match(str(text))
    unit = m.group(2).lower() if m else None
    if m is None or unit not in _UNITS or float(m.group(1)) <= 0:
        raise InputError(f"cannot read the size {text!r}", where=where,
                         fix="Give a positive size such as 8G, 500M or 1.5GiB.")
    return int(float(m.group(1)) * _UNITS[unit])


def format_size(n) -> str:
    """``1.5 GiB``-style text of a byte count."""
    n = float(n)
    for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
        if abs(n) < 1024 or unit == "TiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} TiB"  # pragma: no cover


def default_budget() -> int:
    """80 % of the physical memory (8 GiB where the platform does not say)."""
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        total = 0
    return int(DEFAULT_FRACTION * total) if total > 0 else 8 * 2**30


def resident_bytes() -> int:
    """The process's resident memory now (0 where the platform does not say)."""
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        pass
    try:
        import resource

        return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * 1024
    except (ImportError, OSError):  # pragma: no cover
        return 0


def _refuse(need, budget, what, fix):
    raise InputError(f"{what} needs about {format_size(need)} of memory, more than the budget of "
                     f"{format_size(budget)}", where="--max-memory", fix=fix)


def check_motion_file(path, budget) -> None:
    """Refuse a motion file too large to read within ``budget`` (before reading it)."""
    if budget is None:
        return
    try:
        size = os.path.getsize(path)
    except (OSError, ValueError):
        return                                   # the reader reports a missing file
    need = resident_bytes() + MOTION_PARSE_BYTES_PER_BYTE * size
    if need > budget:
        raise InputError(f"reading this {format_size(size)} motion file needs about "
                         f"{format_size(need)} of memory, more than the budget of "
                         f"{format_size(budget)}", file=path, where="--max-memory",
                         fix="Cut the motion into shorter files (or resample it), or raise --max-memory.")


def lines_memory(n_frames, n_paths, n_coordinates) -> int:
    """Bytes of the action-line stage (module docstring)."""
    return int(n_frames) * (1 + int(n_paths) * int(n_coordinates)) * 8 * LINES_COPIES


def check_lines(n_frames, n_paths, n_coordinates, budget) -> None:
    """Refuse a run whose action-line stage alone exceeds ``budget`` (before computing it)."""
    if budget is None:
        return
    need = resident_bytes() + lines_memory(n_frames, n_paths, n_coordinates)
    if need > budget:
        _refuse(need, budget, f"the action lines of {n_paths} path(s) about {n_coordinates} "
                              f"coordinate(s) over {n_frames} frames",
                "Use fewer frames (--frames START:STOP:STEP) or raise --max-memory.")


def _mesh_vertices(path) -> int:
    """Vertex count of a mesh file from its header where cheap (binary STL, PLY, legacy VTK, VTP);
    otherwise an over-estimate from its size (24 bytes per vertex, less than any format needs)."""
    if path is None:
        return 40 * 24                              # a generated surface (motion.fusiform_surface)
    path = Path(path)
    try:
        size = path.stat().st_size
        with open(path, "rb") as fh:
            head = fh.read(65536)
    except OSError:
        return 0
    suffix = path.suffix.lower()
    if suffix == ".stl" and len(head) >= 84 and not head[:5].lower() == b"solid":
        tri = int.from_bytes(head[80:84], "little")
        if 84 + 50 * tri == size:
            return max(tri // 2 + 2, 4)
    patterns = {".ply": rb"element\s+vertex\s+(\d+)", ".vtk": rb"POINTS\s+(\d+)",
                ".vtp": rb'NumberOfPoints="(\d+)"', ".vtu": rb'NumberOfPoints="(\d+)"'}
    if suffix in patterns:
        m = re.search(patterns[suffix], head)
        if m:
            return int(m.group(1))
    return size // 24 + 4


def muscle_costs(mspec, n_frames, n_coordinates, transport="bind") -> dict:
    """Memory and disk bytes of one muscle (module docstring) and the sizes they come from."""
    f, k = int(n_frames), int(n_coordinates)
    n, r = int(mspec.n_fibres), int(mspec.resolution)
    v = _mesh_vertices(mspec.mesh)
    per_frame = 1 + 2 * k
    # the poses carried at once (`analysis.muscle_chain` streams the frames in chunks)
    poses = min(f, max(1, POSES_PER_CHUNK // per_frame)) * per_frame
    carried = v + (n * (2 * r + 1) if transport == "bind" else 0)
    work = poses * carried * 3 * 8 * WRAP_COPIES
    if transport != "bind":
        work += poses * n * (r + 1) * 3 * 8
    kept = f * n * (r + 1) * 3 * 8 + f * per_frame * n * 8     # points + all poses' lengths
    rows = f * n * (1 + k)
    disk = rows * CSV_BYTES_PER_ROW + f * (n * (r + 1) * 16 + n * 32 + 2048) + PLOT_BYTES
    return {"muscle": mspec.name, "frames": f, "fibres": n, "points": r + 1, "poses": 1 + 2 * k,
            "vertices": v, "work": work, "kept": kept, "tables": rows * TABLE_BYTES_PER_ROW,
            "disk": disk}


def estimate(costs, *, jobs=1) -> dict:
    """Peak memory (bytes above what the process holds) and disk of a run from `muscle_costs`."""
    work = sorted((c["work"] for c in costs), reverse=True)[:max(int(jobs), 1)]
    kept = sum(c["kept"] for c in costs)
    tables = sum(c["tables"] for c in costs)
    return {"memory_bytes": int(max(sum(work), tables) + kept),
            "disk_bytes": int(sum(c["disk"] for c in costs))}


def check_budget(costs, *, budget, jobs=1, out_dir=None) -> dict:
    """Refuse (InputError) a run whose estimate exceeds ``budget`` or the free disk space of
    ``out_dir``; return the estimate (also recorded in run.json)."""
    est = estimate(costs, jobs=jobs)
    held = resident_bytes()
    est["resident_bytes"] = held
    est["max_memory_bytes"] = budget
    if budget is not None and held + est["memory_bytes"] > budget and costs:
        big = max(costs, key=lambda c: c["work"] + c["kept"] + c["tables"])
        _refuse(held + est["memory_bytes"], budget,
                f"this run ({big['frames']} frames x {big['fibres']} fibres x {big['points']} points x "
                f"{big['poses']} poses for muscle '{big['muscle']}', {len(costs)} muscle(s))",
                "Use fewer frames (--frames START:STOP:STEP), fewer fibres or a lower resolution, "
                "or raise --max-memory.")
    if out_dir is not None:
        try:
            free = shutil.disk_usage(out_dir).free
        except OSError:
            free = None
        if free is not None and est["disk_bytes"] > free:
            raise InputError(f"the run's files need about {format_size(est['disk_bytes'])} but the "
                             f"output folder's disk has {format_size(free)} free", file=out_dir,
                             where="--out", fix="Free some space, choose another --out, or use fewer "
                                                "frames (--frames) or fibres.")
    return est
