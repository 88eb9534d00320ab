"""The two tasks of ``fibres study``, as they run in a worker process (Dask or a local pool).

- `rest_bundle(spec, options, muscle)`: the rest-pose work of one subject's muscle, done once
  and shared by all of that subject's trials: the surface at its rest pose and its fibre
  decomposition (`fibres.decompose`: patches, harmonic field, sections, the decomposition plan),
  returned as ``(key, FibreBundle)``.
- `run_trial(trial, out, *bundles)`: ``fibres run`` of one trial (`analysis.cli_run.execute`,
  so its folder holds exactly what ``fibres run`` writes, staged and moved into place), with the
  subject's rest bundles handed to the run (`shared_rest_bundles`) and its plots drawn in the
  worker itself (`_plots_in_this_process`). Never raises for a failing trial: it returns
  ``{"status": "failed", "error": <one line>}``, so that one trial's failure cannot stop the
  others; only Ctrl-C and the worker's own death end it otherwise.

How a rest bundle reaches the run without changing `analysis.run`: within `run_trial`,
``fibres.decompose`` (which `analysis.muscle_chain.run_muscle` imports at call time) is wrapped
by a function that returns the shared bundle when the call is a rest-pose decomposition with *exactly* the inputs
the bundle was made from: the key is the sha256 of the vertices, faces, origin and insertion
points (float64/int64 bytes) and the options. Anything else (a different surface, a plan given,
a changed option) goes to ``fibres.decompose`` itself. A bundle is therefore used only where the
run would have computed the same bundle (`fibres.decompose` is deterministic), so trial results
equal those of a single ``fibres run`` bit for bit; `SHARED` counts the calls served.
"""
from __future__ import annotations

import contextlib
import hashlib
import io
import time as _time
import warnings

import numpy as np

__all__ = ["rest_bundle", "run_trial", "shared_rest_bundles", "rest_key", "SHARED"]

#: rest-pose decompositions served from a shared bundle in this process (``hits``) and computed
#: by the run itself (``misses``)
SHARED = {"hits": 0, "misses": 0}


def rest_key(surface, origin, insertion, opts) -> str | None:
    """sha256 of a rest-pose decomposition's inputs, or None if they are not plain arrays."""
    if not (isinstance(surface, tuple) and len(surface) == 2) or opts.get("plan") is not None:
        return None
    h = hashlib.sha256()
    try:
        for arr, dtype in ((surface[0], np.float64), (surface[1], np.int64), (origin, np.float64),
                           (insertion, np.float64)):
            a = np.ascontiguousarray(np.asarray(arr, dtype=dtype))
            h.update(repr(a.shape).encode())
            h.update(a.tobytes())
    except (TypeError, ValueError):
        return None
    items = sorted((k, dict(sorted(v.items())) if isinstance(v, dict) else v) for k, v in opts.items())
    h.update(repr(items).encode())
    return h.hexdigest()


@contextlib.contextmanager
def shared_rest_bundles(bundles):
    """Within the block, ``fibres.decompose`` returns the bundle of ``bundles`` (key -> bundle)
    whose key matches its inputs (module docstring)."""
    import fibres

    table = {k: b for k, b in (bundles or {}).items() if b is not None}
    original = fibres.decompose

    def decompose(surface, origin, insertion, **opts):
        key = rest_key(surface, origin, insertion, opts) if table else None
        if key is not None and key in table:
            SHARED["hits"] += 1
            return table[key]
        SHARED["misses"] += 1
        return original(surface, origin, insertion, **opts)

    decompose.__doc__ = original.__doc__
    fibres.decompose = decompose
    try:
        yield
    finally:
        fibres.decompose = original


def _decompose_options(mspec) -> dict:
    """The options `analysis.muscle_chain.run_muscle` decomposes a muscle with (a changed rule
    there only loses the sharing: the keys then differ)."""
    opts = dict(template=mspec.template, n_fibres=mspec.n_fibres, resolution=mspec.resolution,
                seed=mspec.seed, slicing=mspec.slicing)
    if mspec.template_params:
        opts["template_params"] = dict(mspec.template_params)
    return opts


def rest_bundle(spec_path, options: dict, muscle: str):
    """``(key, FibreBundle)`` of one muscle's rest-pose decomposition with the study's options,
    or ``(None, None)`` when it cannot be made (the trials then report the problem themselves).

    The rest surface is the one `analysis.run` decomposes (`analysis.muscle_chain.run_muscle`):
    `motion.wrap_surfaces` of the muscle at one pose (the model's defaults: ``rest_vertices``
    do not depend on the pose), in ground."""
    try:
        import fibres
        import motion as motion_pkg
        from motion import wrap_surfaces

        from .muscle_chain import surface_spec
        from .run import _select_muscles
        from .spec import load_spec

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            spec = load_spec(spec_path)
            (mspec,) = _select_muscles(spec, [muscle], fibres=options.get("fibres"),
                                       resolution=options.get("resolution"),
                                       template=options.get("template"), slicing=options.get("slicing"))
            model = spec.model
            pose = motion_pkg.Motion.from_array(model, np.zeros(1), {})
            (rest,) = wrap_surfaces(model, pose, [surface_spec(mspec)])
            opts = _decompose_options(mspec)
            surface = (rest.rest_vertices, rest.faces)
            bundle = fibres.decompose(surface, rest.rest_origin, rest.rest_insertion, **opts)
            _ = bundle.quality          # computed once here, shipped with the bundle
            return rest_key(surface, rest.rest_origin, rest.rest_insertion, opts), bundle
    except Exception:   # noqa: BLE001 - the trial runs without it and reports the error
        return None, None


@contextlib.contextmanager
def _plots_in_this_process():
    """Within the block, `fibres run` draws its plots in this process (its own pool of plot
    processes is for a run alone on a machine): a study already keeps every core busy with
    trials, and a Dask worker is a daemonic process, which may not start processes. A context
    variable (`cli_run.PLOTS_IN_THIS_PROCESS`), so that trials in parallel threads of one
    worker do not undo each other's setting."""
    from . import cli_run

    token = cli_run.PLOTS_IN_THIS_PROCESS.set(True)
    try:
        yield
    finally:
        cli_run.PLOTS_IN_THIS_PROCESS.reset(token)


def _muscle_names(spec_path, options) -> list:
    """The muscles a trial runs (``muscle`` option or every muscle of the fibre model)."""
    from .spec import load_spec

    return list(options.get("muscle") or load_spec(spec_path).muscle_names)


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def run_trial(trial, out_dir, *bundles) -> dict:
    """Run one trial (module docstring); returns ``{"subject", "trial", "status", "kind", "error",
    "warnings", "seconds", "shared"}``: status ``"ok"`` or ``"failed"``, kind (of a failure)
    ``"input"`` (bad input: one line naming the file, element and fix) or ``"internal"``."""
    from .cli import _input_error_types
    from .cli_run import execute
    from .study_file import run_arguments

    t0 = _time.perf_counter()
    hits0 = SHARED["hits"]
    status, kind, error, printed = "ok", None, None, io.StringIO()
    caught = []
    try:
        args = run_arguments(trial, out_dir)
        with warnings.catch_warnings(record=True) as caught, contextlib.redirect_stderr(printed), \
                shared_rest_bundles(dict(b for b in bundles if b and b[0])), _plots_in_this_process():
            warnings.simplefilter("always")
            execute(args)
    except _input_error_types() as exc:
        status, kind, error = "failed", "input", _one_line(exc)
    except Exception as exc:   # noqa: BLE001 - an internal failure of this trial only
        status, kind, error = "failed", "internal", _one_line(f"internal error: {type(exc).__name__}: {exc}")
    lines = [ln.strip() for ln in printed.getvalue().splitlines() if ln.strip()]
    lines += [_one_line(w.message) for w in caught]
    return {"subject": trial.subject, "trial": trial.trial, "status": status, "kind": kind,
            "error": error, "warnings": list(dict.fromkeys(lines)), "seconds": _time.perf_counter() - t0,
            "shared": SHARED["hits"] - hits0}
