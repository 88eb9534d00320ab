"""Render the fibre decomposition of the four LHDL hip muscles: one PNG per muscle.

Usage::

    python bench/render_lhdl.py OUT_DIR [--fibres N] [--template NAME] [--clean]

Reads the original (defective) LHDL meshes from ``../shared/muscles/LHDL_hip_r/muscles/`` (or
``muscles_clean/`` with ``--clean``) and the attachment landmarks of
``attachments/attachment_landmarks.csv`` (millimetres), decomposes each muscle with
`fibres.decompose` and draws the surface (translucent), the fibres (tubes) and the landmarks
(origin blue, insertion red) off screen with pyvista. Prints the timing of each decomposition.
Outputs are not committed.
"""
from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
LHDL = ROOT.parent / "shared" / "muscles" / "LHDL_hip_r"

#: template per muscle: fan-shaped gluteus medius and iliacus (Blemker & Delp 2005 modelled
#: both as fanned), long parallel-fibred psoas and gluteus maximus
TEMPLATES = {"glut_max_r": "parallel", "glut_med_r": "fanned", "iliacus_r": "fanned",
             "psoas_r": "parallel"}


def landmarks(muscle):
    """Origin and insertion landmarks (K, 3) in mm of one LHDL muscle (all clouds)."""
    import pandas as pd

    tab = pd.read_csv(LHDL / "attachments" / "attachment_landmarks.csv")
    sel = tab[tab.muscle == muscle]
    get = lambda kind: sel[sel.type == kind][["x_mm", "y_mm", "z_mm"]].to_numpy(float)  # noqa
    return get("origin"), get("insertion")


def render(muscle, bundle, surface, origin, insertion, path):
    import pyvista as pv

    pv.OFF_SCREEN = True
    faces = np.hstack([np.full((len(surface.faces), 1), 3), surface.faces]).ravel()
    mesh = pv.PolyData(np.asarray(surface.vertices), faces)
    n, p = bundle.points.shape[:2]
    lines = np.hstack([np.full((n, 1), p), np.arange(n * p).reshape(n, p)]).ravel()
    fib = pv.PolyData(bundle.points.reshape(-1, 3), lines=lines)
    fib.cell_data["fibre"] = np.arange(n)
    radius = 0.004 * surface.size
    plotter = pv.Plotter(off_screen=True, window_size=(1000, 1000))
    plotter.add_mesh(mesh, color="tan", opacity=0.25)
    plotter.add_mesh(fib.tube(radius=radius), scalars="fibre", cmap="viridis",
                     show_scalar_bar=False)
    plotter.add_mesh(pv.PolyData(origin), color="blue", point_size=12,
                     render_points_as_spheres=True)
    plotter.add_mesh(pv.PolyData(insertion), color="red", point_size=12,
                     render_points_as_spheres=True)
    plotter.add_text(f"{muscle}: {n} fibres ({bundle.template if isinstance(bundle.template, str) else bundle.template.name})",
                     font_size=12)
    # look at the muscle's broad side: along its direction of least spread, framed on the
    # muscle (landmarks far off it, e.g. gluteus maximus insertion 2 on the tibia, may be cut)
    pts = np.asarray(surface.vertices)
    d = pts - pts.mean(axis=0)
    _, vecs = np.linalg.eigh(d.T @ d)
    view = vecs[:, 0] if vecs[1, 0] <= 0 else -vecs[:, 0]   # from behind (+y is posterior)
    plotter.view_vector(view, viewup=(0, 0, 1))
    plotter.reset_camera(bounds=mesh.bounds)
    plotter.screenshot(str(path))
    plotter.close()


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out_dir", type=Path)
    parser.add_argument("--fibres", type=int, default=100)
    parser.add_argument("--template", default=None, help="same template for every muscle")
    parser.add_argument("--clean", action="store_true", help="use muscles_clean/")
    args = parser.parse_args(argv)

    import fibres
    from fibres.containment import CONTAIN_SOFTNESS
    from fibres.surface_distance import surface_distance

    args.out_dir.mkdir(parents=True, exist_ok=True)
    folder = LHDL / ("muscles_clean" if args.clean else "muscles")
    for muscle, default_template in TEMPLATES.items():
        template = args.template or default_template
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            surface = fibres.as_surface(folder / f"{muscle}.vtk", units="mm")
        for w in caught:
            print(f"  warning: {w.message}")
        o_mm, i_mm = landmarks(muscle)
        o, i = o_mm / 1000, i_mm / 1000
        t0 = time.perf_counter()
        bundle = fibres.decompose(surface, o, i, template=template, n_fibres=args.fibres)
        dt = time.perf_counter() - t0
        flags = {k: int(np.sum(v)) for k, v in bundle.flags.items()}
        s, _ = surface_distance(bundle.points, surface.vertices, surface.faces, reach=0.02,
                                softness=CONTAIN_SOFTNESS)
        print(f"{muscle}: {template}, {bundle.points.shape[0]} fibres in {dt * 1e3:.0f} ms; "
              f"flags {flags}; notes {len(bundle.notes)}; most outside "
              f"{max(np.nanmax(s), 0.0) * 1e3:.2f} mm")
        for note in bundle.notes[:5]:
            print(f"  note: {note}")
        path = args.out_dir / f"{muscle}.png"
        render(muscle, bundle, surface, o, i, path)
        print(f"  wrote {path}")


if __name__ == "__main__":
    main()
