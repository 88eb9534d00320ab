"""OpenSim side of the toolkit: models, motions, kinematics, action lines, surface wrapping.

Never imports ``fibres`` or ``analysis``.
"""
from .errors import InputError, MissingDependencyError

__all__ = ["InputError", "MissingDependencyError"]
