"""OpenSim side of the toolkit: models, motions, kinematics, action lines, surface wrapping.

Never imports ``fibres`` or ``analysis``.
"""
from .action_lines import ActionLines, action_lines
from .errors import InputError, MissingDependencyError
from .kinematics import BodyPoses, body_pose_derivatives, body_poses
from .model import Model
from .osim_reader import load_model
from .motion_file import Motion, load_motion, write_sto
from .surface_binding import SurfaceBinding, bind_surface
from .surface_generate import fusiform_surface
from .surface_spec import BoneMesh, MuscleSurfaceSpec, SurfaceAttachment
from .surface_wrap import WrappedSurface, wrap_surfaces

__all__ = ["InputError", "MissingDependencyError", "Motion", "load_motion", "write_sto",
           "MuscleSurfaceSpec", "SurfaceAttachment", "BoneMesh", "WrappedSurface", "wrap_surfaces",
           "SurfaceBinding", "bind_surface", "fusiform_surface",
           "load_model", "Model", "body_poses", "BodyPoses", "body_pose_derivatives", "action_lines", "ActionLines"]
