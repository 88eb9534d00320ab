"""Fibre path functions for an OpenSim model: per fibre, a polynomial of the muscle's spanned
coordinates fitted to our fibre lengths and moment arms over sampled poses, and the fibre's
muscle parameters.

Method (`fit_fibre_paths`), per muscle of a finished run:

1. Poses: ``n`` samples around the run's own frames (`analysis.path_fit.sample_poses`: the frames
   plus Latin-hypercube offsets within +-10 degrees / 2 cm on each spanned coordinate, as OpenSim's
   PolynomialPathFitter samples), plus the run's frames themselves; a separate validation set of
   ``n // 2`` samples drawn the same way with another random stream. Clamped coordinates (in a
   model with constraints, where posing clamps them) are clipped to their range in the frames and
   the samples: the lengths there are those of the clamped pose, so samples beyond the range
   would put a kink at its bound into the data that no polynomial fits, and OpenSim's assembly
   never evaluates the path function there.
2. Fibre lengths and moment arms at those poses: the same chain as the run (`analysis.run` with the
   run's template, fibres, resolution and transport, the poses as a motion, in chunks of
   ``CHUNK`` poses). The rest decomposition is deterministic, so fibre k is the run's fibre k
   (checked: the rest lengths must agree).
3. Fit: `analysis.path_fit.select_orders` picks per fibre the lowest order 1..``max_order`` whose
   worst validation errors are within ``length_tol`` (0.1 mm) and ``moment_arm_tol`` (0.5 mm). If
   a fibre has no such order, the training samples double (up to ``max_samples``) and the fit is
   repeated; the order and sample count used are reported per fibre with the measured errors.

Muscle parameters of fibre k of a muscle whose action lines i have OpenSim max isometric forces
F_i, optimal fibre lengths l_i, tendon slack lengths s_i and path lengths L_i at the fibre
model's rest pose (the pose the mesh was acquired in; fibre rest length l_k there):

- max isometric force: sum_i F_i / N, an equal share. The templates place the fibres by Sobol
  (quasi-uniform) sampling of the muscle cross-section, so each fibre stands for an equal part of
  the physiological cross-sectional area, to which OpenSim's F_max is proportional.
- optimal fibre length and tendon slack length: the action lines' ratios l_i / L_i and s_i / L_i
  (force-weighted mean over the lines) times the fibre's rest length l_k, so each fibre keeps the
  original fibre/tendon proportions of the muscle-tendon unit along its own length.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from . import path_fit
from .errors import InputError
from .fibre_moment_arms import clamped

__all__ = ["MuscleFit", "fit_fibre_paths", "muscle_parameters", "CHUNK", "LENGTH_TOL", "MOMENT_ARM_TOL"]

#: sampled poses per call of `analysis.run` (bounds the memory of the stacked frames)
CHUNK = 64
#: fit tolerances on the validation poses (metres; metres per radian for moment arms)
LENGTH_TOL = 1e-4
MOMENT_ARM_TOL = 5e-4


@dataclasses.dataclass(frozen=True)
class MuscleFit:
    """The fitted path functions of one muscle's fibres.

    Attributes
    ----------
    muscle : str
    coordinates : tuple of str, (D,)
        Arguments of every polynomial, in order.
    orders : (N,) int
    coefficients : list of (T_k,) float, OpenSim term order
    n_samples : int
        Training poses used (sampled + the run's frames).
    validation : dict of (N,) arrays
        ``length_max``, ``length_rms``, ``moment_arm_max`` on the validation poses.
    motion : dict of (N,) arrays
        ``length_max``, ``moment_arm_max``: the polynomial against the run's own fibre lengths and
        moment arms over the run's frames.
    rest_lengths : (N,) float
    """

    muscle: str
    coordinates: tuple
    orders: np.ndarray
    coefficients: list
    n_samples: int
    validation: dict
    motion: dict
    rest_lengths: np.ndarray
    ok: np.ndarray
    gates: tuple = ()
    gate_reasons: tuple = ()
    limitations: tuple = ()

    def report(self) -> dict:
        """JSON-ready per-fibre record (for run.json)."""
        def r(a):
            return [float(f"{v:.4g}") for v in np.asarray(a, dtype=float)]

        return {"coordinates": list(self.coordinates), "n_samples": int(self.n_samples),
                "length_function": "ExpressionBasedFunction" if self.gates else "MultivariatePolynomialFunction",
                "gates": [{"coordinate": self.coordinates[c], "active_from": float(lo), "active_to": float(hi),
                           "why": why} for (c, lo, hi), why in zip(self.gates, self.gate_reasons)],
                "limitations": list(self.limitations),
                "within_tolerance": bool(np.all(self.ok)),
                "order": [int(o) for o in self.orders],
                "validation_length_max_m": r(self.validation["length_max"]),
                "validation_length_rms_m": r(self.validation["length_rms"]),
                "validation_moment_arm_max_m": r(self.validation["moment_arm_max"]),
                "motion_length_max_m": r(self.motion["length_max"]),
                "motion_moment_arm_max_m": r(self.motion["moment_arm_max"])}


def _measure(spec, model, q, name, msettings, transport):
    """Fibre lengths (S, N), moment arms (S, N, D) and rest lengths of muscle ``name`` at poses q.

    The runs' `FibreWarning`s are not passed on: they are about sampled poses, chunk by chunk
    (one differently worded warning per chunk), not about the motion, whose own run has warned
    already; the fit's quality is the fit report's."""
    import warnings

    import motion as motion_pkg

    from .errors import FibreWarning
    from .run import run

    lengths, arms, rest = [], [], None
    for start in range(0, len(q), CHUNK):
        block = q[start:start + CHUNK]
        mot = motion_pkg.Motion.from_array(model, np.arange(len(block), dtype=float), block)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FibreWarning)
            res = run(spec, mot, muscles=[name], fibres=msettings["fibres"], resolution=msettings["resolution"],
                      template=msettings["template"], quiet=True, keep_points=False, transport=transport)
        m = res.muscles[0]
        lengths.append(m.fibre_lengths)
        arms.append(m.fibre_moment_arms)
        rest = m.rest_lengths
    return np.vstack(lengths), np.vstack(arms), rest


def fit_fibre_paths(spec, result, *, muscles=None, max_order: int = 8, n_samples: int | None = None,
                    max_samples: int = 1024, length_tol: float = LENGTH_TOL,
                    moment_arm_tol: float = MOMENT_ARM_TOL, seed: int = 0, announce=None) -> dict:
    """Fit a polynomial path function to every fibre of the run's muscles (module docstring).

    Parameters
    ----------
    spec : FibreModelSpec
        The fibre model the run was made from.
    result : RunResult
        The run (its frames fix the sampled range; its fibres are the ones fitted).
    muscles : sequence of str, optional
        Muscles to fit (default: every muscle of the run).
    max_order : int
        Highest total degree tried.
    n_samples : int, optional
        First number of sampled training poses (default 64 per spanned coordinate).
    max_samples : int
        Most sampled training poses.
    length_tol, moment_arm_tol : float
        Validation tolerances (m).
    seed : int
        Random stream of the sampling.
    announce : callable(str), optional
        Called with a one-line progress message per muscle.

    Returns
    -------
    dict muscle name -> MuscleFit
    """
    model = spec.model
    transport = result.settings.get("transport", "bind")
    names = list(muscles) if muscles else list(result.muscle_names)
    out = {}
    for name in names:
        m = result.muscle(name)
        if not m.coordinates:
            raise InputError(f"muscle {name!r} spans no free coordinate, so it has no path function to fit",
                             where=f"muscle {name!r}", fix="Leave it out of the export with --muscle.")
        msettings = result.settings["muscles"][name]
        coord_idx = np.array([model.coordinate_index(c) for c in m.coordinates])
        kinds = [model.coordinates[c].motion_type for c in coord_idx]
        rng = np.random.default_rng([seed, 1])
        rng_v = np.random.default_rng([seed, 2])
        d = len(coord_idx)
        n = int(n_samples or 64 * d)
        q_run = clamped(model, result.q)      # the poses used: a clamped coordinate never leaves its range
        gates, reasons, limitations = _path_features(model, spec.muscle(name), m.coordinates, q_run, coord_idx, kinds)
        top = path_fit.max_order_for(d, max_order)
        q_val = clamped(model, path_fit.sample_poses(q_run, coord_idx, kinds, max(n // 2, 16), rng_v))
        if announce:
            announce(f"fitting path functions of {name} ({m.n_fibres} fibres, {d} coordinates)")
        l_val, r_val, rest = _measure(spec, model, q_val, name, msettings, transport)
        if not np.allclose(rest, m.rest_lengths, rtol=0, atol=1e-9):
            raise RuntimeError(f"muscle {name!r}: the sampled fibres are not the run's fibres "
                               "(rest lengths differ)")
        q_tr = np.empty((0, result.q.shape[1]))
        l_tr = np.empty((0, m.n_fibres))
        r_tr = np.empty((0, m.n_fibres, d))
        while True:
            q_new = clamped(model, path_fit.sample_poses(q_run, coord_idx, kinds, n - len(q_tr), rng))
            l_new, r_new, _ = _measure(spec, model, q_new, name, msettings, transport)
            q_tr, l_tr, r_tr = np.vstack([q_tr, q_new]), np.vstack([l_tr, l_new]), np.vstack([r_tr, r_new])
            train = (np.vstack([q_tr, q_run])[:, coord_idx], np.vstack([l_tr, m.fibre_lengths]),
                     np.vstack([r_tr, m.fibre_moment_arms]))
            choice = path_fit.select_orders(train, (q_val[:, coord_idx], l_val, r_val), max_order=top,
                                            length_tol=length_tol, moment_arm_tol=moment_arm_tol, gates=gates)
            if choice.ok.all() or 2 * n > max_samples:
                break
            n *= 2
        l_m, r_m = _evaluate_each(choice, d, q_run[:, coord_idx], gates)
        out[name] = MuscleFit(
            muscle=name, coordinates=tuple(m.coordinates), orders=choice.orders,
            coefficients=choice.coefficients, n_samples=len(train[0]),
            validation={"length_max": choice.length_max, "length_rms": choice.length_rms,
                        "moment_arm_max": choice.moment_arm_max},
            motion={"length_max": np.abs(l_m - m.fibre_lengths).max(axis=0),
                    "moment_arm_max": np.abs(r_m - m.fibre_moment_arms).max(axis=(0, 2))},
            rest_lengths=m.rest_lengths, ok=choice.ok, gates=gates,
            gate_reasons=reasons, limitations=limitations)
    return out


def _path_features(model, mspec, coordinates, q_frames, coord_idx, kinds):
    """Gates (`analysis.path_fit`, module docstring) for the ConditionalPathPoints of the muscle's
    action lines that switch inside the sampled range and, for a muscle spanning one coordinate,
    for the values where a line starts or stops wrapping; and plain-language limitations: wrap
    objects of a muscle spanning several coordinates (the polynomial smooths over the bend in a
    fibre's length where its line starts or stops wrapping) and conditional points on
    coordinates the function does not take."""
    gates, reasons, notes = [], [], []
    lo_q = np.asarray(q_frames)[:, coord_idx].min(axis=0)
    hi_q = np.asarray(q_frames)[:, coord_idx].max(axis=0)
    half = np.array([path_fit.SAMPLING_HALF_WIDTH.get(k, path_fit.SAMPLING_HALF_WIDTH["rotational"])
                     for k in kinds])
    for line in mspec.action_lines:
        path = model.path(line)
        for pt in path.points:
            if pt.kind != "conditional":
                continue
            if pt.coordinate not in coordinates:
                notes.append(f"{line}: ConditionalPathPoint {pt.name} switches with {pt.coordinate}, "
                             "which the path function does not take: its step is not represented")
                continue
            c = list(coordinates).index(pt.coordinate)
            gate = (c, float(pt.range[0]) - 1e-5, float(pt.range[1]) + 1e-5)
            inside = [lo_q[c] - half[c] < x < hi_q[c] + half[c] for x in gate[1:]]
            if any(inside) and gate not in gates:
                gates.append(gate)
                reasons.append(f"{line}: ConditionalPathPoint {pt.name}")
        if path.wraps and len(coordinates) == 1:
            # one coordinate: the line starts / stops wrapping at fixed values of it, where a
            # fibre's length bends sharply (its moment arm steps, README "Wrap objects"): a gate
            # there makes the function piecewise, so it follows the bend
            for x, wrapped_above in _wrap_switches(model, line, coord_idx[0], q_frames[0],
                                                   lo_q[0] - half[0], hi_q[0] + half[0]):
                gate = (0, x, 1e3) if wrapped_above else (0, -1e3, x)
                if gate not in gates:
                    gates.append(gate)
                    reasons.append(f"{line}: {'starts' if wrapped_above else 'stops'} wrapping above it")
        elif path.wraps:
            notes.append(f"{line}: wraps {', '.join(w.wrap_object for w in path.wraps)}; where it starts or stops "
                         "wrapping (a surface in the coordinates' space) a fibre's length bends sharply, which "
                         "the polynomial smooths (see motion_moment_arm_max_m)")
    return tuple(gates), tuple(reasons), tuple(notes)


def _wrap_switches(model, line, column, q_base, lo, hi, n_grid: int = 4001):
    """Values of model coordinate ``column`` in [lo, hi] (the others at ``q_base``) where path
    ``line`` starts or stops wrapping any of its wrap objects (its tangent points appear or
    vanish, `motion.wrapping.action_lines`), each with True when it is wrapped above it."""
    import motion as motion_pkg

    grid = np.linspace(lo, hi, n_grid)
    q = np.repeat(np.asarray(q_base, dtype=float)[None], n_grid, axis=0)
    q[:, column] = grid
    lines = motion_pkg.action_lines(model, q, muscles=[line])
    n_points = len(model.path(line).points)
    wrapped = np.asarray(lines.point_mask)[:, 0, n_points::2]          # (G, W): first tangent point
    out = []
    for w in range(wrapped.shape[1]):
        for i in np.flatnonzero(wrapped[1:, w] != wrapped[:-1, w]):
            out.append((0.5 * (grid[i] + grid[i + 1]), bool(wrapped[i + 1, w])))
    return out


def _evaluate_each(choice, d, q, gates=()):
    """Lengths (S, N) and moment arms (S, N, D) of fibres with their own orders."""
    n = len(choice.orders)
    lengths = np.empty((len(q), n))
    arms = np.empty((len(q), n, d))
    for order in np.unique(choice.orders):        # loop over the few distinct orders
        sel = np.flatnonzero(choice.orders == order)
        coef = np.array([choice.coefficients[k] for k in sel])
        lengths[:, sel], arms[:, sel] = path_fit.evaluate(coef, path_fit.monomial_exponents(d, int(order)), q, gates)
    return lengths, arms


def muscle_parameters(model, mspec, properties, rest_lengths) -> dict:
    """Per-fibre OpenSim muscle parameters (module docstring).

    Parameters
    ----------
    model : motion.Model
    mspec : MuscleSpec
        The fibre-model muscle (its action lines and rest pose).
    properties : dict action line -> dict
        The action lines' ``max_isometric_force``, ``optimal_fiber_length``,
        ``tendon_slack_length`` (floats; missing keys take OpenSim's defaults).
    rest_lengths : (N,) float

    Returns
    -------
    dict with ``max_isometric_force`` (float, per fibre), ``optimal_fiber_length`` and
    ``tendon_slack_length`` ((N,) float), ``line_rest_lengths`` (L,) float.
    """
    import motion as motion_pkg
    from motion.surface.rest import rest_pose

    from .muscle_chain import surface_spec

    q_rest = rest_pose(model, surface_spec(mspec)).q
    lines = motion_pkg.action_lines(model, np.asarray(q_rest, dtype=float)[None], muscles=list(mspec.action_lines))
    line_len = np.asarray(lines.lengths)[0]
    force = np.array([properties[n].get("max_isometric_force", 1000.0) for n in mspec.action_lines])
    l_opt = np.array([properties[n].get("optimal_fiber_length", 0.1) for n in mspec.action_lines])
    l_ts = np.array([properties[n].get("tendon_slack_length", 0.2) for n in mspec.action_lines])
    w = force / force.sum() if force.sum() > 0 else np.full(len(force), 1.0 / len(force))
    rest = np.asarray(rest_lengths, dtype=float)
    return {"max_isometric_force": float(force.sum() / len(rest)),
            "optimal_fiber_length": float(w @ (l_opt / line_len)) * rest,
            "tendon_slack_length": float(w @ (l_ts / line_len)) * rest,
            "line_rest_lengths": line_len}
