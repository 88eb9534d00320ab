"""Fibre templates in the unit cube, after Blemker & Delp (2005) and Kohout et al. (2012) §3.1.

Blemker & Delp, "Three-dimensional representation of complex muscle architectures and
geometries", Ann. Biomed. Eng. 33(5):661-673 (2005) describe a muscle's fibre architecture as a
family of (rational) Bézier curves in a cube template, each curve indexed by two parameters and
running from the origin attachment area to the insertion area; the template is then mapped into
the muscle. Kohout et al. (GRAPP 2012) put the origin area on the bottom face and the insertion
area on the top face and sample the family with Sobol points (r, s).

Convention (shared with the rest of `fibres`): the cube is [0,1]^3; z is the fibre/principal axis
(z = 0 origin face, z = 1 insertion face); x, y span the cross-section; r moves across x, s across
y. Every control point lies in the cube and every weight is positive, so every fibre stays inside
the cube (convex-hull property of rational Bézier curves).

The six families (degree, rational?):

=========  ======  =====================================================================
parallel   2       straight fibres from the origin rectangle to the insertion rectangle.
pennate    3       origin band at the x=0 side, insertion band shifted across by
                   ``pennation`` (1: at the x=1 side, 0: above the origin band): fibres leave
                   the tendons along z (tangent length ``tendon``) and cross the muscle
                   obliquely (unipennate; pennation angle set by the band offset).
bipennate  3       origin bands at both x sides, insertion band in the middle (central
                   tendon): two mirrored pennate halves (r < 1/2 left, r >= 1/2 right);
                   ``pennation`` moves the origin bands from above the insertion (0) to the
                   outer faces (1).
curved     2, rat. arcs bulging towards +x; the fibre through the cube centre is an exact
                   circular arc (weight cos(alpha); Piegl & Tiller, The NURBS Book, ch. 7);
                   ``curvature`` is the bulge of that fibre as a fraction of the room to the x=1 face.
fanned     2       a wide origin converging on a small insertion around ``fan_centre``
                   (triangular/fan-shaped muscles, e.g. gluteus medius).
rectus     4       after the rectus femoris model of Blemker & Delp, "Rectus femoris and
                   vastus intermedius fiber excursions predicted by three-dimensional muscle
                   models", J. Biomech. 39:1383-1391 (2006): fibres leave a central proximal
                   aponeurosis that reaches ``aponeurosis`` of the length into the muscle and
                   run obliquely to distal aponeuroses on both outer sides, which reach the
                   same fraction down from the top (a simplification: one symmetric layer).
=========  ======  =====================================================================

Attachment areas are axis-aligned rectangles ``(x0, x1, y0, y1)`` on the bottom/top faces; they
are sampled on a 5 x 5 grid each for `Template.origin_area` / `Template.insertion_area` (what the
fitting of §3.2 compares with the user's landmarks).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from types import MappingProxyType

import numpy as np

from .bezier import arc_weight, evaluate
from ..errors import InputError

__all__ = ["TEMPLATES", "DEFAULTS", "Template", "get_template"]

TEMPLATES = ("parallel", "pennate", "bipennate", "curved", "fanned", "rectus")

#: documented default parameters of each template (sizes are fractions of the cube face)
DEFAULTS = MappingProxyType({
    "parallel": MappingProxyType({"origin_size": (1.0, 1.0), "insertion_size": (1.0, 1.0),
                                  "origin_centre": (0.5, 0.5), "insertion_centre": (0.5, 0.5)}),
    "pennate": MappingProxyType({"origin_size": (0.5, 1.0), "insertion_size": (0.5, 1.0),
                                 "tendon": 0.25, "pennation": 1.0}),
    "bipennate": MappingProxyType({"origin_size": (0.5, 1.0), "insertion_size": (0.3, 1.0),
                                   "tendon": 0.25, "pennation": 1.0}),
    "curved": MappingProxyType({"origin_size": (0.6, 1.0), "insertion_size": (0.6, 1.0),
                                "curvature": 0.5}),
    "fanned": MappingProxyType({"origin_size": (1.0, 1.0), "insertion_size": (0.2, 0.2),
                                "fan_centre": (0.5, 0.5), "spread": 0.5}),
    "rectus": MappingProxyType({"origin_size": (0.3, 1.0), "insertion_size": (0.5, 1.0),
                                "aponeurosis": 0.3}),
})

_GRID = 5  # area samples per rectangle side


def _pair(name, value):
    arr = np.asarray(value, dtype=np.float64).reshape(-1)
    if arr.shape != (2,) or not np.isfinite(arr).all():
        raise InputError(f"template parameter {name} must be two numbers, got {value!r}",
                         where=name, fix="Give (x, y) fractions of the cube face.")
    return arr


def _frac(name, value, lo, hi, *, open_lo=False, open_hi=False):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"template parameter {name} must be a number, got {value!r}",
                         where=name) from None
    bad = not np.isfinite(v) or v < lo or v > hi or (open_lo and v == lo) or (open_hi and v == hi)
    if bad:
        raise InputError(f"template parameter {name}={value!r} is out of range",
                         where=name, fix=f"Use a value in {'(' if open_lo else '['}{lo}, {hi}"
                                         f"{')' if open_hi else ']'}.")
    return v


def _centred_rect(size, centre, name):
    """(x0, x1, y0, y1) of a rectangle of ``size`` centred at ``centre``; must fit in the face."""
    lo = centre - size / 2
    hi = centre + size / 2
    if (size <= 0).any() or (lo < -1e-12).any() or (hi > 1 + 1e-12).any():
        raise InputError(f"the {name} area (size {tuple(size)}, centre {tuple(centre)}) does not "
                         "fit in the unit face", where=name,
                         fix="Use sizes in (0, 1] and centres that keep the area on the face.")
    return np.array([max(lo[0], 0), min(hi[0], 1), max(lo[1], 0), min(hi[1], 1)])


def _size(params, key):
    s = _pair(key, params[key])
    if (s <= 0).any() or (s > 1).any():
        raise InputError(f"template parameter {key}={tuple(s)} must be in (0, 1]", where=key,
                         fix="Give fractions of the cube face.")
    return s


def _rects(name, p):
    """Origin and insertion rectangles (lists of (x0, x1, y0, y1)) for the validated params."""
    o, i = _size(p, "origin_size"), _size(p, "insertion_size")
    if name == "parallel":
        return ([_centred_rect(o, _pair("origin_centre", p["origin_centre"]), "origin")],
                [_centred_rect(i, _pair("insertion_centre", p["insertion_centre"]), "insertion")])
    ylo_o, yhi_o = 0.5 - o[1] / 2, 0.5 + o[1] / 2
    ylo_i, yhi_i = 0.5 - i[1] / 2, 0.5 + i[1] / 2
    pen = p.get("pennation", 1.0)
    if name == "pennate":  # origin band at x=0; insertion band shifted by pennation * max
        ci = o[0] / 2 + pen * (1 - o[0] / 2 - i[0] / 2)
        return ([np.array([0.0, o[0], ylo_o, yhi_o])],
                [np.array([ci - i[0] / 2, ci + i[0] / 2, ylo_i, yhi_i])])
    if name == "curved":
        return ([np.array([0.0, o[0], ylo_o, yhi_o])], [np.array([0.0, i[0], ylo_i, yhi_i])])
    if name == "bipennate":  # outer origin bands (moved out by pennation), central insertion
        above = 0.5 - i[0] / 4                      # above the left half of the insertion band
        cl = above - pen * (above - o[0] / 4)       # pennation 1: band touches the x=0 face
        return ([np.array([cl - o[0] / 4, cl + o[0] / 4, ylo_o, yhi_o]),
                 np.array([1 - cl - o[0] / 4, 1 - cl + o[0] / 4, ylo_o, yhi_o])],
                [np.array([0.5 - i[0] / 2, 0.5 + i[0] / 2, ylo_i, yhi_i])])
    if name == "rectus":  # central origin band, outer insertion bands
        return ([np.array([0.5 - o[0] / 2, 0.5 + o[0] / 2, ylo_o, yhi_o])],
                [np.array([0.0, i[0] / 2, ylo_i, yhi_i]), np.array([1 - i[0] / 2, 1.0, ylo_i, yhi_i])])
    if name == "fanned":
        return ([_centred_rect(o, np.array([0.5, 0.5]), "origin")],
                [_centred_rect(i, _pair("fan_centre", p["fan_centre"]), "insertion")])
    raise AssertionError(name)


def _lerp(a, b, u):
    return a + (b - a) * u


def _end_points(name, rects_o, rects_i, rs):
    """Origin and insertion points (N, 3) of the fibres (r, s)."""
    r, s = rs[:, 0], rs[:, 1]
    n = len(rs)
    po, pi = np.zeros((n, 3)), np.ones((n, 3))
    ro, ri = rects_o[0], rects_i[0]
    po[:, 1] = _lerp(ro[2], ro[3], s)
    pi[:, 1] = _lerp(ri[2], ri[3], s)
    if name in ("bipennate", "rectus"):
        left = r < 0.5
        u = np.where(left, 2 * r, 2 * r - 1)  # position across its half
        if name == "bipennate":  # left band [0, a] -> insertion left half, right mirrored
            a, b = rects_o[0], rects_o[1]
            po[:, 0] = np.where(left, _lerp(a[0], a[1], u), _lerp(b[0], b[1], u))
            pi[:, 0] = np.where(left, _lerp(ri[0], 0.5 * (ri[0] + ri[1]), u),
                                _lerp(0.5 * (ri[0] + ri[1]), ri[1], u))
        else:  # central origin: left half of it -> left insertion band, right -> right band
            a, b = rects_i[0], rects_i[1]
            po[:, 0] = np.where(left, _lerp(ro[0], 0.5 * (ro[0] + ro[1]), u),
                                _lerp(0.5 * (ro[0] + ro[1]), ro[1], u))
            pi[:, 0] = np.where(left, _lerp(a[0], a[1], u), _lerp(b[0], b[1], u))
    else:
        po[:, 0] = _lerp(ro[0], ro[1], r)
        pi[:, 0] = _lerp(ri[0], ri[1], r)
    return po, pi


def _control(name, p, rects_o, rects_i, rs):
    """Control points (N, D+1, 3) and weights (D+1,) or None."""
    po, pi = _end_points(name, rects_o, rects_i, rs)
    ez = np.array([0.0, 0.0, 1.0])
    if name == "parallel":
        return np.stack([po, 0.5 * (po + pi), pi], axis=1), None
    if name in ("pennate", "bipennate"):
        h = p["tendon"]
        return np.stack([po, po + h * ez, pi - h * ez, pi], axis=1), None
    if name == "rectus":
        a = p["aponeurosis"]
        mid = 0.5 * (po + pi)
        return np.stack([po, po + a * ez, mid, pi - a * ez, pi], axis=1), None
    if name == "fanned":
        mid = 0.5 * (po + pi)
        lifted = po.copy()
        lifted[:, 2] = 0.5
        return np.stack([po, _lerp(mid, lifted, p["spread"]), pi], axis=1), None
    if name == "curved":
        c = p["curvature"]
        mid = 0.5 * (po + pi)
        bulge = mid.copy()
        bulge[:, 0] = mid[:, 0] + c * (1.0 - mid[:, 0])
        # one weight for the whole family (fibres then never cross): the arc weight of the
        # fibre through the centre of the cube, bulging c/2 over a chord of 1
        w1 = float(arc_weight(np.array([0.5, 0.5, 0.0]), np.array([0.5 + c / 2, 0.5, 0.5]),
                              np.array([0.5, 0.5, 1.0])))
        return np.stack([po, bulge, pi], axis=1), np.array([1.0, w1, 1.0])
    raise AssertionError(name)


def _grid_on(rects, z):
    u = np.linspace(0.0, 1.0, _GRID)
    gx, gy = np.meshgrid(u, u, indexing="ij")
    pts = [np.stack([_lerp(r[0], r[1], gx.ravel()), _lerp(r[2], r[3], gy.ravel()),
                     np.full(gx.size, z)], axis=1) for r in rects]
    out = np.concatenate(pts)
    out.flags.writeable = False
    return out


@dataclass(frozen=True)
class Template:
    """A family of template fibres in the unit cube (Blemker & Delp 2005; Kohout 2012 §3.1).

    Build with `get_template`. Attributes
    -------------------------------------
    name : str
        One of `TEMPLATES`.
    params : mapping
        The full parameter set (defaults of `DEFAULTS` updated with the caller's values).
    origin_area : (K, 3) float
        Points sampling the origin rectangle(s) on the bottom face (z = 0).
    insertion_area : (K, 3) float
        Points sampling the insertion rectangle(s) on the top face (z = 1).
    offset : (2,) float
        Cross-section offset (x, y) of the insertion area's centroid from the origin
        area's, ``(insertion_area.mean(axis=0) - origin_area.mean(axis=0))[:2]``.
    oblique : bool
        Whether that offset is not zero (above 1e-12; pennate): the attachment direction
        is then not the box's z axis (`fibres.fit.fitting.principal_frame`). offset and
        oblique are derived from the areas once, when the template is made (plain
        attributes, not dataclass fields).
    """

    name: str
    params: MappingProxyType
    origin_area: np.ndarray = field(init=False, repr=False)
    insertion_area: np.ndarray = field(init=False, repr=False)
    _rects: tuple = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        if self.name not in TEMPLATES:
            raise InputError(f"unknown template {self.name!r}", where="template",
                             fix=f"Use one of: {', '.join(TEMPLATES)}.")
        p = dict(self.params)
        for key in ("tendon",):
            if key in p:
                p[key] = _frac(key, p[key], 0.0, 0.5)
        if "pennation" in p:
            p["pennation"] = _frac("pennation", p["pennation"], 0.0, 1.0)
        if "curvature" in p:
            p["curvature"] = _frac("curvature", p["curvature"], 0.0, 1.0, open_hi=True)
        if "spread" in p:
            p["spread"] = _frac("spread", p["spread"], 0.0, 1.0)
        if "aponeurosis" in p:
            p["aponeurosis"] = _frac("aponeurosis", p["aponeurosis"], 0.0, 0.5)
        rects_o, rects_i = _rects(self.name, p)
        p = {k: (tuple(float(x) for x in v) if isinstance(v, (tuple, list, np.ndarray)) else v)
             for k, v in p.items()}
        object.__setattr__(self, "params", MappingProxyType(p))
        object.__setattr__(self, "_rects", (tuple(rects_o), tuple(rects_i)))
        object.__setattr__(self, "origin_area", _grid_on(rects_o, 0.0))
        object.__setattr__(self, "insertion_area", _grid_on(rects_i, 1.0))
        offset = (self.insertion_area.mean(axis=0) - self.origin_area.mean(axis=0))[:2]
        offset.flags.writeable = False
        object.__setattr__(self, "offset", offset)
        object.__setattr__(self, "oblique", bool(np.abs(offset).max() > 1e-12))

    @property
    def degree(self) -> int:
        """Degree D of the Bézier curves of this family."""
        return {"parallel": 2, "pennate": 3, "bipennate": 3, "curved": 2, "fanned": 2,
                "rectus": 4}[self.name]

    @property
    def rational(self) -> bool:
        """Whether the curves are rational (non-unit weights)."""
        return self.name == "curved" and self.params["curvature"] > 0

    def control_points(self, rs):
        """Control points (N, D+1, 3) and weights ((D+1,) or None) of the fibres ``rs`` (N, 2)."""
        rs = self._check_rs(rs)
        return _control(self.name, self.params, self._rects[0], self._rects[1], rs)

    def fibre_points(self, rs, t) -> np.ndarray:
        """Points of the template fibres.

        Parameters
        ----------
        rs : (N, 2) float in [0, 1]
            Fibre parameters (usually `sobol_rs`).
        t : (P,) float in [0, 1]
            Curve parameters (``np.linspace(0, 1, R + 1)`` for resolution R).

        Returns
        -------
        (N, P, 3) float64
            Unit-cube points; t = 0 on the origin area (z = 0), t = 1 on the insertion area
            (z = 1).
        """
        rs = self._check_rs(rs)
        t = np.asarray(t, dtype=np.float64).reshape(-1)
        if t.size and (t.min() < 0 or t.max() > 1 or not np.isfinite(t).all()):
            raise ValueError("t must lie in [0, 1]")
        return self._points(rs, t)

    def _points(self, rs, t) -> np.ndarray:
        """`fibre_points` of checked ``rs`` (N, 2) and ``t`` (P,) float64 in [0, 1] (e.g.
        `fibres.template.sampling.sobol_rs` and a linspace, made by the caller)."""
        ctrl, w = _control(self.name, self.params, self._rects[0], self._rects[1], rs)
        return evaluate(ctrl, t, w)

    @staticmethod
    def _check_rs(rs):
        rs = np.asarray(rs, dtype=np.float64)
        if rs.ndim == 1 and rs.shape == (2,):
            rs = rs[None]
        if rs.ndim != 2 or rs.shape[1] != 2:
            raise ValueError(f"rs must be (N, 2), got {rs.shape}")
        if rs.size and (not np.isfinite(rs).all() or rs.min() < 0 or rs.max() > 1):
            raise ValueError("rs must lie in [0, 1]^2")
        return rs


def get_template(name: str = "parallel", **params) -> Template:
    """A fibre template by name with its documented defaults overridden by ``params``.

    Parameters
    ----------
    name : str
        One of `TEMPLATES`.
    **params
        Any key of ``DEFAULTS[name]`` (e.g. ``origin_size=(0.5, 1.0)``, ``curvature=0.3``).

    Raises
    ------
    InputError
        Unknown name, unknown parameter or a value out of range.
    """
    if name not in TEMPLATES:
        raise InputError(f"unknown template {name!r}", where="template",
                         fix=f"Use one of: {', '.join(TEMPLATES)}.")
    unknown = sorted(set(params) - set(DEFAULTS[name]))
    if unknown:
        raise InputError(f"unknown parameter(s) {', '.join(unknown)} for the {name} template",
                         where="template_params",
                         fix=f"Use: {', '.join(DEFAULTS[name])}.")
    try:
        return _cached_template(name, tuple(sorted(params.items())))
    except TypeError:                                  # unhashable values (lists, arrays)
        return _build_template(name, params)


@lru_cache(maxsize=64)
def _cached_template(name, items):
    """Templates are immutable: one instance per (name, parameters)."""
    return _build_template(name, dict(items))


def _build_template(name, params):
    merged = dict(DEFAULTS[name])
    merged.update(params)
    return Template(name, MappingProxyType(merged))
