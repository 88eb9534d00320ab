"""A fibre-resolved OpenSim model: every decomposed muscle replaced by one muscle per fibre.

`export_osim` writes an OpenSim 4.x model (``.osim``) that keeps everything of the original model
and replaces (or, with ``keep_original=True``, adds beside) the action lines of each fibre-model
muscle by ``<muscle>_fibreNNN`` muscles, one per fibre:

- class: that of the muscle's first action line, every property copied (activation dynamics,
  pennation, curves ...), or ``muscle_class`` (e.g. ``DeGrooteFregly2016Muscle`` for Moco) with
  the properties every OpenSim Muscle has;
- path: a ``FunctionBasedPath`` (OpenSim 4.5+) whose ``length_function`` is a
  ``MultivariatePolynomialFunction`` of the muscle's spanned coordinates, fitted to the fibre's
  lengths and moment arms (`analysis.fibre_paths`); OpenSim takes the moment arms and lengthening
  speed from its derivatives;
- ``max_isometric_force``, ``optimal_fiber_length``, ``tendon_slack_length``: the rules of
  `analysis.fibre_paths.muscle_parameters` (equal share of the force; lengths scaled by the
  fibre's rest length).

The XML is edited as a tree (defusedxml to read, ElementTree to write). A model older than 4.0
(``Version`` < 40000) is first upgraded by OpenSim itself (``opensim.Model(file).printToXML``),
so that option needs the ``opensim`` package (the ``[opensim]`` extra). Mesh files the original
names are re-pointed (relative paths) so that they resolve from the exported model's folder. The
ForceSet's ObjectGroups (e.g. Rajagopal's ``hip_flex_r``) name the fibre muscles in place of the
action lines they replace (beside them with ``keep_original``); any other element that still
names a replaced muscle (controllers, probes ...) is named in one warning.
"""
from __future__ import annotations

import copy
import os
import tempfile
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

from .errors import InputError

__all__ = ["export_osim", "write_fibre_model", "fibre_muscle_names", "MUSCLE_COMMON_PROPERTIES"]

#: properties every OpenSim Muscle has (copied when the class changes)
MUSCLE_COMMON_PROPERTIES = ("appliesForce", "min_control", "max_control", "max_isometric_force",
                            "optimal_fiber_length", "tendon_slack_length", "pennation_angle_at_optimal",
                            "max_contraction_velocity", "ignore_tendon_compliance",
                            "ignore_activation_dynamics")
_PATH_TAGS = ("GeometryPath", "FunctionBasedPath")


class ExportWarning(UserWarning):
    """Something of the original model may need the user's attention in the exported one."""


def fibre_muscle_names(muscle: str, n: int) -> list:
    """``<muscle>_fibre000`` ... names of the n fibre muscles (at least 3 digits)."""
    width = max(3, len(str(n - 1)))
    return [f"{muscle}_fibre{k:0{width}d}" for k in range(n)]


def _num(x) -> str:
    return repr(float(x))


def _source_tree(model_file):
    """(root element, document folder) of a model in 4.x form (older files upgraded by OpenSim)."""
    from motion.osim.xml_document import read_document

    path = Path(model_file)
    root = read_document(path).el
    version = int(float(root.get("Version", "0") or 0))
    if version >= 40000:
        return root
    model = root.find("Model")
    if model is not None and (model.find("JointSet") is not None or model.find("Ground") is not None):
        root.set("Version", "40000")    # 4.x content behind an older header (motion.osim.reader)
        return root
    try:
        import opensim
    except ImportError:
        raise InputError(f"the model is in OpenSim {version // 10000}.x format; exporting a fibre model "
                         "needs it in 4.x form", file=path,
                         fix="pip install 'musclefibres[opensim]' (the export then upgrades it), or open "
                             "and save the model in OpenSim 4.") from None
    with tempfile.TemporaryDirectory() as tmp:
        up = Path(tmp) / path.name
        opensim.Model(str(path)).printToXML(str(up))
        return read_document(up).el


def _find_model(root):
    model = root.find("Model")
    if model is None:
        raise InputError("no <Model> element", file=None, fix="Give an OpenSim model file.")
    return model


def _coordinate_paths(model_el) -> dict:
    """coordinate name -> '/jointset/<joint>/<coordinate>'."""
    out = {}
    jointset = model_el.find("JointSet/objects")
    for joint in (jointset if jointset is not None else []):
        for coord in joint.findall("coordinates/Coordinate"):
            out[coord.get("name")] = f"/jointset/{joint.get('name')}/{coord.get('name')}"
    return out


def _float(el, tag):
    child = el.find(tag)
    if child is None or child.text is None:
        return None
    try:
        return float(child.text.split()[0])
    except (ValueError, IndexError):
        return None


def line_properties(model_file, names, *, root=None) -> dict:
    """The OpenSim muscle properties of the named forces (for `fibre_paths.muscle_parameters`);
    ``root``: the document already read by `_source_tree`."""
    model_el = _find_model(root if root is not None else _source_tree(model_file))
    forces = {f.get("name"): f for f in model_el.find("ForceSet/objects")}
    out = {}
    for n in names:
        props = {}
        for tag in ("max_isometric_force", "optimal_fiber_length", "tendon_slack_length", "optimal_force"):
            v = _float(forces[n], tag)
            if v is not None:
                props[tag] = v
        out[n] = props
    return out


def _polynomial_path(coordinate_paths, coefficients, order: int, gates=()):
    path = ET.Element("FunctionBasedPath", name="path")
    ET.SubElement(path, "coordinate_paths").text = " ".join(coordinate_paths)
    if gates:   # a polynomial plus ConditionalPathPoint-gated polynomials (analysis.path_fit)
        from .path_fit import expression, monomial_exponents

        names = [f"q{i}" for i in range(len(coordinate_paths))]
        fn = ET.SubElement(ET.SubElement(path, "length_function"), "ExpressionBasedFunction")
        ET.SubElement(fn, "expression").text = expression(
            coefficients, monomial_exponents(len(coordinate_paths), int(order)), gates, names)
        ET.SubElement(fn, "variables").text = " ".join(names)
        return path
    fn = ET.SubElement(ET.SubElement(path, "length_function"), "MultivariatePolynomialFunction")
    ET.SubElement(fn, "coefficients").text = " ".join(_num(c) for c in coefficients)
    ET.SubElement(fn, "dimension").text = str(len(coordinate_paths))
    ET.SubElement(fn, "order").text = str(int(order))
    return path


def _set_value(el, tag, value):
    child = el.find(tag)
    if child is None:
        child = ET.SubElement(el, tag)
    child.text = _num(value)


def _fibre_element(template, name, muscle_class, path_el, params, k):
    if muscle_class is None or muscle_class == template.tag:
        el = copy.deepcopy(template)
    else:
        el = ET.Element(muscle_class)
        for child in template:
            if child.tag in MUSCLE_COMMON_PROPERTIES:
                el.append(copy.deepcopy(child))
    el.set("name", name)
    for child in list(el):
        if child.tag in _PATH_TAGS or child.get("name") in ("path", "geometrypath"):
            el.remove(child)
    el.insert(0, path_el)
    if template.find("optimal_force") is not None and template.find("max_isometric_force") is None:
        _set_value(el, "optimal_force", params["max_isometric_force"])   # a PathActuator
    else:
        _set_value(el, "max_isometric_force", params["max_isometric_force"])
        _set_value(el, "optimal_fiber_length", params["optimal_fiber_length"][k])
        _set_value(el, "tendon_slack_length", params["tendon_slack_length"][k])
    return el


def _repoint_meshes(model_el, source_dir: Path, out_dir: Path):
    """Rewrite mesh_file entries that resolve from the source model's folder relative to out_dir."""
    for mesh in model_el.iter("mesh_file"):
        if not mesh.text:
            continue
        rel = mesh.text.strip().replace("\\", "/")
        for base in (source_dir, source_dir / "Geometry", source_dir / "geometry"):
            cand = (base / rel).resolve()
            if cand.is_file():
                mesh.text = Path(os.path.relpath(cand, out_dir.resolve())).as_posix()
                break


def write_fibre_model(model_file, out_path, muscles, *, keep_original=False, muscle_class=None,
                      final_folder=None, root=None) -> Path:
    """Write the fibre model.

    Parameters
    ----------
    model_file : path
        The original OpenSim model.
    out_path : path
        The ``.osim`` to write (atomically).
    muscles : list of dict
        One per fibre-model muscle: ``name``, ``action_lines`` (the forces it replaces),
        ``coordinates`` (D,), ``orders`` (N,), ``coefficients`` (N lists), ``params``
        (`fibre_paths.muscle_parameters`).
    keep_original : bool
        Keep the action lines beside the fibres (they still apply force).
    muscle_class : str, optional
        OpenSim class of the fibre muscles (default: that of the first action line).
    final_folder : path, optional
        The folder the model will finally live in, if it is written elsewhere first (staging):
        mesh paths are made relative to it.
    root : Element, optional
        The source document already read by `_source_tree` (not modified).
    """
    from .output_files import write_text

    out_path = Path(out_path)
    root = copy.deepcopy(root if root is not None else _source_tree(model_file))
    model_el = _find_model(root)
    objects = model_el.find("ForceSet/objects")
    if objects is None:
        raise InputError("the model has no ForceSet", file=model_file, fix="Give the model the muscles "
                         "the fibre model names.")
    forces = {f.get("name"): f for f in objects}
    cpaths = _coordinate_paths(model_el)
    removed, successors = [], {}
    for mus in muscles:
        missing = [n for n in mus["action_lines"] if n not in forces]
        if missing:
            raise InputError(f"no force {missing[0]!r} in the model", file=model_file,
                             where=f"muscle {mus['name']!r}: action_lines", fix="Name forces of the ForceSet.")
        template = forces[mus["action_lines"][0]]
        paths = [cpaths[c] for c in mus["coordinates"]]
        index = list(objects).index(template)
        names = fibre_muscle_names(mus["name"], len(mus["orders"]))
        clash = [n for n in names if n in forces]
        if clash:
            raise InputError(f"the model already has a force {clash[0]!r}", file=model_file,
                             where=f"muscle {mus['name']!r}", fix="Rename the fibre-model muscle.")
        for k, name in enumerate(names):
            el = _fibre_element(template, name, muscle_class,
                                _polynomial_path(paths, mus["coefficients"][k], mus["orders"][k], mus.get("gates", ())),
                                mus["params"], k)
            objects.insert(index + 1 + k, el)
        for n in mus["action_lines"]:
            successors.setdefault(n, []).extend(names)
        if not keep_original:
            for n in mus["action_lines"]:
                objects.remove(forces[n])
                removed.append(n)
    _update_groups(model_el, successors, keep_original)
    _warn_dangling(model_el, removed)
    if model_el.get("name"):
        model_el.set("name", model_el.get("name") + "_fibres")
    _repoint_meshes(model_el, Path(model_file).resolve().parent, Path(final_folder or out_path.parent))
    ET.indent(root, space="\t")
    text = '<?xml version="1.0" encoding="UTF-8" ?>\n' + ET.tostring(root, encoding="unicode") + "\n"
    write_text(text, out_path)
    return out_path


def _update_groups(model_el, successors: dict, keep_original: bool) -> None:
    """The ForceSet's ObjectGroups name the fibre muscles where they named an action line they
    replace (``successors``: action line -> fibre muscle names), in its place, or after it with
    ``keep_original``: a group such as Rajagopal's ``hip_flex_r`` keeps meaning what it meant."""
    for members in model_el.findall("ForceSet/groups/ObjectGroup/members"):
        words = (members.text or "").split()
        if not any(w in successors for w in words):
            continue
        out = []
        for w in words:
            if w in successors:
                out.extend(([w] if keep_original else []) + [n for n in successors[w] if n not in out])
            else:
                out.append(w)
        members.text = " " + " ".join(out)


def _warn_dangling(model_el, removed):
    """One warning naming elements that still mention a removed force (controllers, probes,
    groups ...), each by its owner's tag and name: ``ObjectGroup 'hip_add_r' <members>``."""
    if not removed:
        return
    names = set(removed)
    owner = {child: parent for parent in model_el.iter() for child in parent}
    hits = []
    for el in model_el.iter():
        words = set((el.text or "").replace("/", " ").split())
        if words & names and el.tag not in ("PathPoint",):
            up = owner.get(el)
            where = f"{up.tag} '{up.get('name')}' <{el.tag}>" if up is not None and up.get("name") else f"<{el.tag}>"
            hits.append(f"{where} ({', '.join(sorted(words & names))})")
    if hits:
        more = f" and {len(hits) - 5} more" if len(hits) > 5 else ""
        warnings.warn("the exported model still mentions replaced muscles in " + "; ".join(hits[:5]) + more
                      + ": edit those elements to use the fibre muscles", ExportWarning, stacklevel=3)


def export_osim(spec, result, out_path, *, muscles=None, keep_original=False, muscle_class=None,
                max_order: int = 8, seed: int = 0, announce=None, final_folder=None) -> dict:
    """Fit the fibres of a run and write the fibre-resolved OpenSim model (module docstring).

    Parameters
    ----------
    spec : FibreModelSpec
    result : RunResult
        A run of ``spec`` (its frames fix the fitted range).
    out_path : path
        The ``.osim`` to write.
    muscles : sequence of str, optional
        Muscles to export (default all of the run).
    keep_original, muscle_class, final_folder : see `write_fibre_model`
    max_order : int
        Highest polynomial order tried.
    seed : int
        Sampling seed.
    announce : callable(str), optional
        Progress messages.

    Returns
    -------
    dict: the export record written to run.json: ``file``, ``muscle_class``, ``keep_original``,
    ``parameter_rules`` and per muscle the fibre names, parameters and fit report.
    """
    from .fibre_paths import fit_fibre_paths, muscle_parameters

    fits = fit_fibre_paths(spec, result, muscles=muscles, max_order=max_order, seed=seed, announce=announce)
    entries, record = [], {}
    source = _source_tree(spec.model_path)          # read (and for a 3.x file upgraded) once
    for name, fit in fits.items():
        mspec = spec.muscle(name)
        props = line_properties(spec.model_path, mspec.action_lines, root=source)
        params = muscle_parameters(spec.model, mspec, props, fit.rest_lengths)
        entries.append({"name": name, "action_lines": list(mspec.action_lines), "coordinates": fit.coordinates,
                        "orders": fit.orders, "coefficients": fit.coefficients, "params": params,
                        "gates": fit.gates})
        rep = fit.report()
        rep.update({"fibre_muscles": fibre_muscle_names(name, len(fit.orders)),
                    "replaces": list(mspec.action_lines),
                    "max_isometric_force_N": params["max_isometric_force"],
                    "optimal_fiber_length_m": [round(float(v), 6) for v in params["optimal_fiber_length"]],
                    "tendon_slack_length_m": [round(float(v), 6) for v in params["tendon_slack_length"]]})
        record[name] = rep
    path = write_fibre_model(spec.model_path, out_path, entries, keep_original=keep_original,
                             muscle_class=muscle_class, final_folder=final_folder, root=source)
    return {"file": str(Path(path)), "muscle_class": muscle_class or "as the original",
            "keep_original": bool(keep_original),
            "parameter_rules": {"max_isometric_force": "sum of the action lines' forces / number of fibres",
                                "optimal_fiber_length": "force-weighted mean of the lines' optimal fibre "
                                                        "length / path length at the rest pose, times the "
                                                        "fibre's rest length",
                                "tendon_slack_length": "same rule with the tendon slack length"},
            "muscles": record}
