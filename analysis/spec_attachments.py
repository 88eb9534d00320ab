"""The ``origin`` / ``insertion`` tables of a fibre-model TOML (`analysis.spec`): attachment
points given inline or read from a landmark file (CSV with row selection, or a point cloud), in
the muscle's frame or in a body's own frame (as path points in the .osim), in m or mm; by
default the first or last point of the muscle's first action line.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from motion.surface.spec import SurfaceAttachment

__all__ = ["AttachmentSpec", "read_attachment", "UNITS", "is_unit"]

#: length units of a fibre model, metres per unit
UNITS = {"m": 1.0, "mm": 1e-3}
_ATTACH_KEYS = ("body", "frame", "points", "file", "where", "columns", "units")
#: the frames attachment points may be given in
_ATTACH_FRAMES = ("muscle", "body")


def is_unit(value) -> bool:
    """A known unit name (`UNITS`)."""
    return isinstance(value, str) and value in UNITS


@dataclass(frozen=True, eq=False)
class AttachmentSpec(SurfaceAttachment):
    """Attachment points of one muscle end as the fibre model gives them: a
    `motion.surface.spec.SurfaceAttachment` (``body``, ``points`` (K, 3) in metres,
    ``in_body_frame``) that also says where the points came from.

    Attributes
    ----------
    source : str
        The TOML key, landmark file or path point the points came from (for messages and
        run.json).
    """

    source: str = ""


def _path_end(path, end: str):
    """(body, location (3,)) of the first ("origin") or last ("insertion") point of a path."""
    pts = list(path.points)
    p = pts[0] if end == "origin" else pts[-1]
    return p.body, np.asarray(p.location, dtype=float)


def read_attachment(ctx, table, where, end, unit, bodies, path) -> AttachmentSpec:
    """The `AttachmentSpec` of one end from its TOML table (None: the path's end point);
    ``ctx`` reports problems (`analysis.spec`)."""
    default_body, default_loc = _path_end(path, end)
    if table is None:
        return AttachmentSpec(body=default_body, points=default_loc[None], in_body_frame=True,
                              source=f"{'first' if end == 'origin' else 'last'} path point of {path.name}")
    if not isinstance(table, dict):
        ctx.fail(where, "expected a table", f"Write {end} = {{ body = \"...\", points = [[x, y, z]] }}.")
    ctx.check_keys(table, _ATTACH_KEYS, where)
    body = table.get("body", default_body)
    if not isinstance(body, str) or body not in bodies:
        ctx.fail(f"{where}.body", f"'{body}' is not a body of the model", f"Use one of: {', '.join(bodies)}.")
    own = table.get("frame", "muscle")
    if own == body:
        own = "body"
    if own not in _ATTACH_FRAMES:
        ctx.fail(f"{where}.frame", f"unknown attachment frame {own!r}",
                 f"Use frame = \"body\" (points in the frame of body '{body}', as path points in the .osim) "
                 "or frame = \"muscle\" (the muscle's own frame, the default).")
    in_body = own == "body"
    if ("points" in table) == ("file" in table):
        ctx.fail(where, "needs exactly one of 'points' and 'file'",
                 "Give points = [[x, y, z], ...] or file = \"<landmarks>.csv\".")
    if "points" in table:
        for k in ("where", "columns"):
            if k in table:
                ctx.fail(f"{where}.{k}", "only allowed with 'file'", f"Remove {k} or use file = ...")
        try:
            pts = np.array(table["points"], dtype=float)
        except (TypeError, ValueError):
            pts = np.zeros((0,))
        if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0 or not np.isfinite(pts).all():
            ctx.fail(f"{where}.points", "expected a list of [x, y, z] triples of numbers",
                     "Write points = [[x, y, z], ...].")
        scale = UNITS.get(table.get("units", unit)) if is_unit(table.get("units", unit)) else None
        if scale is None:
            ctx.fail(f"{where}.units", f"unknown units {table['units']!r}", "Use \"m\" or \"mm\".")
        return AttachmentSpec(body=body, points=pts * scale, in_body_frame=in_body, source=f"{where}.points")
    file = ctx.file_path(table["file"], f"{where}.file", "landmark file")
    pts, scale = _read_points(ctx, file, table, where, unit)
    return AttachmentSpec(body=body, points=pts * scale, in_body_frame=in_body, source=str(file))


def _read_points(ctx, file, table, where, unit):
    """(K, 3) points and metres-per-unit from a CSV (with row selection) or a point-cloud file."""
    if "units" in table and not is_unit(table["units"]):
        ctx.fail(f"{where}.units", f"unknown units {table['units']!r}", "Use \"m\" or \"mm\".")
    if file.suffix.lower() not in (".csv", ".txt"):
        for k in ("where", "columns"):
            if k in table:
                ctx.fail(f"{where}.{k}", "only allowed with a CSV file", f"Remove {k}.")
        from fibres.errors import InputError as MeshError
        from fibres.mesh.surface import read_mesh

        try:
            pts, _ = read_mesh(file)
        except MeshError as exc:   # untrusted file: read without VTK (fibres.mesh.vtk_reader)
            ctx.fail(f"{where}.file", f"cannot read the point cloud {file.name} ({exc.problem})",
                     "Give a CSV with x,y,z columns or a VTK/VTP/PLY point cloud.")
        if pts.ndim != 2 or len(pts) == 0:
            ctx.fail(f"{where}.file", f"no points in {file.name}", "Give a file with at least one point.")
        return pts, UNITS[table.get("units", unit)]
    import pandas as pd

    try:
        df = pd.read_csv(file)
    except Exception as exc:  # noqa: BLE001 - malformed CSV is bad input
        ctx.fail(f"{where}.file", f"cannot read the CSV {file.name} ({exc})", "Give a CSV with a header row.")
    df.columns = [str(c).strip() for c in df.columns]
    cols = table.get("columns")
    col_units = None
    if cols is not None:
        if not (isinstance(cols, list) and len(cols) == 3 and all(isinstance(c, str) for c in cols)):
            ctx.fail(f"{where}.columns", "expected three column names", "Write columns = [\"x\", \"y\", \"z\"].")
    else:
        for cand, u in ((["x", "y", "z"], None), (["x_mm", "y_mm", "z_mm"], "mm"), (["x_m", "y_m", "z_m"], "m")):
            if all(c in df.columns for c in cand):
                cols, col_units = cand, u
                break
        else:
            # a header-less CSV of three numbers per row
            try:
                raw = np.loadtxt(file, delimiter=",", ndmin=2)
            except ValueError:
                raw = None
            if raw is None or raw.shape[1] != 3 or "where" in table:
                ctx.fail(f"{where}.file", f"{file.name} has no x,y,z columns (found {', '.join(df.columns)})",
                         "Name them with columns = [\"...\", \"...\", \"...\"].")
            return raw, UNITS[table.get("units", unit)]
    missing = [c for c in cols if c not in df.columns]
    if missing:
        ctx.fail(f"{where}.columns", f"{file.name} has no column {missing[0]!r}",
                 f"Columns are: {', '.join(df.columns)}.")
    sel = table.get("where", {})
    if not isinstance(sel, dict):
        ctx.fail(f"{where}.where", "expected a table", "Write where = { column = value }.")
    mask = np.ones(len(df), dtype=bool)
    for col, want in sel.items():
        if col not in df.columns:
            ctx.fail(f"{where}.where.{col}", f"{file.name} has no column {col!r}",
                     f"Columns are: {', '.join(df.columns)}.")
        wants = want if isinstance(want, list) else [want]
        series = df[col]
        hit = np.zeros(len(df), dtype=bool)
        for w in wants:
            if isinstance(w, (int, float)) and not isinstance(w, bool):
                hit |= (pd.to_numeric(series, errors="coerce") == w).to_numpy()
            else:
                hit |= (series.astype(str).str.strip() == str(w)).to_numpy()
        mask &= hit
        if not mask.any():
            have = sorted(set(series.astype(str)))[:12]
            ctx.fail(f"{where}.where.{col}", f"no row of {file.name} matches {col} = {want!r}"
                     " (with the conditions before it)", f"Values in that column: {', '.join(have)}.")
    try:
        pts = df.loc[mask, cols].to_numpy(dtype=float)
    except ValueError:
        ctx.fail(f"{where}.file", f"non-numeric values in columns {', '.join(cols)} of {file.name}",
                 "Fix the file.")
    if len(pts) == 0 or not np.isfinite(pts).all():
        ctx.fail(f"{where}.file", f"no usable points in {file.name}", "Give at least one finite x,y,z row.")
    return pts, UNITS[table.get("units", col_units or unit)]
