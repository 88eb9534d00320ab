"""OpenSim side of the toolkit: models, motions, kinematics, action lines, surface wrapping.

Never imports ``fibres`` or ``analysis``.
"""
from .errors import InputError, MissingDependencyError
from .motion_file import Motion, load_motion, write_sto

__all__ = ["InputError", "MissingDependencyError", "Motion", "load_motion", "write_sto"]
