"""The fibre model: a TOML file tying an OpenSim model to the muscle surfaces to decompose.

Format (``docs/INTERFACE.md``; paths are relative to the TOML file)::

    model = "arm.osim"            # OpenSim model (required)
    motion = "flexion.mot"        # default motion for `fibres run` (optional)
    units = "m"                   # units of meshes and landmarks: "m" or "mm" (default "m")

    [defaults]                    # any muscle key below, applied unless the muscle sets it
    template = "parallel"
    fibres = 100
    resolution = 19

    [muscles.biceps]
    action_lines = ["BIClong", "BICshort"]   # OpenSim paths driving and compared with this surface
    mesh = "meshes/biceps.stl"    # closed surface; omit it to generate one around the action line
    frame = "ground"              # "ground" (at rest_pose) | a body name | "bodies"
    rest_pose = { r_elbow_flex = 0.0 }       # SI (rad, m); default: the model's default values
    origin = { body = "r_humerus", points = [[0.0, 0.0, 0.0]] }
    insertion = { body = "r_ulna_radius_hand", file = "biceps_insertion.csv" }

Muscle keys: ``action_lines``, ``mesh``, ``frame``, ``rest_pose``, ``origin``, ``insertion``,
``template``, ``fibres``, ``resolution``, ``seed``, ``template_params`` (a table handed to the
template), ``units`` (overrides the top-level units for this muscle), ``bones`` (a list of
``{ body = "femur_r", mesh = "femur.vtk" }`` in the muscle's frame and units: obstacles the
wrapped surface keeps out of), ``volume`` (m^3, for a generated surface),
``origin_tendon_share`` (generated surface: the share of the tendon at the origin end, 0..1,
default 0.5).

``frame = "bodies"`` is for NMSBuilder/LHDL exports: mesh and landmark coordinates are in one
scanner frame in which every body frame is the identity, so a landmark's coordinates are already
its coordinates in the frame of the body it rides on, whatever that body is.

Attachment tables (``origin`` / ``insertion``; omit one to use the first / last path point of the
first action line) take exactly one of

- ``points = [[x, y, z], ...]`` in the muscle's frame and units;
- ``file = "landmarks.csv"``: a CSV file (header row) with columns ``x, y, z`` (the muscle's
  units), or ``x_mm, y_mm, z_mm`` (millimetres) or ``x_m, y_m, z_m`` (metres), or the three
  columns named by ``columns = ["px", "py", "pz"]``; ``where = {muscle = "iliacus_r", type =
  "origin"}`` keeps only the rows whose columns equal those values (a list value means "any of");
  ``units = "mm"`` overrides the unit rule. A file that is not ``.csv``/``.txt`` is read as a point
  cloud (legacy VTK, VTP, PLY, ...): its vertices are the points.

and ``body`` (the body the points ride on; default: the body of the first / last path point of the
first action line) and ``frame``: ``"muscle"`` (default: the points are in the muscle's ``frame``,
like its mesh) or ``"body"`` (the points are in ``body``'s own frame, as path-point locations in the
.osim, e.g. ``origin = { body = "pelvis", frame = "body", points = [[-0.014, 0.017, 0.107]] }``).

Every mistake raises one :class:`analysis.errors.InputError` naming the TOML file, the key (e.g.
``muscles.biceps.action_lines[1]``) and the fix.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

import numpy as np

from .errors import InputError
from .spec_attachments import UNITS, AttachmentSpec, is_unit, read_attachment

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = ["load_spec", "FibreModelSpec", "MuscleSpec", "AttachmentSpec", "TEMPLATE_NAMES"]

#: The fibre templates (``fibres.TEMPLATES`` once available; the same names as INTERFACE.md).
TEMPLATE_NAMES = ("parallel", "pennate", "bipennate", "curved", "fanned", "rectus")
_TOP_KEYS = ("model", "motion", "units", "defaults", "muscles")
_MUSCLE_KEYS = ("action_lines", "mesh", "frame", "rest_pose", "origin", "insertion", "template",
                "fibres", "resolution", "seed", "template_params", "units", "bones", "volume",
                "origin_tendon_share",
                "slicing")
_BONE_KEYS = ("body", "mesh")
_DEFAULTS = {"frame": "ground", "template": "parallel", "fibres": 100, "resolution": 19, "seed": 0}

#: cross-section methods of the decomposition (``fibres.SLICINGS``)
SLICINGS = ("harmonic", "planes")
#: Most fibres per muscle. Every fibre is sampled, morphed, filtered, carried through every frame
#: and every perturbed pose, and written per frame; Kohout et al. (2012) use hundreds. Above this a
#: run needs tens of GB (see `analysis.budget`), so the value is almost surely a typo.
MAX_FIBRES = 100_000
#: Most segments per fibre. The surface is cut by one plane per fibre point (Kohout 2012: "the
#: minimal number of slices used is equal to the specified resolution"); beyond 1000 planes the
#: slices are finer than the triangles of any muscle mesh, and at 10,000 they would pass the end
#: planes, which sit 1e-4 of the box height inside its ends (`fibres.slicing.morph.END_INSET`).
MAX_RESOLUTION = 1000
#: Largest seed (the Sobol scrambling seed is a 32-bit unsigned integer in many tools)
MAX_SEED = 2**32 - 1
_LIMITS = {"fibres": (1, MAX_FIBRES), "resolution": (1, MAX_RESOLUTION), "seed": (0, MAX_SEED)}
_LIMIT_WHY = {"fibres": "more fibres than any muscle study needs; the run would need tens of GB",
              "resolution": "finer than the triangles of any muscle mesh (one slice per fibre point)",
              "seed": "seeds are 32-bit unsigned integers"}


def check_count(key: str, value, *, where=None, file=None):
    """An integer option of the fibre model (``fibres``, ``resolution``, ``seed``) within its
    limits (`MAX_FIBRES`, `MAX_RESOLUTION`, `MAX_SEED`), or InputError saying why."""
    lo, hi = _LIMITS[key]
    where = where or key
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lo:
        raise InputError(f"expected an integer >= {lo}, got {value!r}", file=file, where=where,
                         fix=f"Set {key} to a whole number >= {lo}.")
    if value > hi:
        raise InputError(f"{value} is above the limit of {hi} ({_LIMIT_WHY[key]})", file=file,
                         where=where, fix=f"Set {key} to at most {hi}.")
    return int(value)


def _template_names():
    try:
        from fibres import TEMPLATES
    except ImportError:
        return TEMPLATE_NAMES
    return tuple(TEMPLATES)


@dataclass(frozen=True)
class MuscleSpec:
    """One muscle of the fibre model, with defaults applied and paths resolved.

    Attributes
    ----------
    name : str
    action_lines : tuple of str
        OpenSim path (muscle) names.
    mesh : Path or None
        Closed surface file; None means "generate one around the action line".
    units : str
        "m" or "mm": units of the mesh (landmarks are already converted to metres).
    frame : str
        "ground", a body name, or "bodies".
    rest_pose : mapping str -> float
        Coordinate values (SI) at which the mesh was acquired; missing ones take model defaults.
    origin, insertion : AttachmentSpec
    template : str
    n_fibres : int
    resolution : int
        Segments per fibre (resolution + 1 points).
    seed : int
    template_params : mapping
    bones : tuple of (body, Path)
        Bone meshes (in the muscle's frame and units) that the wrapped surface keeps out of.
    volume : float or None
        Volume (m^3) of a generated surface (no mesh); None: motion's default rule.
    slicing : str
        "harmonic" (isolines of a harmonic field; the default with a mesh) or "planes" (Kohout
        2012; the default of a generated surface).
    origin_tendon_share : float
        Generated surface: the share of the tendon at the origin end
        (`motion.MuscleSurfaceSpec.origin_tendon_share`).
    """

    name: str
    action_lines: tuple
    mesh: Path | None
    units: str
    frame: str
    rest_pose: MappingProxyType
    origin: AttachmentSpec
    insertion: AttachmentSpec
    template: str = "parallel"
    n_fibres: int = 100
    resolution: int = 19
    seed: int = 0
    template_params: MappingProxyType = field(default_factory=lambda: MappingProxyType({}))
    bones: tuple = ()
    volume: float | None = None
    slicing: str = "harmonic"
    origin_tendon_share: float = 0.5

    @property
    def scale(self) -> float:
        """Metres per mesh unit."""
        return UNITS[self.units]


@dataclass(frozen=True)
class FibreModelSpec:
    """A loaded, validated fibre model.

    Attributes
    ----------
    file : Path
        The TOML file.
    model_path : Path
    motion_path : Path or None
    units : str
    muscles : tuple of MuscleSpec
    model : motion.Model
        The loaded OpenSim model (used for validation; reused by the run).
    """

    file: Path
    model_path: Path
    motion_path: Path | None
    units: str
    muscles: tuple
    model: object = field(default=None, compare=False, repr=False)

    @property
    def muscle_names(self) -> tuple:
        return tuple(m.name for m in self.muscles)

    def muscle(self, name: str) -> MuscleSpec:
        """The spec of muscle ``name`` (KeyError if the fibre model has none)."""
        found = {m.name: m for m in self.muscles}
        if name not in found:
            raise KeyError(f"no muscle {name!r} in the fibre model; have {', '.join(found)}")
        return found[name]


# --------------------------------------------------------------------------- model accessors
def _model_paths(model) -> dict:
    """name -> path record of every muscle/path force in the model."""
    return {p.name: p for p in model.paths}


def _model_bodies(model) -> tuple:
    return tuple(b.name for b in model.bodies)


# --------------------------------------------------------------------------- loading
class _Ctx:
    """Raises InputError naming the TOML file."""

    def __init__(self, file: Path):
        self.file = file

    def fail(self, where, problem, fix):
        raise InputError(problem, file=self.file, where=where, fix=fix)

    def check_keys(self, table, allowed, where):
        for key in table:
            if key not in allowed:
                close = [a for a in allowed if a.startswith(str(key)[:3])]
                hint = f" Did you mean '{close[0]}'?" if close else ""
                self.fail(f"{where}.{key}" if where else key, "unknown key",
                          f"Allowed keys here: {', '.join(allowed)}.{hint}")

    def file_path(self, value, where, what):
        if not isinstance(value, str) or not value:
            self.fail(where, f"expected a file name (string), got {value!r}",
                      f"Write the path of the {what} relative to the TOML file.")
        if any(ord(ch) < 32 for ch in value):
            self.fail(where, f"the path {value!r} holds a control character (NUL, newline ...)",
                      f"Write the path of the {what} without control characters.")
        try:
            p = (self.file.parent / value).resolve()
            found = p.is_file()
        except (OSError, ValueError) as exc:
            self.fail(where, f"cannot use the path {value!r} ({exc})",
                      f"Write the path of the {what} relative to the TOML file.")
        if not found:
            self.fail(where, f"the {what} '{value}' does not exist (looked for {p})",
                      "Fix the path; paths are relative to the TOML file.")
        return p


def _check_template_params(ctx, template, params, where):
    """The template's own checks (`fibres.get_template`), any failure as one InputError here."""
    from fibres import get_template

    try:
        get_template(template, **params)
    except Exception as exc:  # noqa: BLE001 - a wrong value of any type is bad input
        problem = getattr(exc, "problem", None) or f"{type(exc).__name__}: {exc}"
        ctx.fail(where, f"not accepted by the {template} template ({problem})",
                 "Give the template's documented parameters as numbers (docs/INTERFACE.md).")


def _our_input_errors():
    return (InputError,)            # one class for the three packages (fibres.errors)


def load_spec(path, *, model=None) -> FibreModelSpec:
    """Load and validate a fibre-model TOML file (`_load_spec`); anything unexpected that goes
    wrong while reading it becomes one `InputError` naming the file (never a Python error).

    Parameters
    ----------
    path : str or os.PathLike
        The ``*.toml`` file.
    model : motion.Model, optional
        The already-loaded OpenSim model; default: ``motion.load_model`` of the ``model`` key.

    Returns
    -------
    FibreModelSpec

    Raises
    ------
    analysis.errors.InputError (or motion's, for the .osim)
        One line naming the file, the key and the fix, for any mistake.
    """
    try:
        return _load_spec(path, model=model)
    except _our_input_errors():
        raise
    except Exception as exc:  # noqa: BLE001 - bad input must not crash (RecursionError included)
        raise InputError(f"cannot use this fibre model ({type(exc).__name__}: {exc})", file=path,
                         fix="Check the file against docs/INTERFACE.md; every value must have the "
                             "documented type.") from None


def _load_spec(path, *, model=None) -> FibreModelSpec:
    """`load_spec` without the safety net: every rule of the module docstring, checked in order."""
    file = Path(path)
    ctx = _Ctx(file)
    if not file.is_file():
        raise InputError("the fibre model file does not exist", file=file,
                         fix="Pass the path of a fibre-model .toml file.")
    try:
        data = tomllib.loads(file.read_text(encoding="utf-8"))
    except UnicodeDecodeError:
        raise InputError("not a text file", file=file, fix="Pass a fibre-model .toml file.") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"not valid TOML ({exc})", file=file,
                         fix="Fix the TOML syntax (https://toml.io).") from None
    ctx.check_keys(data, _TOP_KEYS, "")
    if "model" not in data:
        ctx.fail("model", "missing key", "Add model = \"<file>.osim\" (relative to the TOML file).")
    model_path = ctx.file_path(data["model"], "model", "OpenSim model")
    motion_path = ctx.file_path(data["motion"], "motion", "motion") if "motion" in data else None
    units = data.get("units", "m")
    if not is_unit(units):
        ctx.fail("units", f"unknown units {units!r}", "Use units = \"m\" or units = \"mm\".")
    defaults = data.get("defaults", {})
    if not isinstance(defaults, dict):
        ctx.fail("defaults", "expected a table", "Write [defaults] with muscle keys.")
    ctx.check_keys(defaults, _MUSCLE_KEYS, "defaults")
    muscles = data.get("muscles")
    if not isinstance(muscles, dict) or not muscles:
        ctx.fail("muscles", "no muscles", "Add at least one [muscles.<name>] table.")
    if model is None:
        from motion import load_model

        model = load_model(model_path)
    specs = []
    for name, table in muscles.items():
        where = f"muscles.{name}"
        if not name.strip() or any(ord(ch) < 32 or ord(ch) == 127 for ch in name):
            ctx.fail(where, f"the muscle name {name!r} is empty or holds control characters "
                            "(tab, newline ...)", "Rename the muscle (letters, digits, _ and -).")
        if not isinstance(table, dict):
            ctx.fail(where, "expected a table", f"Write [muscles.{name}] with its keys.")
        ctx.check_keys(table, _MUSCLE_KEYS, where)
        merged = {**_DEFAULTS, "units": units, **defaults, **table}
        # a key taken from [defaults] is reported there
        src = {k: (f"{where}.{k}" if k in table else f"defaults.{k}") for k in merged}
        specs.append(_muscle(ctx, name, merged, src, model))
    return FibreModelSpec(file=file.resolve(), model_path=model_path, motion_path=motion_path,
                          units=units, muscles=tuple(specs), model=model)


def _muscle(ctx, name, d, src, model) -> MuscleSpec:
    where = f"muscles.{name}"
    paths = _model_paths(model)
    bodies = _model_bodies(model)
    if "action_lines" not in d:
        ctx.fail(f"{where}.action_lines", "missing key",
                 "List the OpenSim muscles that drive this surface, e.g. action_lines = [\"BIClong\"].")
    lines = d["action_lines"]
    if isinstance(lines, str):
        lines = [lines]
    if not isinstance(lines, list) or not lines:
        ctx.fail(src["action_lines"], "expected a non-empty list of OpenSim muscle names",
                 "Write action_lines = [\"<muscle in the .osim>\", ...].")
    for i, ln in enumerate(lines):
        if not isinstance(ln, str):
            ctx.fail(f"{src['action_lines']}[{i}]", f"expected a muscle name (string), got {ln!r}",
                     "Write action_lines = [\"<muscle in the .osim>\", ...].")
        if ln not in paths:
            import difflib

            close = difflib.get_close_matches(ln, sorted(paths), n=3)
            ctx.fail(f"{src['action_lines']}[{i}]", f"'{ln}' is not a muscle of the model",
                     f"Did you mean {', '.join(close)}?" if close else
                     f"Use one of: {', '.join(sorted(paths)[:12])}{' ...' if len(paths) > 12 else ''}.")
    if len(set(lines)) != len(lines):
        ctx.fail(src["action_lines"], "an action line is listed twice", "List each one once.")
    unit = d["units"]
    if not is_unit(unit):
        ctx.fail(src["units"], f"unknown units {unit!r}", "Use \"m\" or \"mm\".")
    mesh = ctx.file_path(d["mesh"], src["mesh"], "mesh") if "mesh" in d else None
    frame = d["frame"]
    if not isinstance(frame, str) or (frame not in ("ground", "bodies") and frame not in bodies):
        ctx.fail(src["frame"], f"unknown frame {frame!r}",
                 f"Use \"ground\", \"bodies\" or a body of the model: {', '.join(bodies)}.")
    rest = d.get("rest_pose", {})
    if not isinstance(rest, dict):
        ctx.fail(src["rest_pose"], "expected a table", "Write rest_pose = { <coordinate> = <value> }.")
    names = tuple(model.coordinate_names)
    for k, v in rest.items():
        if k not in names:
            ctx.fail(f"{src['rest_pose']}.{k}", "not a coordinate of the model",
                     f"Use one of: {', '.join(names)}.")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
            ctx.fail(f"{src['rest_pose']}.{k}", f"expected a number, got {v!r}",
                     "Give the coordinate value in SI units (rad or m).")
    template = d["template"]
    names_t = _template_names()
    if template not in names_t:
        ctx.fail(src["template"], f"unknown template {template!r}", f"Use one of: {', '.join(names_t)}.")
    # a mesh is cut along its harmonic field; a generated belly (a straight tube whose flat caps
    # are its attachments, bent onto the path) by planes, which keep its fibres' median on the
    # action line (Arm26 biceps: 1.0 mm against 2.0 mm)
    slicing = d.get("slicing", "harmonic" if "mesh" in d else "planes")
    if slicing not in SLICINGS:
        ctx.fail(src.get("slicing", f"{where}.slicing"), f"unknown slicing {slicing!r}",
                 f"Use one of: {', '.join(SLICINGS)}.")
    ints = {key: check_count(key, d[key], where=src[key], file=ctx.file)
            for key in ("fibres", "resolution", "seed")}
    bones = []
    raw_bones = d.get("bones", [])
    if not isinstance(raw_bones, list):
        ctx.fail(src["bones"], "expected a list of tables",
                 "Write bones = [{ body = \"femur_r\", mesh = \"femur.vtk\" }].")
    for k, bone in enumerate(raw_bones):
        key = f"{src['bones']}[{k}]"
        if not isinstance(bone, dict) or "body" not in bone or "mesh" not in bone:
            ctx.fail(key, "expected { body = ..., mesh = ... }", "Give the bone's body and mesh file.")
        ctx.check_keys(bone, _BONE_KEYS, key)
        if not isinstance(bone["body"], str) or bone["body"] not in bodies:
            ctx.fail(f"{key}.body", f"'{bone['body']}' is not a body of the model", f"Use one of: {', '.join(bodies)}.")
        bones.append((bone["body"], ctx.file_path(bone["mesh"], f"{key}.mesh", "bone mesh")))
    volume = d.get("volume")
    if volume is not None and (isinstance(volume, bool) or not isinstance(volume, (int, float))
                               or not 0 < volume < float("inf")):
        ctx.fail(src["volume"], f"expected a positive number (m^3), got {volume!r}",
                 "Give the generated surface's volume in cubic metres, or remove the key.")
    share = d.get("origin_tendon_share", 0.5)
    if isinstance(share, bool) or not isinstance(share, (int, float)) or not 0 <= share <= 1:
        ctx.fail(src["origin_tendon_share"], f"expected a number from 0 to 1, got {share!r}",
                 "Give the share of the tendon at the origin end (0.5: half at each end).")
    if mesh is not None and src.get("origin_tendon_share", "").startswith(where):   # not [defaults]
        ctx.fail(src["origin_tendon_share"], "only a generated surface (no mesh) has tendons",
                 "Remove origin_tendon_share, or the mesh.")
    params = d.get("template_params", {})
    if not isinstance(params, dict):
        ctx.fail(src["template_params"], "expected a table", "Write template_params = { name = value }.")
    _check_template_params(ctx, template, params, src.get("template_params", f"{where}.template_params"))
    ends = {}
    for end in ("origin", "insertion"):
        ends[end] = read_attachment(ctx, d.get(end), src.get(end, f"{where}.{end}"), end, unit, bodies,
                                paths[lines[0]])
    return MuscleSpec(name=name, action_lines=tuple(lines), mesh=mesh, units=unit, frame=frame,
                      rest_pose=MappingProxyType({k: float(v) for k, v in rest.items()}),
                      origin=ends["origin"], insertion=ends["insertion"], template=template,
                      n_fibres=ints["fibres"], resolution=ints["resolution"], seed=ints["seed"],
                      template_params=MappingProxyType(dict(params)), bones=tuple(bones),
                      volume=None if volume is None else float(volume), slicing=slicing,
                      origin_tendon_share=float(share))
