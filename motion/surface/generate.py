"""Closed fusiform muscle surfaces around an action line, for muscles that have no mesh.

The surface is a tube of revolution about the rest action line with the radius profile

    r(s) = r_max * sin(pi s) ** taper,   s in [0, 1] the arc-length fraction,

closed by one apex vertex at each end (the first and last path points), so it tapers to the
attachments. Rings sit on the line's rotation-minimising frames (Wang et al. 2008), so the
tube follows curved and wrapped lines without twisting.

Maximum radius (first that applies):

1. ``max_radius`` given;
2. ``volume`` given (m^3): ``volume = pi r_max^2 L I(taper)`` with
   ``I(taper) = Gamma(taper + 1/2) / (sqrt(pi) Gamma(taper + 1))`` the mean of
   ``sin(pi s)**(2 taper)``;
3. from OpenSim's muscle parameters: ``volume = PCSA * optimal_fiber_length`` with
   ``PCSA = max_isometric_force / sigma`` and specific tension ``sigma = 61 N/cm^2``
   (0.61 MPa, Arnold, Ward, Lieber & Delp, Ann. Biomed. Eng. 2010), then rule 2;
4. otherwise ``r_max = 0.1 L`` (a 1:5 belly, the typical fusiform aspect ratio).
"""
from __future__ import annotations

import math

import numpy as np

from .curves import any_perpendicular, curve_tangents, resample_polylines, rotation_minimizing_frames
from .volume import mesh_volume, solve_radial_scale, volume_cubic

__all__ = ["fusiform_surface", "fusiform_radius", "belly_surface", "belly_radius", "SPECIFIC_TENSION"]

#: A generated belly's radius is at most this fraction of its rest length (`belly_surface`).
BELLY_MAX_ASPECT = 0.1

#: A generated belly's flat caps are cut into this many rings (the inner ones are its landmarks).
CAP_RINGS = 3

#: Specific tension used to turn max isometric force into PCSA (Pa), Arnold et al. 2010.
SPECIFIC_TENSION = 0.61e6


def _profile_mean(taper: float) -> float:
    """Mean of sin(pi s)**(2 taper) over s in [0, 1]."""
    return math.gamma(taper + 0.5) / (math.sqrt(math.pi) * math.gamma(taper + 1.0))


def fusiform_radius(length: float, *, volume: float | None = None, max_isometric_force: float | None = None,
                    optimal_fiber_length: float | None = None, taper: float = 1.0) -> float:
    """The maximum radius ``r_max`` by the rules of the module docstring (metres)."""
    length = float(length)
    if length <= 0:
        raise ValueError("length must be positive")
    if volume is None and max_isometric_force and optimal_fiber_length:
        if np.isfinite(max_isometric_force) and np.isfinite(optimal_fiber_length) \
                and max_isometric_force > 0 and optimal_fiber_length > 0:
            volume = max_isometric_force / SPECIFIC_TENSION * optimal_fiber_length
    if volume is not None:
        if not volume > 0:
            raise ValueError("volume must be positive")
        return math.sqrt(volume / (math.pi * length * _profile_mean(taper)))
    return 0.1 * length


def _axis_samples(curve, n_rings, n_around, *, min_rings, what):
    """``n_rings`` arc-length samples of the axis curve and its length; ValueError for a
    degenerate axis or too few rings (``min_rings``) or vertices around (3)."""
    c = resample_polylines(np.asarray(curve, dtype=float), int(n_rings))
    length = float(np.sum(np.linalg.norm(np.diff(c, axis=0), axis=-1)))
    if length <= 0:
        raise ValueError(f"{what} has zero length")
    if n_rings < min_rings or n_around < 3:
        raise ValueError(f"need n_rings >= {min_rings} and n_around >= 3")
    return c, length


def fusiform_surface(curve, *, max_radius: float | None = None, volume: float | None = None,
                     taper: float = 1.0, n_rings: int = 40, n_around: int = 24):
    """A closed, smooth, outward-oriented fusiform surface around a polyline.

    Parameters
    ----------
    curve : (P, 3) float
        The action line at the rest pose, origin first (metres).
    max_radius, volume : float, keyword-only
        See the module docstring (``max_radius`` wins; default ``0.1 L``).
    taper : float, keyword-only
        Exponent of the sine profile (1: spindle; < 1: blunter ends).
    n_rings : int, keyword-only
        Number of arc-length stations including the two apexes (rings = ``n_rings - 2``).
    n_around : int, keyword-only
        Vertices per ring.

    Returns
    -------
    vertices : (V, 3) float
        ``V = (n_rings - 2) * n_around + 2``; vertex 0 is the origin apex, the last the
        insertion apex.
    faces : (T, 3) int
        ``T = 2 n_around (n_rings - 2)``, counter-clockwise seen from outside.
    """
    c, length = _axis_samples(curve, n_rings, n_around, min_rings=3, what="the action line")
    r_max = float(max_radius) if max_radius is not None else fusiform_radius(length, volume=volume, taper=taper)
    tan = curve_tangents(c[None])
    frames = rotation_minimizing_frames(c[None], any_perpendicular(tan[:, 0]), tangents=tan)[0]
    s = np.linspace(0.0, 1.0, int(n_rings))[1:-1]
    radius = r_max * np.sin(np.pi * s) ** float(taper)
    phi = 2.0 * np.pi * np.arange(int(n_around)) / int(n_around)
    normal = frames[1:-1, :, 0]
    binormal = frames[1:-1, :, 1]
    ring = (c[1:-1, None, :] + radius[:, None, None]
            * (np.cos(phi)[None, :, None] * normal[:, None, :] + np.sin(phi)[None, :, None] * binormal[:, None, :]))
    n_r, n_a = ring.shape[0], ring.shape[1]
    vertices = np.concatenate([c[:1], ring.reshape(-1, 3), c[-1:]], axis=0)
    idx = 1 + np.arange(n_r * n_a).reshape(n_r, n_a)
    nxt = np.roll(idx, -1, axis=1)
    last = len(vertices) - 1
    start_fan = np.stack([np.zeros(n_a, dtype=np.int64), nxt[0], idx[0]], axis=1)
    end_fan = np.stack([np.full(n_a, last), idx[-1], nxt[-1]], axis=1)
    a, b, cc, d = idx[:-1], nxt[:-1], nxt[1:], idx[1:]
    quads = np.concatenate([np.stack([a, b, cc], axis=-1).reshape(-1, 3),
                            np.stack([a, cc, d], axis=-1).reshape(-1, 3)], axis=0)
    faces = np.concatenate([start_fan, quads, end_fan], axis=0).astype(np.int64)
    if mesh_volume(vertices, faces) < 0:
        faces = faces[:, ::-1].copy()
    if max_radius is None and volume is not None:
        # the polygonal rings hold a little less than the smooth profile: rescale the radius
        # so the triangulated volume is exactly the requested one (a cubic in the scale)
        centre = np.concatenate([c[:1], np.repeat(c[1:-1], n_a, axis=0), c[-1:]], axis=0)
        coeffs = volume_cubic(centre[None], (vertices - centre)[None], faces)
        k = solve_radial_scale(coeffs, float(volume))[0]
        vertices = centre + k * (vertices - centre)
    return vertices, faces


def belly_radius(length: float, *, volume: float | None = None, max_radius: float | None = None) -> float:
    """The radius of `belly_surface`'s tube of rest length ``length`` (m), before the
    triangulated volume is made exact: ``max_radius``; else ``sqrt(volume / (pi length))``
    capped at ``BELLY_MAX_ASPECT * length``; else ``BELLY_MAX_ASPECT * length``."""
    if max_radius is not None:
        return float(max_radius)
    cap = BELLY_MAX_ASPECT * float(length)
    if volume is None:
        return cap
    if not volume > 0:
        raise ValueError("volume must be positive")
    return min(math.sqrt(float(volume) / (math.pi * float(length))), cap)


def belly_surface(curve, *, volume: float | None = None, max_radius: float | None = None,
                  n_rings: int = 40, n_around: int = 24, landmark_fraction: float = 0.9):
    """A closed tube around the belly piece of an action line, flat caps where the tendons join.

    The belly of a tendon-aware generated muscle (`motion.osim.muscle_parameters`): a tube of
    constant radius ``r`` about the line (rings on its rotation-minimising frames, Wang et al.
    2008), closed at each end by a flat disc perpendicular to the line, the tendon's footprint.
    Fibres of the parallel template then run from cap to cap, so their lengths are the belly
    length ``L - l_ts`` (rigid tendon). ``r``: ``max_radius``; else ``volume = pi r^2 b`` (the
    triangulated volume made exact, as in `fusiform_surface`); else ``0.1 b``.

    Parameters
    ----------
    curve : (P, 3) float
        The belly piece of the line at the rest pose, origin side first (metres).
    volume, max_radius : float, keyword-only
    n_rings, n_around : int, keyword-only
        Rings along the tube (both cap rims included) and vertices per ring.
    landmark_fraction : float, keyword-only
        The attachment landmarks: each cap's centre and a ring of 8 points at this fraction of
        the radius.

    Returns
    -------
    vertices : (V, 3) float
        ``V = n_rings * n_around + 2``: the rings, then the origin and insertion cap centres.
    faces : (T, 3) int
        Outward oriented.
    origin, insertion : (9, 3) float
        Attachment landmarks on the two caps.
    """
    c, length = _axis_samples(curve, n_rings, n_around, min_rings=2, what="the belly")
    r = belly_radius(length, volume=volume, max_radius=max_radius)
    slender = max_radius is None and volume is not None and r < math.sqrt(float(volume) / (math.pi * length))
    tan = curve_tangents(c[None])
    frames = rotation_minimizing_frames(c[None], any_perpendicular(tan[:, 0]), tangents=tan)[0]
    phi = 2.0 * np.pi * np.arange(int(n_around)) / int(n_around)
    around = (np.cos(phi)[None, :, None] * frames[:, None, :, 0] + np.sin(phi)[None, :, None] * frames[:, None, :, 1])
    ring = c[:, None, :] + r * around                                                  # (R, A, 3)
    n_r, n_a = ring.shape[0], ring.shape[1]
    fractions = np.arange(1, CAP_RINGS) / CAP_RINGS                                    # inner cap rings
    caps = [c[i][None, None, :] + r * fractions[:, None, None] * around[i][None] for i in (0, -1)]
    n_c = len(fractions) * n_a
    vertices = np.concatenate([ring.reshape(-1, 3), caps[0].reshape(-1, 3), caps[1].reshape(-1, 3),
                               c[:1], c[-1:]], axis=0)
    idx = np.arange(n_r * n_a).reshape(n_r, n_a)
    nxt = np.roll(idx, -1, axis=1)
    first, last = n_r * n_a + 2 * n_c, n_r * n_a + 2 * n_c + 1
    a, b, cc, d = idx[:-1], nxt[:-1], nxt[1:], idx[1:]
    tris = [np.stack([a, b, cc], axis=-1).reshape(-1, 3), np.stack([a, cc, d], axis=-1).reshape(-1, 3)]
    for k, (centre_v, rim) in enumerate(((first, idx[0]), (last, idx[-1]))):   # the two flat caps
        inner = n_r * n_a + k * n_c + np.arange(n_c).reshape(len(fractions), n_a)
        rings_k = list(inner) + [rim]
        cap = [np.stack([np.full(n_a, centre_v), np.roll(rings_k[0], -1), rings_k[0]], axis=1)]
        for lo, hi in zip(rings_k[:-1], rings_k[1:]):
            cap += [np.stack([lo, np.roll(hi, -1), hi], axis=1), np.stack([lo, np.roll(lo, -1), np.roll(hi, -1)], axis=1)]
        cap = np.concatenate(cap)
        tris.append(cap if k == 0 else cap[:, ::-1])
    faces = np.concatenate(tris).astype(np.int64)
    if mesh_volume(vertices, faces) < 0:
        faces = faces[:, ::-1].copy()
    centre = np.concatenate([np.repeat(c, n_a, axis=0), np.repeat(c[:1], n_c, axis=0), np.repeat(c[-1:], n_c, axis=0),
                             c[:1], c[-1:]], axis=0)
    if max_radius is None and volume is not None and not slender:
        coeffs = volume_cubic(centre[None], (vertices - centre)[None], faces)
        k = solve_radial_scale(coeffs, float(volume))[0]
        vertices = centre + k * (vertices - centre)
        r *= k

    def landmarks(i):   # the cap centre and its inner rings: the tendon's footprint
        sel = slice(n_r * n_a, n_r * n_a + n_c) if i == 0 else slice(n_r * n_a + n_c, n_r * n_a + 2 * n_c)
        return np.vstack([vertices[first if i == 0 else last][None], vertices[sel]])

    return vertices, faces, landmarks(0), landmarks(-1)
