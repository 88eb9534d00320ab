"""Render the fibre decomposition of the four LHDL hip muscles: one PNG per muscle.

Usage::

    python bench/render_lhdl.py OUT_DIR [--fibres N] [--template NAME] [--clean]
                                        [--slicing harmonic|planes] [--resolution R]
                                        [--muscles a,b] [--psoas-origin own|iliacus]

Reads the original (defective) LHDL meshes from ``../shared/muscles/LHDL_hip_r/muscles/`` (or
``muscles_clean/`` with ``--clean``) and the attachment landmarks of
``attachments/attachment_landmarks.csv`` (millimetres), decomposes each muscle with
`fibres.decompose` and draws the surface (translucent), the fibres (tubes) and the landmarks
(origin blue, insertion red) and, with harmonic slicing, the attachment patches off screen with
pyvista, two views per muscle. Prints the timing of each decomposition. docs/gallery/ holds the
pictures of ``--clean`` (both slicings) and of ``--clean --muscles psoas_r --psoas-origin
iliacus`` (the psoas with the iliacus-area origin of ``tests/data/lhdl_hip.toml``, Modenese &
Kohout 2020's choice: the part above that patch is a dead end and gets no fibres).
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


def landmarks(muscle, origin_of=None):
    """Origin and insertion landmarks (K, 3) in mm of one LHDL muscle (gluteus maximus:
    insertion cloud 1; cloud 2 lies on the tibia, ~310 mm from the mesh); ``origin_of``: take
    the origin of that muscle instead."""
    import pandas as pd

    tab = pd.read_csv(LHDL / "attachments" / "attachment_landmarks.csv")
    sel = tab[tab.muscle == muscle]
    if muscle == "glut_max_r":
        sel = sel[(sel.type == "origin") | (sel.cloud == 1)]
    get = lambda kind: sel[sel.type == kind][["x_mm", "y_mm", "z_mm"]].to_numpy(float)  # noqa
    if origin_of is not None:
        mine = tab[(tab.muscle == origin_of) & (tab.type == "origin")]
        return mine[["x_mm", "y_mm", "z_mm"]].to_numpy(float), get("insertion")
    return get("origin"), get("insertion")


def render(muscle, bundle, surface, origin, insertion, path, *, size=(1200, 560)):
    """Two views (the muscle's broad side, and edge-on) of the translucent surface, the fibres
    (tubes coloured by fibre), the attachment patches (origin blue, insertion red; harmonic
    slicing) and the landmarks, with the fibre quality numbers."""
    import pyvista as pv

    pv.OFF_SCREEN = True
    faces = np.hstack([np.full((len(surface.faces), 1), 3), surface.faces]).ravel()
    mesh = pv.PolyData(np.asarray(surface.vertices), faces)
    n, p = bundle.points.shape[:2]
    lines = np.hstack([np.full((n, 1), p), np.arange(n * p).reshape(n, p)]).ravel()
    fib = pv.PolyData(bundle.points.reshape(-1, 3), lines=lines)
    fib.cell_data["fibre"] = np.arange(n)
    radius = 0.003 * surface.size
    pts = np.asarray(surface.vertices)
    d = pts - pts.mean(axis=0)
    _, vecs = np.linalg.eigh(d.T @ d)
    broad = vecs[:, 0] if vecs[1, 0] <= 0 else -vecs[:, 0]   # from behind (+y is posterior)
    plotter = pv.Plotter(off_screen=True, window_size=size, shape=(1, 2), border=False)
    q = bundle.quality
    name = bundle.template if isinstance(bundle.template, str) else bundle.template.name
    slicing = getattr(bundle.plan, "slicing", "planes")
    for col, view in enumerate((broad, vecs[:, 1])):
        plotter.subplot(0, col)
        plotter.add_mesh(mesh, color="tan", opacity=0.2)
        for attr, colour in (("origin_faces", "royalblue"), ("insertion_faces", "crimson")):
            mask = getattr(bundle.plan, attr, None)
            if mask is not None and np.any(mask):
                plotter.add_mesh(mesh.extract_cells(np.flatnonzero(mask)), color=colour,
                                 opacity=0.35)
        plotter.add_mesh(fib.tube(radius=radius), scalars="fibre", cmap="viridis",
                         show_scalar_bar=False)
        plotter.add_mesh(pv.PolyData(origin), color="blue", point_size=9,
                         render_points_as_spheres=True)
        plotter.add_mesh(pv.PolyData(insertion), color="red", point_size=9,
                         render_points_as_spheres=True)
        plotter.view_vector(view, viewup=(0, 0, 1))
        plotter.reset_camera(bounds=mesh.bounds)
        if col == 0:
            plotter.add_text(f"{muscle}: {n} fibres, {name}, {slicing} slicing", font_size=10)
        elif q is not None:
            plotter.add_text(f"empty >5 mm {q.empty_5mm:.1%}; turns p95 {q.turn_p95:.0f} deg;\n"
                             f"origin {q.origin_covered:.0%} / insertion "
                             f"{q.insertion_covered:.0%} covered", font_size=9)
    plotter.screenshot(str(path))
    plotter.close()


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out_dir", type=Path)
    parser.add_argument("--fibres", type=int, default=100)
    parser.add_argument("--template", default=None, help="same template for every muscle")
    parser.add_argument("--clean", action="store_true", help="use muscles_clean/")
    parser.add_argument("--slicing", default="harmonic", choices=("harmonic", "planes"))
    parser.add_argument("--resolution", type=int, default=15)
    parser.add_argument("--muscles", default=",".join(TEMPLATES), help="comma-separated")
    parser.add_argument("--psoas-origin", default="own", choices=("own", "iliacus"),
                        help="iliacus: the psoas with the iliacus-area origin of the TOML")
    args = parser.parse_args(argv)

    import fibres
    from fibres.finishing.containment import CONTAIN_SOFTNESS
    from fibres.mesh.surface_distance import surface_distance

    args.out_dir.mkdir(parents=True, exist_ok=True)
    folder = LHDL / ("muscles_clean" if args.clean else "muscles")
    for muscle in args.muscles.split(","):
        template = args.template or TEMPLATES[muscle]
        other = "iliacus_r" if muscle == "psoas_r" and args.psoas_origin == "iliacus" else None
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            surface = fibres.as_surface(folder / f"{muscle}.vtk", units="mm")
        for w in caught:
            print(f"  warning: {w.message}")
        o_mm, i_mm = landmarks(muscle, other)
        o, i = o_mm / 1000, i_mm / 1000
        t0 = time.perf_counter()
        bundle = fibres.decompose(surface, o, i, template=template, n_fibres=args.fibres,
                                  resolution=args.resolution, slicing=args.slicing)
        dt = time.perf_counter() - t0
        flags = {k: int(np.sum(v)) for k, v in bundle.flags.items()}
        s, _ = surface_distance(bundle.points, surface.vertices, surface.faces, reach=0.02,
                                softness=CONTAIN_SOFTNESS)
        print(f"{muscle}: {template}, {bundle.points.shape[0]} fibres in {dt * 1e3:.0f} ms; "
              f"flags {flags}; notes {len(bundle.notes)}; most outside "
              f"{max(np.nanmax(s), 0.0) * 1e3:.2f} mm")
        for note in bundle.notes[:5]:
            print(f"  note: {note}")
        name = muscle if other is None else f"{muscle}_{other.split('_')[0]}_origin"
        path = args.out_dir / f"{name}_{args.slicing}.png"
        render(muscle if other is None else f"{muscle} ({other} origin)", bundle, surface, o, i,
               path)
        print(f"  wrote {path}")


if __name__ == "__main__":
    main()
