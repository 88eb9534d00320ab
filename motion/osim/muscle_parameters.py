"""OpenSim muscle parameters and the rigid-tendon split of a path into tendons and belly.

`muscle_parameters(model, name)` reads from the model file the properties every OpenSim muscle
class has (Thelen2003Muscle, Millard2012EquilibriumMuscle, Schutte1993Muscle_Deprecated,
RigidTendonMuscle ...): ``max_isometric_force``, ``optimal_fiber_length``,
``tendon_slack_length`` and ``pennation_angle_at_optimal`` (``pennation_angle`` in OpenSim 2.x
files). A path force without them (PathActuator, Ligament) gets None for each.

The tendon rule of generated muscles (`belly_span`), a rigid-tendon reading of the Hill model
(Zajac, Crit. Rev. Biomed. Eng. 1989; OpenSim's RigidTendonMuscle): the tendon keeps its slack
length ``l_ts`` and the rest of the path is the fibre part, the belly,

    b(L) = L - l_ts,

measured along the path. The tendon length is split between the two ends, a share ``s`` at the
origin and ``1 - s`` at the insertion: OpenSim has one tendon length per muscle and does not say
where it sits, so by default ``s = 1/2`` and the belly is centred on the path; a fibre model may
say otherwise per muscle (a gastrocnemius' tendon is mostly distal). Where the path is shorter
than ``l_ts + 2 f L`` (``f = BELLY_MIN_FRACTION``) the belly is kept at least ``f L`` long by
the C1 floor

    b = f L + x^2 / (4 f L)   for 0 <= x = L - l_ts < 2 f L,      b = f L for x < 0,

and the tendons share the rest in the same proportion (the caller warns: such a path cannot
hold its tendon).
Pennation does not enter the belly length: the belly is the fibre part of the path along the
line; a pennate template then lays its fibres at its own angle inside that belly (their lengths
are shorter than the belly by about cos of that angle).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["MuscleParameters", "muscle_parameters", "belly_span", "BELLY_MIN_FRACTION"]

#: The belly is never shorter than this fraction of the path (see the module docstring).
BELLY_MIN_FRACTION = 0.02

_CACHE: dict = {}


@dataclass(frozen=True)
class MuscleParameters:
    """A muscle's Hill-model parameters from the model file (SI; None where absent)."""

    max_isometric_force: float | None = None
    optimal_fiber_length: float | None = None
    tendon_slack_length: float | None = None
    pennation_angle: float | None = None


def _number(el, *tags):
    for tag in tags:
        text = el.findtext(tag)
        if text is not None:
            try:
                value = float(text.split()[0])
            except (ValueError, IndexError):
                return None
            return value if np.isfinite(value) else None
    return None


def muscle_parameters(model, name: str) -> MuscleParameters:
    """The `MuscleParameters` of the path force ``name`` of ``model`` (read once per file).

    Parameters
    ----------
    model : motion.Model
        Its ``file`` is read (defusedxml, decoded as `motion.osim.xml_document.read_document`
        does: UTF-8, else Latin-1); a model without a readable file gives all None.
    name : str
        The muscle's name.

    Returns
    -------
    MuscleParameters
    """
    file = getattr(model, "file", None)
    if not file:
        return MuscleParameters()
    key = str(file)
    if key not in _CACHE:
        table = {}
        try:   # read as the model itself was (a Latin-1 byte under a UTF-8 declaration, as in LHDL)
            from .xml_document import read_document

            root = read_document(key).el
        except Exception:  # noqa: BLE001 - no file or not XML: no parameters
            root = None
        if root is not None:
            for el in root.iter():
                label = el.get("name")
                if label is None or label in table or el.find("max_isometric_force") is None:
                    continue
                table[label] = MuscleParameters(
                    max_isometric_force=_number(el, "max_isometric_force"),
                    optimal_fiber_length=_number(el, "optimal_fiber_length"),
                    tendon_slack_length=_number(el, "tendon_slack_length"),
                    pennation_angle=_number(el, "pennation_angle_at_optimal", "pennation_angle"))
        if len(_CACHE) >= 8:
            _CACHE.pop(next(iter(_CACHE)))
        _CACHE[key] = table
    return _CACHE[key].get(name, MuscleParameters())


def belly_span(path_length, tendon_slack_length, origin_share: float = 0.5):
    """Arc-length start and end of the belly on paths of length ``L`` (module docstring).

    Parameters
    ----------
    path_length : (F,) float
        Current path lengths ``L`` (m).
    tendon_slack_length : float
        ``l_ts`` (m), >= 0.
    origin_share : float
        The share ``s`` (0..1) of the tendon at the origin end.

    Returns
    -------
    start, stop : (F,) float
        The belly runs from arc length ``start`` to ``stop`` (``stop - start = b(L)``).
    short : (F,) bool
        Frames where the path is shorter than ``l_ts + 2 f L`` (the floor acts).
    """
    length = np.asarray(path_length, dtype=float)
    slack = max(float(tendon_slack_length), 0.0)
    floor = BELLY_MIN_FRACTION * length
    x = length - slack
    belly = np.where(x >= 2.0 * floor, x, floor + np.maximum(x, 0.0) ** 2 / np.maximum(4.0 * floor, 1e-300))
    share = float(origin_share)
    return share * (length - belly), length - (1.0 - share) * (length - belly), x < 2.0 * floor
