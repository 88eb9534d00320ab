"""OpenSim AnalyzeTool setup files (``fibres run --setup SETUP.xml``): a researcher's existing
MuscleAnalysis setup, run as it is beside a fibre model.

Read from the ``<AnalyzeTool>`` element (OpenSim 3.x and 4.x write the same elements; paths are
relative to the setup file's folder, as OpenSim resolves them):

- ``model_file``: must be the fibre model's OpenSim model (the same file, or a file with the same
  content); the fibre model says which meshes go with which muscles of that model.
- ``coordinates_file``: the motion (in place of ``--motion``).
- ``initial_time`` / ``final_time``: the motion rows whose time lies in that interval (in place of
  ``--frames``; 1e-9 s tolerance), intersected with an enabled MuscleAnalysis's own
  ``start_time`` / ``end_time``; its ``step_interval`` keeps every n-th of those rows.
- a MuscleAnalysis's ``muscle_list``: ``all``, or OpenSim muscle names; a fibre-model muscle runs
  when one of its action lines (or its own name) is listed.

Everything else that would change the result is named in ONE `SetupFileWarning`: a states file in
place of coordinates, speeds and external loads files, a low-pass filter of the coordinates,
replaced force sets, other analyses, ``compute_moments`` (muscle moments need forces), a
``moment_arm_coordinate_list`` other than ``all`` (moment arms are written for every spanned
coordinate), listed muscles that no fibre-model muscle drives. ``results_directory`` is not used
(outputs go to ``--out``).
"""
from __future__ import annotations

import dataclasses
import math
import warnings
from pathlib import Path

import numpy as np

from .errors import InputError

__all__ = ["AnalyzeSetup", "SetupFileWarning", "read_setup", "apply_setup"]


class SetupFileWarning(UserWarning):
    """Parts of an AnalyzeTool setup that `fibres run --setup` does not use."""


@dataclasses.dataclass(frozen=True)
class AnalyzeSetup:
    """What `fibres run` takes from an AnalyzeTool setup (module docstring)."""

    file: Path
    model_file: Path | None
    coordinates_file: Path | None
    initial_time: float
    final_time: float
    muscles: tuple | None          # OpenSim names, None = all
    step_interval: int
    unsupported: tuple


def _text(el, tag, default=""):
    child = el.find(tag)
    return default if child is None or child.text is None else child.text.strip()


def _float(el, tag, default, file):
    text = _text(el, tag)
    if not text:
        return default
    low = text.lower()
    if low in ("inf", "+inf", "infinity"):
        return math.inf
    if low in ("-inf", "-infinity"):
        return -math.inf
    try:
        return float(text)
    except ValueError:
        raise InputError(f"<{tag}> is not a number: {text!r}", file=file, where=f"AnalyzeTool/{tag}",
                         fix="Write a time in seconds.") from None


def read_setup(path) -> AnalyzeSetup:
    """Read an AnalyzeTool setup file (module docstring); bad files raise `InputError`."""
    from motion.osim.xml_document import read_document

    path = Path(path)
    if not path.is_file():
        raise InputError("setup file not found", file=path, where="--setup",
                         fix="Give an OpenSim AnalyzeTool setup (.xml) file.")
    try:
        root = read_document(path).el
    except Exception as exc:   # noqa: BLE001 - motion's InputError or a parse failure
        raise InputError(f"cannot read the setup ({exc})", file=path, where="--setup",
                         fix="Give an AnalyzeTool setup written by OpenSim.") from None
    tool = root.find("AnalyzeTool")
    if tool is None:
        found = [c.tag for c in root]
        raise InputError(f"no <AnalyzeTool> in the setup (found {', '.join(found) or 'nothing'})", file=path,
                         where="OpenSimDocument", fix="Give an AnalyzeTool setup (File > Analyze > Save in the GUI).")
    base = path.resolve().parent

    def file_of(tag):
        text = _text(tool, tag)
        if not text or text.lower() == "unassigned":
            return None
        p = Path(text.replace("\\", "/"))
        return p if p.is_absolute() else (base / p)

    unsupported = []
    for tag, what in (("states_file", "a states file (give coordinates_file)"), ("speeds_file", "a speeds file"),
                      ("external_loads_file", "external loads")):
        if file_of(tag) is not None:
            unsupported.append(f"<{tag}> ({what})")
    cutoff = _float(tool, "lowpass_cutoff_frequency_for_coordinates", -1.0, path)
    if cutoff > 0:
        unsupported.append(f"<lowpass_cutoff_frequency_for_coordinates> {cutoff:g} Hz (coordinates are used unfiltered)")
    if _text(tool, "replace_force_set").lower() == "true" or _text(tool, "force_set_files"):
        unsupported.append("<force_set_files>/<replace_force_set>")
    muscles, step = None, 1
    t0 = _float(tool, "initial_time", -math.inf, path)
    t1 = _float(tool, "final_time", math.inf, path)
    analyses = tool.find("AnalysisSet/objects")
    seen_ma = False
    for a in (list(analyses) if analyses is not None else []):
        if _text(a, "on", "true").lower() == "false":
            continue
        if a.tag != "MuscleAnalysis" or seen_ma:
            unsupported.append(f"the {a.tag} analysis '{a.get('name', '')}'")
            continue
        seen_ma = True
        names = _text(a, "muscle_list").split()
        if names and not any(n.lower() == "all" for n in names):
            muscles = tuple(names)
        coords = _text(a, "moment_arm_coordinate_list").split()
        if coords and not any(c.lower() == "all" for c in coords):
            unsupported.append(f"<moment_arm_coordinate_list> {' '.join(coords)} (moment arms are written for "
                               "every coordinate a muscle spans)")
        if _text(a, "compute_moments").lower() == "true":
            unsupported.append("<compute_moments> (muscle moments need muscle forces; fibres computes lengths "
                               "and moment arms)")
        t0 = max(t0, _float(a, "start_time", -math.inf, path))
        t1 = min(t1, _float(a, "end_time", math.inf, path))
        try:
            step = max(1, int(float(_text(a, "step_interval", "1") or 1)))
        except ValueError:
            step = 1
    return AnalyzeSetup(file=path, model_file=file_of("model_file"), coordinates_file=file_of("coordinates_file"),
                        initial_time=t0, final_time=t1, muscles=muscles, step_interval=step,
                        unsupported=tuple(unsupported))


def _same_file(a: Path, b: Path) -> bool:
    from .run_record import sha256_file

    a, b = Path(a).resolve(), Path(b).resolve()
    return a == b or (a.is_file() and b.is_file() and sha256_file(a) == sha256_file(b))


def apply_setup(setup: AnalyzeSetup, spec) -> dict:
    """The ``run`` arguments of a setup for a fibre model: ``motion`` (path), ``frames`` (row
    indices) and ``muscles`` (fibre-model names or None); warns once about unsupported parts."""
    import motion as motion_pkg

    if setup.model_file is not None and not _same_file(setup.model_file, spec.model_path):
        raise InputError(f"the setup's model_file is {setup.model_file}, not the fibre model's model "
                         f"{spec.model_path}", file=setup.file, where="AnalyzeTool/model_file",
                         fix="Point the fibre model's 'model' key and the setup to the same .osim file.")
    if setup.coordinates_file is None:
        raise InputError("the setup names no coordinates_file", file=setup.file, where="AnalyzeTool/coordinates_file",
                         fix="Give the motion (.mot) as <coordinates_file>.")
    if not setup.coordinates_file.is_file():
        raise InputError("the setup's coordinates_file does not exist", file=setup.coordinates_file,
                         where="AnalyzeTool/coordinates_file", fix="Fix the path in the setup file.")
    with warnings.catch_warnings():     # the run reads the motion again and reports its warnings then
        warnings.simplefilter("ignore")
        time = motion_pkg.load_motion(setup.coordinates_file, spec.model).time
    rows = np.flatnonzero((time >= setup.initial_time - 1e-9) & (time <= setup.final_time + 1e-9))
    if rows.size == 0:
        raise InputError(f"no motion row lies between initial_time {setup.initial_time:g} s and final_time "
                         f"{setup.final_time:g} s (the motion runs {time[0]:g}..{time[-1]:g} s)", file=setup.file,
                         where="AnalyzeTool/initial_time", fix="Fix the time range of the setup.")
    rows = rows[::setup.step_interval]
    muscles, unknown = None, []
    if setup.muscles is not None:
        listed = set(setup.muscles)
        muscles = [m.name for m in spec.muscles if m.name in listed or listed & set(m.action_lines)]
        driven = {n for m in spec.muscles for n in (m.name, *m.action_lines)}
        unknown = [n for n in setup.muscles if n not in driven]
        if not muscles:
            raise InputError(f"no muscle of the fibre model is driven by the setup's muscle_list "
                             f"({' '.join(setup.muscles)})", file=setup.file, where="MuscleAnalysis/muscle_list",
                             fix=f"List action lines of: {', '.join(spec.muscle_names)} (or 'all').")
    parts = list(setup.unsupported)
    if unknown:
        parts.append(f"muscles no fibre-model muscle drives: {', '.join(unknown)}")
    if parts:
        warnings.warn(f"{setup.file}: not used by fibres run: " + "; ".join(parts), SetupFileWarning, stacklevel=2)
    return {"motion": setup.coordinates_file, "frames": rows, "muscles": muscles}
