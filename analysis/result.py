"""What `analysis.run` returns: per-muscle fibre and action-line lengths and moment arms, in memory.

Dimension letters (STYLE.md): F frames, N fibres, L action lines of one muscle, C coordinates the
muscle spans, P points per fibre.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from motion.osim.model import readonly_array

__all__ = ["MuscleResult", "RunResult"]


@dataclass(frozen=True, eq=False)
class MuscleResult:
    """One muscle over the frames of a run.

    Attributes
    ----------
    name : str
        The muscle of the fibre model (one surface; its OpenSim muscles are ``action_lines``).
    coordinates : tuple of str, (C,)
        The independent coordinates its action lines span (the moment-arm coordinates).
    fibre_lengths : (F, N) float
        Polyline arc length of each fibre, metres.
    fibre_moment_arms : (F, N, C) float
        r = -dL/dq per fibre and coordinate (m, or dimensionless for a translational coordinate).
    action_lines : tuple of str, (L,)
    action_line_lengths : (F, L) float
    action_line_moment_arms : (F, L, C) float
        Exact -dL/dq of the OpenSim paths (``motion.wrapping.action_lines``).
    rest_lengths : (N,) float
        Fibre lengths at the rest pose (the pose the mesh was acquired in).
    fibre_points : (F, N, P, 3) float or None
        Fibre polylines per frame in ground (kept unless the run was told not to). After
        ``fibres run`` (its ``on_muscle`` hook) only the 3D scene's frames are kept, (F', N, P, 3)
        with F' <= F (`analysis.scene.scene_frames`).
    surface_vertices : (F, V, 3) float or None
        The wrapped surface per frame (or the scene's frames), if kept; ``surface_faces`` (T, 3)
        int goes with it.
    notes : tuple of str
    quality : dict or None
        `fibres.finishing.quality.FibreQuality` of the rest-pose fibres, as a dict.
    optimal_lengths : (N,) float or None
        Each fibre's optimal length l_opt (m) for ``normalized_lengths``, NaN where unknown
        (`analysis.run`: the OpenSim muscle's optimal_fiber_length; with a user mesh scaled by
        the fibre's rest length over the median rest length).
    line_normalized_lengths : (F, L) float or None
        Per action line, the rigid-tendon normalized fibre length (L_path - tendon_slack_length)
        / optimal_fiber_length of its OpenSim muscle (NaN where the model has no parameters).
    """

    name: str
    coordinates: tuple
    fibre_lengths: np.ndarray
    fibre_moment_arms: np.ndarray
    action_lines: tuple
    action_line_lengths: np.ndarray
    action_line_moment_arms: np.ndarray
    rest_lengths: np.ndarray
    fibre_points: np.ndarray | None = None
    surface_vertices: np.ndarray | None = None
    surface_faces: np.ndarray | None = None
    notes: tuple = ()
    quality: dict | None = None
    optimal_lengths: np.ndarray | None = None
    line_normalized_lengths: np.ndarray | None = None

    def __post_init__(self):
        object.__setattr__(self, "coordinates", tuple(self.coordinates))
        object.__setattr__(self, "action_lines", tuple(self.action_lines))
        object.__setattr__(self, "notes", tuple(self.notes))
        fl = readonly_array(self.fibre_lengths, (-1, -1), name="fibre_lengths")
        fr = readonly_array(self.fibre_moment_arms, (-1, -1, -1), name="fibre_moment_arms")
        al = readonly_array(self.action_line_lengths, (-1, -1), name="action_line_lengths")
        ar = readonly_array(self.action_line_moment_arms, (-1, -1, -1), name="action_line_moment_arms")
        rest = readonly_array(self.rest_lengths, (-1,), name="rest_lengths")
        n_f, n_n = fl.shape
        c = len(self.coordinates)
        if fr.shape != (n_f, n_n, c):
            raise ValueError(f"fibre_moment_arms must be {(n_f, n_n, c)}, got {fr.shape}")
        if al.shape != (n_f, len(self.action_lines)):
            raise ValueError(f"action_line_lengths must be {(n_f, len(self.action_lines))}, got {al.shape}")
        if ar.shape != (n_f, len(self.action_lines), c):
            raise ValueError(f"action_line_moment_arms must be {(n_f, len(self.action_lines), c)}, "
                             f"got {ar.shape}")
        if rest.shape != (n_n,):
            raise ValueError(f"rest_lengths must be ({n_n},), got {rest.shape}")
        for key, val in (("fibre_lengths", fl), ("fibre_moment_arms", fr), ("action_line_lengths", al),
                         ("action_line_moment_arms", ar), ("rest_lengths", rest)):
            object.__setattr__(self, key, val)
        if self.optimal_lengths is not None:
            opt = readonly_array(self.optimal_lengths, (-1,), name="optimal_lengths")
            if opt.shape != (n_n,):
                raise ValueError(f"optimal_lengths must be ({n_n},), got {opt.shape}")
            object.__setattr__(self, "optimal_lengths", opt)
        if self.line_normalized_lengths is not None:
            ln = readonly_array(self.line_normalized_lengths, (-1, -1), name="line_normalized_lengths")
            if ln.shape != al.shape:
                raise ValueError(f"line_normalized_lengths must be {al.shape}, got {ln.shape}")
            object.__setattr__(self, "line_normalized_lengths", ln)
        if self.fibre_points is not None:
            pts = readonly_array(self.fibre_points, (-1, -1, -1, -1), name="fibre_points")
            if pts.shape[0] > n_f or pts.shape[1] != n_n or pts.shape[3] != 3:
                raise ValueError(f"fibre_points must be (F' <= {n_f}, {n_n}, P, 3), got {pts.shape}")
            object.__setattr__(self, "fibre_points", pts)
        if self.surface_vertices is not None:
            object.__setattr__(self, "surface_vertices",
                               readonly_array(self.surface_vertices, (-1, -1, -1), name="surface_vertices"))
            object.__setattr__(self, "surface_faces", readonly_array(self.surface_faces, dtype=np.int64))

    @property
    def n_fibres(self) -> int:
        return self.fibre_lengths.shape[1]

    @property
    def normalized_lengths(self) -> np.ndarray:
        """(F, N) float: fibre length over its optimal length, l / l_opt (NaN where unknown)."""
        if self.optimal_lengths is None:
            return np.full(self.fibre_lengths.shape, np.nan)
        return self.fibre_lengths / self.optimal_lengths[None, :]


@dataclass(frozen=True, eq=False)
class RunResult:
    """Everything `fibres run` computes, in memory.

    Attributes
    ----------
    time : (F,) float
        The motion's time of each frame used.
    frames : (F,) int
        Row index into the motion file of each frame used (the tables' ``frame`` column is
        ``0..F-1``, an index into the rows actually used).
    coordinate_names : tuple of str
        All model coordinates, model order.
    q : (F, C_all) float
        Coordinate values of each frame (SI).
    muscles : tuple of MuscleResult
    timings : mapping str -> float
        Wall-clock seconds per stage.
    settings : mapping
        Everything that shaped the result (fibres, resolution, template, step h, ...).
    inputs : mapping
        Input files (spec, model, motion, meshes, landmarks) by role.
    """

    time: np.ndarray
    frames: np.ndarray
    coordinate_names: tuple
    q: np.ndarray
    muscles: tuple
    timings: MappingProxyType = field(default_factory=lambda: MappingProxyType({}))
    settings: MappingProxyType = field(default_factory=lambda: MappingProxyType({}))
    inputs: MappingProxyType = field(default_factory=lambda: MappingProxyType({}))

    def __post_init__(self):
        object.__setattr__(self, "time", readonly_array(self.time, (-1,), name="time"))
        object.__setattr__(self, "frames", readonly_array(self.frames, dtype=np.int64))
        object.__setattr__(self, "q", readonly_array(self.q, (-1, -1), name="q"))
        object.__setattr__(self, "coordinate_names", tuple(self.coordinate_names))
        object.__setattr__(self, "muscles", tuple(self.muscles))
        for key in ("timings", "settings", "inputs"):
            object.__setattr__(self, key, MappingProxyType(dict(getattr(self, key))))
        n_f = len(self.time)
        if self.frames.shape != (n_f,) or self.q.shape != (n_f, len(self.coordinate_names)):
            raise ValueError("time, frames and q must share the frame axis")
        for m in self.muscles:
            if m.fibre_lengths.shape[0] != n_f:
                raise ValueError(f"muscle {m.name!r} has {m.fibre_lengths.shape[0]} frames, expected {n_f}")

    @property
    def muscle_names(self) -> tuple:
        return tuple(m.name for m in self.muscles)

    def muscle(self, name: str) -> MuscleResult:
        """The result of muscle ``name`` (KeyError if it was not run)."""
        for m in self.muscles:
            if m.name == name:
                return m
        raise KeyError(f"no muscle {name!r} in this run; have {', '.join(self.muscle_names)}")

    def coordinate_values(self, name: str) -> np.ndarray:
        """(F,) values of coordinate ``name``."""
        return self.q[:, self.coordinate_names.index(name)]

    def to_frame(self):
        """All lengths and moment arms as one long pandas DataFrame.

        Columns: frame, time, muscle, kind ("fibre" | "action_line"), fibre (id, -1 for an
        action line), action_line ("" for a fibre), quantity ("length" | "moment_arm"),
        coordinate ("" for a length), value (SI).
        """
        from .tables import result_long_frame

        return result_long_frame(self)
