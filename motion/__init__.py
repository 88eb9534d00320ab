"""OpenSim side of the toolkit: models, motions, kinematics, action lines, surface wrapping.

Uses `fibres` for geometry and errors, never `analysis` (docs/DESIGN.md, "Layering").
"""
from .wrapping.action_lines import ActionLines, action_lines
from .errors import InputError, MissingDependencyError
from .osim.kinematics import BodyPoses, body_pose_derivatives, body_poses
from .osim.model import Model
from .osim.reader import load_model
from .osim.motion_file import Motion, load_motion, write_sto
from .surface.bind import bind_surface
from .surface.binding import SurfaceBinding
from .surface.generate import fusiform_surface
from .surface.spec import BoneMesh, MuscleSurfaceSpec, SurfaceAttachment
from .surface.wrap import WrappedSurface, wrap_surfaces

__all__ = ["InputError", "MissingDependencyError", "Motion", "load_motion", "write_sto",
           "MuscleSurfaceSpec", "SurfaceAttachment", "BoneMesh", "WrappedSurface", "wrap_surfaces",
           "SurfaceBinding", "bind_surface", "fusiform_surface",
           "load_model", "Model", "body_poses", "BodyPoses", "body_pose_derivatives", "action_lines", "ActionLines"]
