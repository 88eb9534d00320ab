"""models/make_cylinders.py: analytic validation models, checked against OpenSim 4.6."""
from __future__ import annotations

import importlib.util
import math
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


def _load(name):
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, ROOT / "models" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


mc = _load("make_cylinders")
A, B, D, RHO, R = 0.12, 0.10, 0.015, 0.008, 0.02


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    out = tmp_path_factory.mktemp("cyl")
    return (mc.make_straight(out / "straight", a=A, b=B, d=D, rho=RHO),
            mc.make_pulley(out / "pulley", a=A, b=B, radius=R, rho=RHO))


def test_moment_arm_formula_is_minus_dl_dq():
    q = np.linspace(-1.0, 2.5, 50)
    h = 1e-6
    fd = -(mc.straight_length(q + h, a=A, b=B, d=D) - mc.straight_length(q - h, a=A, b=B, d=D))
    # central difference error ~ h^2 L''' ~ 1e-12 m, round-off ~ 1e-16 / 1e-6 = 1e-10
    np.testing.assert_allclose(fd / (2 * h), mc.straight_moment_arm(q, a=A, b=B, d=D), atol=1e-8)
    assert mc.straight_moment_arm(0.0, a=A, b=B, d=D) == pytest.approx(D, abs=1e-15)
    with pytest.raises(ValueError):
        mc.pulley_length([-0.1], a=A, b=B, radius=R)
    # a concentric fibre at offset e: d/dq of its length is the radius R + e
    e = np.array([-0.005, 0.0, 0.005])
    lf = mc.pulley_fibre_length(q[q >= 0][:, None], e, a=A, b=B, radius=R)
    slope = np.diff(lf, axis=0) / np.diff(q[q >= 0])[:, None]
    np.testing.assert_allclose(slope, np.broadcast_to(R + e, slope.shape), rtol=1e-9)


@pytest.mark.parametrize("which", [0, 1])
def test_files_mesh_and_landmarks(models, which):
    import trimesh

    paths = models[which]
    mesh = trimesh.load(paths["mesh"])
    assert mesh.is_watertight and mesh.is_winding_consistent
    # a 32-gon prism: volume = (32 / 2pi) sin(2pi / 32) pi rho^2 (a + b), float32 vertices
    sides = 32
    exact = sides / 2 * math.sin(2 * math.pi / sides) * RHO ** 2 * (A + B)
    assert mesh.volume == pytest.approx(exact, rel=1e-5)
    origin = np.loadtxt(paths["origin"], delimiter=",", skiprows=1)
    insertion = np.loadtxt(paths["insertion"], delimiter=",", skiprows=1)
    np.testing.assert_allclose(origin[:, 1], A, atol=1e-7)          # the top cap, y = a
    np.testing.assert_allclose(insertion[:, 1], -B, atol=1e-7)      # the bottom cap, y = -b
    x0 = D if which == 0 else -R
    radial = np.hypot(origin[:, 0] - x0, origin[:, 2])
    assert radial.max() == pytest.approx(RHO, abs=1e-7) and radial.min() < 1e-7
    spec = tomllib.loads(paths["spec"].read_text())
    assert (paths["spec"].parent / spec["model"]).is_file()
    assert spec["muscles"]["cylinder"]["action_lines"] == ["cyl"]
    lines = paths["motion"].read_text().splitlines()
    sweep = np.loadtxt(lines[lines.index("endheader") + 2:])
    np.testing.assert_allclose(sweep[:, 1], np.arange(0.0, 91.0, 5.0))


def test_opensim_agrees_with_the_formulas(models, osim):
    osim.Logger.removeFileSink()   # no opensim.log beside the model files
    straight = osim.Model(str(models[0]["model"]))
    pulley = osim.Model(str(models[1]["model"]))
    for model, kind in ((straight, "straight"), (pulley, "pulley")):
        state = model.initSystem()
        q = model.getCoordinateSet().get("q")
        path = model.getMuscles().get("cyl").getGeometryPath()
        for deg in np.arange(0.0, 91.0, 15.0):
            th = math.radians(deg)
            q.setValue(state, th)
            model.realizePosition(state)
            length, arm = path.getLength(state), path.computeMomentArm(state, q)
            if kind == "straight":
                # no wrapping: OpenSim's length and moment arm are exact geometry (round-off)
                assert length == pytest.approx(mc.straight_length(th, a=A, b=B, d=D), abs=1e-12)
                assert arm == pytest.approx(mc.straight_moment_arm(th, a=A, b=B, d=D), abs=1e-9)
            else:
                # analytic cylinder wrap in the plane z = 0: exact to round-off (measured 1e-15)
                assert length == pytest.approx(mc.pulley_length(th, a=A, b=B, radius=R),
                                               abs=1e-9)
                assert arm == pytest.approx(-R, abs=1e-7)
