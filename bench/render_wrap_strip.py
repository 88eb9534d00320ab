"""Render a strip of one LHDL hip muscle wrapped at several hip-flexion angles (pyvista, offscreen).

Usage: python bench/render_wrap_strip.py [--muscle iliacus_r] [--angles -10 25 60] [--out wrap_strip.png]

The LHDL data (Modenese & Kohout 2020; CC BY-NC-SA 2.0 BE, LHDL consortium) is read from
../shared/muscles/LHDL_hip_r relative to the repository; the PNG is not committed.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
LHDL = ROOT.parent / "shared" / "muscles" / "LHDL_hip_r"
LINES = {"iliacus_r": ["iliacus_r"], "psoas_r": ["psoas_r"],
         "glut_max_r": ["glut_max1_r", "glut_max2_r", "glut_max3_r"],
         "glut_med_r": ["glut_med1_r", "glut_med2_r", "glut_med3_r"]}


def _mesh(path):
    import pyvista as pv

    m = pv.read(str(path))
    return np.asarray(m.points, dtype=float) * 1e-3, m.faces.reshape(-1, 4)[:, 1:]


def main(argv=None):
    import pandas as pd
    import pyvista as pv

    from motion import BoneMesh, MuscleSurfaceSpec, SurfaceAttachment, wrap_surfaces
    from motion.osim.kinematics import motion_from_array
    from motion.osim.reader import load_model

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--muscle", default="iliacus_r", choices=sorted(LINES))
    ap.add_argument("--angles", type=float, nargs="+", default=[-10.0, 25.0, 60.0])
    ap.add_argument("--out", default="wrap_strip.png")
    ap.add_argument("--no-bones", action="store_true", help="no bone collision (faster)")
    args = ap.parse_args(argv)

    model = load_model(LHDL / "model" / "LHDL_hip_r.osim")
    q = np.tile([c.default_value for c in model.coordinates], (len(args.angles), 1))
    q[:, model.coordinate_index("hip_flexion_r")] = np.deg2rad(args.angles)
    motion = motion_from_array(model, q)
    lm = pd.read_csv(LHDL / "attachments" / "attachment_landmarks.csv")

    def pts(muscle, kind, cloud=None):
        sel = lm[(lm.muscle == muscle) & (lm.type == kind)]
        if cloud is not None:
            sel = sel[sel.cloud == cloud]
        return sel[["x_mm", "y_mm", "z_mm"]].to_numpy() * 1e-3

    bones = {"pelvis": _mesh(LHDL / "bones" / "iliac_r.vtk"), "femur_r": _mesh(LHDL / "bones" / "femur_r.vtk")}
    bone_specs = () if args.no_bones else tuple(BoneMesh(b, bv, bf) for b, (bv, bf) in bones.items())
    origin_of = "iliacus_r" if args.muscle == "psoas_r" else args.muscle
    v, f = _mesh(LHDL / "muscles_clean" / f"{args.muscle}.vtk")
    spec = MuscleSurfaceSpec(args.muscle, LINES[args.muscle], v, f, frame="bodies",
                             origin=SurfaceAttachment("pelvis", pts(origin_of, "origin")),
                             insertion=SurfaceAttachment("femur_r", pts(args.muscle, "insertion",
                                                                        1 if args.muscle == "glut_max_r" else None)),
                             bones=bone_specs)
    wrapped = wrap_surfaces(model, motion, [spec])[0]
    from motion.osim.kinematics import body_poses

    tf = np.asarray(body_poses(model, motion).tf_ground_body)
    plotter = pv.Plotter(off_screen=True, shape=(1, len(args.angles)), window_size=(600 * len(args.angles), 700))
    for k, angle in enumerate(args.angles):
        plotter.subplot(0, k)
        for body, (bv, bf) in bones.items():
            b = model.body_index(body)
            moved = bv @ tf[k, b, :3, :3].T + tf[k, b, :3, 3]
            plotter.add_mesh(pv.PolyData(moved, np.hstack([np.full((len(bf), 1), 3), bf]).ravel()),
                             color="ivory", opacity=0.35)
        surf = pv.PolyData(wrapped.vertices[k], np.hstack([np.full((len(wrapped.faces), 1), 3),
                                                           wrapped.faces]).ravel())
        plotter.add_mesh(surf, color="firebrick", smooth_shading=True)
        plotter.add_points(np.concatenate([wrapped.origin[k], wrapped.insertion[k]]), color="navy",
                           point_size=8, render_points_as_spheres=True)
        plotter.add_text(f"{args.muscle}  hip flexion {angle:g} deg\nvolume error "
                         f"{wrapped.volume_error[k] * 100:+.3f} %", font_size=10)
        # OpenSim ground: y up, x anterior, z to the right; look from anterior-medial
        centre = wrapped.vertices[k].mean(axis=0)
        plotter.camera.focal_point = centre
        plotter.camera.position = centre + 0.55 * np.array([1.0, 0.15, -0.45])
        plotter.camera.up = (0.0, 1.0, 0.0)
    plotter.screenshot(args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
