"""``fibres render [DIR] [--frame K] [--view iso|front|back|side|top] [--out FILE.png]
[--size WxH] [--no-bones] [--no-surfaces]``: an off-screen picture of a run's 3D scene.

Reads ``DIR/scene/scene.pvd`` (written by ``fibres run``; `analysis.scene`) with
``pyvista.PVDReader`` and draws, off screen, the frame whose index in the run is ``K`` (default:
the middle frame written): bones light grey, wrapped muscle surfaces translucent, action lines
black, fibres coloured by muscle. Views use OpenSim's axes (x forward, y up, z to the right):
``front`` looks from +x, ``back`` from -x, ``side`` from +z (the right side), ``top`` from +y,
``iso`` from (1, 0.6, 1). Writes ``FILE.png`` (default ``DIR/render_<frame>_<view>.png``).
"""
from __future__ import annotations

import contextlib
import json
import sys
from pathlib import Path

from .errors import InputError

__all__ = ["add_arguments", "execute", "render_scene", "VIEWS"]

#: view name -> (camera direction from the focal point, view-up)
VIEWS = {"iso": ((1.0, 0.6, 1.0), (0, 1, 0)), "front": ((1, 0, 0), (0, 1, 0)), "back": ((-1, 0, 0), (0, 1, 0)),
         "side": ((0, 0, 1), (0, 1, 0)), "top": ((0, 1, 0), (1, 0, 0))}
_MUSCLE_COLOURS = ("#d62728", "#1f77b4", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf")


def add_arguments(parser) -> None:
    parser.add_argument("dir", nargs="?", default="fibres-out", metavar="DIR",
                        help="output folder of fibres run (default fibres-out)")
    parser.add_argument("--frame", type=int, default=None, metavar="K",
                        help="frame of the run to draw (default: the middle frame of the scene)")
    parser.add_argument("--view", choices=tuple(VIEWS), default="iso", help="camera direction (default iso)")
    parser.add_argument("--out", default=None, metavar="FILE.png",
                        help="picture to write (default DIR/render_<frame>_<view>.png)")
    parser.add_argument("--size", default="1200x900", metavar="WxH", help="picture size in pixels (default 1200x900)")
    parser.add_argument("--no-bones", action="store_true", help="leave the bones out")
    parser.add_argument("--no-surfaces", action="store_true", help="leave the muscle surfaces out")


def _size(text):
    try:
        w, h = (int(v) for v in str(text).lower().split("x"))
        if w < 16 or h < 16 or w > 8000 or h > 8000:
            raise ValueError
        return w, h
    except ValueError:
        raise InputError(f"--size {text!r} is not WIDTHxHEIGHT", where="--size",
                         fix="Give e.g. --size 1200x900 (16..8000 pixels each).") from None


def render_scene(scene_dir, out_png, *, frame=None, view="iso", size=(1200, 900), bones=True,
                 surfaces=True) -> Path:
    """Draw one frame of a scene folder (`analysis.scene`) to a PNG, off screen; returns its path."""
    import pyvista as pv

    scene_dir = Path(scene_dir)
    pvd = scene_dir / "scene.pvd"
    if not pvd.is_file():
        raise InputError("no scene.pvd in the folder", file=scene_dir, where="scene/",
                         fix="Run fibres run without --no-scene first (it writes DIR/scene/).")
    names = json.loads((scene_dir / "names.json").read_text())
    frames = names["frames"]
    k = frames[len(frames) // 2] if frame is None else int(frame)
    if k not in frames:
        raise InputError(f"frame {k} is not in the scene", file=pvd, where="--frame",
                         fix=f"Use one of the frames written: {frames[0]}..{frames[-1]} "
                             f"(every {frames[1] - frames[0] if len(frames) > 1 else 1}).")
    parts = {p: pv.read(str(scene_dir / f"{p}_{k:04d}.vtp")) for p in names["parts"]}
    pv.OFF_SCREEN = True
    with _vtk_errors_only():      # without a display VTK logs a coloured "bad X server" WARN line
        return _draw(parts, names, frames, k, out_png, view=view, size=size, bones=bones, surfaces=surfaces)


@contextlib.contextmanager
def _vtk_errors_only():
    """VTK's log on stderr limited to errors while drawing (its previous cutoff restored)."""
    from vtkmodules.vtkCommonCore import vtkLogger

    previous = vtkLogger.GetCurrentVerbosityCutoff()
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    try:
        yield
    finally:
        vtkLogger.SetStderrVerbosity(vtkLogger.ConvertToVerbosity(previous))


def _draw(parts, names, frames, k, out_png, *, view, size, bones, surfaces) -> Path:
    import numpy as np
    import pyvista as pv

    plotter = pv.Plotter(off_screen=True, window_size=list(size))
    plotter.set_background("white")
    if bones and parts["bones"].n_points:
        plotter.add_mesh(parts["bones"], color="#e8e2d0", smooth_shading=True)
    surf = parts["surfaces"]
    if surfaces and surf.n_points:
        for m in np.unique(surf.cell_data["muscle"]):
            piece = surf.extract_cells(np.flatnonzero(surf.cell_data["muscle"] == m))
            plotter.add_mesh(piece, color=_MUSCLE_COLOURS[int(m) % len(_MUSCLE_COLOURS)], opacity=0.25)
    lines = parts["lines"]
    if lines.n_points:
        plotter.add_mesh(lines, color="black", line_width=3)
    fib = parts["fibres"]
    if fib.n_points:
        for m in np.unique(fib.cell_data["muscle"]):
            piece = fib.extract_cells(np.flatnonzero(fib.cell_data["muscle"] == m))
            plotter.add_mesh(piece, color=_MUSCLE_COLOURS[int(m) % len(_MUSCLE_COLOURS)], line_width=1.5)
        # the muscles' names in their colours under the title (VTK's legend box clips long names
        # at the window's right edge)
        for i, m in enumerate(np.unique(fib.cell_data["muscle"])):
            plotter.add_text(f"— {names['muscles'][int(m)]}", position=(8, size[1] - 48 - 22 * i), font_size=9,
                             color=_MUSCLE_COLOURS[int(m) % len(_MUSCLE_COLOURS)])
    direction, up = VIEWS[view]
    plotter.view_vector(direction, viewup=up)
    plotter.reset_camera()
    t = names["times"][frames.index(k)]
    plotter.add_text(f"frame {k}, t = {t:.3g} s, view {view}", font_size=10, color="black")
    out_png = Path(out_png)
    from .output_files import atomic_path

    with atomic_path(out_png) as tmp:
        plotter.screenshot(str(tmp) + ".png")
        Path(str(tmp) + ".png").replace(tmp)
    plotter.close()
    return out_png


def execute(args) -> int:
    out_dir = Path(args.dir)
    if not out_dir.is_dir():
        raise InputError("no such output folder", file=out_dir, where="DIR",
                         fix="Give the --out folder of a fibres run.")
    size = _size(args.size)
    frame = args.frame
    png = Path(args.out) if args.out else None
    if png is None:
        names = json.loads((out_dir / "scene" / "names.json").read_text()) if (out_dir / "scene" / "names.json").is_file() else None
        k = frame if frame is not None else (names["frames"][len(names["frames"]) // 2] if names else 0)
        png = out_dir / f"render_{int(k):04d}_{args.view}.png"
    if png.suffix.lower() != ".png":
        raise InputError("the picture must be a .png file", file=png, where="--out", fix="Give a name ending in .png.")
    path = render_scene(out_dir / "scene", png, frame=frame, view=args.view, size=size, bones=not args.no_bones,
                        surfaces=not args.no_surfaces)
    print(f"fibres render: wrote {path}", file=sys.stderr)
    return 0
