"""``fibres decompose MESH --origin POINTS --insertion POINTS``: one static surface to fibres.

The method is Kohout et al. (GRAPP 2012) as implemented by `fibres.decompose`. Inputs, as
INTERFACE.md says:

- ``MESH``: a closed triangle surface (STL, OBJ, PLY, OFF, GLB, glTF, legacy VTK, VTP, VTU). Safe repairs
  (duplicate vertices, zero-area or duplicate faces, stray pieces) are reported as one warning
  line on stderr; open surfaces, point clouds and NaN coordinates are refused.
- ``POINTS`` (``--origin``, ``--insertion``): a CSV with columns x,y,z (header row optional),
  a point-cloud mesh file, or ``"x,y,z;x,y,z"``.
- ``--units m|mm`` applies to the mesh and both point sets; outputs are in metres.

Output (``--out``, default ``<MESH stem>_fibres.vtp`` in the current folder), written to a
temporary name and renamed, so a failed run leaves no file:

- ``.vtp``: one polyline cell per fibre in fibre order, cell data ``fibre`` (its id);
- ``.csv``: columns fibre, point, x, y, z;
- ``.npz``: ``points`` (N, R+1, 3), ``fibre`` (N,), ``rs`` (N, 2), ``trimmed``,
  ``reconstructed`` (N,) and ``template`` (name).
"""
from __future__ import annotations

import argparse
import os
import sys
import warnings
from pathlib import Path

import numpy as np

from .errors import InputError
from .output_files import atomic_path, write_csv

__all__ = ["add_arguments", "execute", "write_fibres", "OUT_SUFFIXES"]

OUT_SUFFIXES = (".vtp", ".csv", ".npz")


def _int_at_least(minimum: int, what: str):
    """An argparse type: an integer >= ``minimum`` (``what`` names it in the message)."""
    def parse(text):
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < minimum:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
        return value

    return parse


_positive_int = _int_at_least(1, "a positive integer")
_non_negative_int = _int_at_least(0, "an integer >= 0")


def add_arguments(parser) -> None:
    """Arguments of ``fibres decompose``."""
    parser.add_argument("mesh", metavar="MESH",
                        help="closed muscle surface (STL, OBJ, PLY, OFF, GLB, glTF, VTK, VTP, VTU)")
    parser.add_argument("--origin", required=True, metavar="POINTS",
                        help="origin landmarks: CSV with x,y,z columns, a point-cloud mesh "
                             "file, or 'x,y,z;x,y,z'")
    parser.add_argument("--insertion", required=True, metavar="POINTS",
                        help="insertion landmarks (same forms as --origin)")
    parser.add_argument("--template", default="parallel", metavar="NAME",
                        help="fibre template: parallel (default), pennate, bipennate, curved, "
                             "fanned, rectus")
    parser.add_argument("--slicing", choices=("harmonic", "planes"), default="harmonic",
                        help="cross-sections: isolines of a harmonic field between the attachment "
                             "patches (default) or parallel planes (Kohout 2012)")
    parser.add_argument("--fibres", type=_positive_int, default=100, metavar="N",
                        help="number of fibres (default 100)")
    parser.add_argument("--resolution", type=_positive_int, default=19, metavar="R",
                        help="segments per fibre, R+1 points (default 19)")
    parser.add_argument("--seed", type=_non_negative_int, default=0, metavar="S",
                        help="Sobol scrambling seed (default 0)")
    parser.add_argument("--units", choices=("m", "mm"), default="m",
                        help="units of the mesh and the landmarks (default m)")
    parser.add_argument("--out", default=None, metavar="FILE",
                        help="output .vtp, .csv or .npz (default: <MESH stem>_fibres.vtp)")


def _check_out(out: Path) -> None:
    if out.suffix.lower() not in OUT_SUFFIXES:
        raise InputError(f"unsupported output type {out.suffix or '(none)'!r}", file=out,
                         where="--out", fix="Use a file name ending in .vtp, .csv or .npz.")
    if out.is_dir():
        raise InputError("the output is a folder", file=out, where="--out",
                         fix="Give a file name ending in .vtp, .csv or .npz.")
    parent = out.absolute().parent
    if not parent.is_dir():
        raise InputError("the output folder does not exist", file=out, where="--out",
                         fix="Create the folder first or choose another --out.")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError("the output folder is not writable", file=out, where="--out",
                         fix="Choose a folder you can write to with --out.")


def _write_vtp(path, points, fibre_ids):
    import pyvista as pv
    from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter

    n, p = points.shape[:2]
    conn = np.arange(n * p).reshape(n, p)
    lines = np.hstack([np.full((n, 1), p), conn]).ravel()
    poly = pv.PolyData(points.reshape(-1, 3), lines=lines)
    poly.cell_data["fibre"] = np.asarray(fibre_ids, dtype=np.int64)
    with atomic_path(path) as tmp:
        writer = vtkXMLPolyDataWriter()
        writer.SetFileName(str(tmp))
        writer.SetInputData(poly)
        writer.SetDataModeToBinary()
        if not writer.Write():
            raise OSError(f"VTK could not write {path}")


def write_fibres(path, bundle) -> Path:
    """Write a `fibres.FibreBundle` as .vtp, .csv or .npz (by suffix), atomically.

    Parameters
    ----------
    path : str or os.PathLike
    bundle : fibres.FibreBundle
        Uses ``points`` (N, P, 3), ``rs`` (N, 2), ``flags`` and ``template``.
    """
    path = Path(path)
    pts = np.asarray(bundle.points, dtype=np.float64)
    n, p = pts.shape[:2]
    ids = np.arange(n)
    suffix = path.suffix.lower()
    if suffix == ".csv":
        import pandas as pd

        frame = pd.DataFrame({"fibre": np.repeat(ids, p), "point": np.tile(np.arange(p), n),
                              "x": pts[..., 0].ravel(), "y": pts[..., 1].ravel(),
                              "z": pts[..., 2].ravel()})
        write_csv(frame, path)
    elif suffix == ".npz":
        flags = dict(getattr(bundle, "flags", {}) or {})
        template = getattr(bundle, "template", "")
        name = getattr(template, "name", template)
        extra = {k: np.asarray(v) for k, v in flags.items()}
        with atomic_path(path) as tmp, open(tmp, "wb") as fh:
            np.savez(fh, points=pts, fibre=ids, rs=np.asarray(bundle.rs),
                     template=np.asarray(str(name)), **extra)
    elif suffix == ".vtp":
        _write_vtp(path, pts, ids)
    else:
        raise InputError(f"unsupported output type {suffix!r}", file=path, where="--out",
                         fix="Use .vtp, .csv or .npz.")
    return path


def execute(args) -> int:
    """Run ``fibres decompose``; returns the exit status (errors are raised as InputError)."""
    import fibres
    from fibres.decompose import decompose
    from fibres.fit.fitting import check_landmarks
    from fibres.mesh.surface import SurfaceRepairWarning, as_points, check_muscle_scale

    from .spec import check_count

    for key in ("fibres", "resolution", "seed"):
        check_count(key, getattr(args, key), where=f"--{key}")
    mesh = Path(args.mesh)
    out = Path(args.out) if args.out else Path(f"{mesh.stem}_fibres.vtp")
    _check_out(out)
    if args.template not in fibres.TEMPLATES:
        fibres.get_template(args.template)  # raises the InputError listing the names
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", SurfaceRepairWarning)
        surface = fibres.as_surface(mesh, units=args.units)
    for w in caught:
        if issubclass(w.category, SurfaceRepairWarning):
            print(f"fibres decompose: warning: {w.message}", file=sys.stderr)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    check_muscle_scale(surface, file=mesh)
    origin = as_points(args.origin, units=args.units, name="origin")
    insertion = as_points(args.insertion, units=args.units, name="insertion")
    check_landmarks(surface.vertices, origin, name="origin", file=_label(args.origin))
    check_landmarks(surface.vertices, insertion, name="insertion", file=_label(args.insertion))
    bundle = decompose(surface, origin, insertion, template=args.template,
                       n_fibres=args.fibres, resolution=args.resolution, seed=args.seed,
                       slicing=args.slicing)
    write_fibres(out, bundle)
    n, p = np.shape(bundle.points)[:2]
    print(f"wrote {n} fibres of {p} points to {out} (coordinates in metres"
          f"{', converted from mm' if args.units == 'mm' else ''})")
    q = bundle.quality
    print(f"fibre quality: {q.empty_5mm:.1%} of the volume farther than 5 mm from a fibre, "
          f"sharpest turns max {q.turn_max:.0f} / p95 {q.turn_p95:.0f} degrees, "
          f"{q.origin_covered:.0%} of the origin and {q.insertion_covered:.0%} of the insertion "
          f"area within 5 mm of a fibre end, {q.outside} points outside")
    for problem in q.problems():
        print(f"fibres decompose: warning: fibre quality: {problem}", file=sys.stderr)
    # what the decomposition noted (far landmarks, patch pieces, several isoline loops, a dead
    # end beyond a patch); the repairs were printed above
    for note in bundle.notes:
        if not note.startswith("surface repaired: "):
            print(f"fibres decompose: note: {note}", file=sys.stderr)
    return 0


def _label(points_arg):
    """The file name of a POINTS argument (for messages), or None for inline points."""
    return points_arg if points_arg and Path(points_arg).suffix else None
