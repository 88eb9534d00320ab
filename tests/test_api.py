"""Pin each package's public names: changing them is a contract change (INTERFACE.md)."""
import importlib

import pytest

# Each package's curated public API. Add a name here when you add it to the package's __all__.
EXPECTED = {
    "motion": {
        "InputError", "MissingDependencyError",
        "Motion", "load_motion", "write_sto",
        "MuscleSurfaceSpec", "SurfaceAttachment", "BoneMesh", "WrappedSurface", "wrap_surfaces",
        "SurfaceBinding", "bind_surface", "fusiform_surface",
        "load_model", "Model", "body_poses", "BodyPoses", "body_pose_derivatives", "action_lines", "ActionLines",
    },
    "fibres": {
        "InputError", "MissingDependencyError",
        "Surface", "as_surface", "sobol_rs", "get_template", "TEMPLATES",
        "decompose", "FibreBundle", "DecompositionPlan", "make_plan", "mean_value_coordinates",
        "HarmonicPlan", "FibreQuality", "FibreQualityWarning", "SLICINGS", "DEFAULT_SLICING",
    },
    "analysis": {
        "InputError", "MissingDependencyError",
        "run", "RunResult", "MuscleResult", "load_spec", "FibreModelSpec", "MuscleSpec", "AttachmentSpec",
        "study",
    },
}


@pytest.mark.parametrize("package", sorted(EXPECTED))
def test_all_is_pinned(package):
    module = importlib.import_module(package)
    assert set(module.__all__) == EXPECTED[package]
    assert len(module.__all__) == len(set(module.__all__)), "duplicate names in __all__"
    for name in module.__all__:
        assert hasattr(module, name), f"{package}.{name} is in __all__ but not defined"
