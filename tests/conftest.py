"""Shared test fixtures: where ../shared is, and skips when it or opensim is absent."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
OPENSIM_DIR = SHARED / "opensim"
LHDL_DIR = SHARED / "muscles" / "LHDL_hip_r"

HAVE_SHARED = SHARED.is_dir()
HAVE_OPENSIM = importlib.util.find_spec("opensim") is not None

needs_shared = pytest.mark.skipif(not HAVE_SHARED, reason="../shared data folder is absent")
needs_opensim = pytest.mark.skipif(not HAVE_OPENSIM, reason="opensim (OpenSim 4.6) is not installed")


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    if not HAVE_SHARED:
        pytest.skip("../shared data folder is absent")
    return SHARED


@pytest.fixture(scope="session")
def opensim_dir(shared_dir) -> Path:
    return shared_dir / "opensim"


@pytest.fixture(scope="session")
def lhdl_dir(shared_dir) -> Path:
    return shared_dir / "muscles" / "LHDL_hip_r"


@pytest.fixture(scope="session")
def osim():
    """The opensim module (the oracle), or skip. OpenSim's log file sink is removed so that
    loading a model does not leave ``opensim.log`` files beside it."""
    module = pytest.importorskip("opensim")
    module.Logger.removeFileSink()
    return module
