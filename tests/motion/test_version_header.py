"""A 4.x model behind a 3.x version header (``Version="30000"`` over ``socket_parent_frame``
content, as some Rajagopal-family files): read as 4.x with one warning, as OpenSim 4.6 loads it."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

import motion
from motion.osim.reader import ModelFileWarning, load_model

ARM = __import__("pathlib").Path(__file__).resolve().parents[2] / "models" / "arm_example.osim"


def _relabel(src, dst, version):
    text = src.read_text()
    assert 'Version="40000"' in text
    dst.write_text(text.replace('Version="40000"', f'Version="{version}"', 1))
    return dst


def _load(path):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = load_model(path)
    return model, [w for w in caught if issubclass(w.category, ModelFileWarning)]


@pytest.mark.parametrize("version", ["30000", "20302"])
def test_4x_content_with_an_old_header_reads_as_4x(tmp_path, version):
    ref = load_model(ARM)
    model, caught = _load(_relabel(ARM, tmp_path / "arm.osim", version))
    assert len(caught) == 1
    msg = str(caught[0].message)
    assert f'Version="{version}"' in msg and "<JointSet>" in msg and "4.x" in msg
    assert model.coordinate_names == ref.coordinate_names and model.path_names == ref.path_names
    q = np.radians([[0.0], [45.0], [120.0]])
    a, b = motion.action_lines(ref, q), motion.action_lines(model, q)
    np.testing.assert_array_equal(a.lengths, b.lengths)
    np.testing.assert_array_equal(a.moment_arms, b.moment_arms)


def test_true_3x_and_4x_files_do_not_warn(tmp_path, lhdl_dir):
    assert _load(ARM)[1] == []
    model, caught = _load(lhdl_dir / "model" / "LHDL_hip_r.osim")      # a real 3.x file
    assert caught == [] and model.version == 30000


@pytest.mark.shared
def test_rajagopal_behind_a_30000_header(tmp_path, opensim_dir):
    src = opensim_dir / "RajagopalLaiUhlrich2023" / "RajagopalLaiUhlrich2023.osim"
    ref = load_model(src)
    model, caught = _load(_relabel(src, tmp_path / "raj.osim", "30000"))
    assert len(caught) == 1
    assert model.path_names == ref.path_names and len(model.wrap_objects) == len(ref.wrap_objects)
    q = np.zeros((1, len(ref.coordinates)))
    np.testing.assert_array_equal(motion.action_lines(ref, q).lengths, motion.action_lines(model, q).lengths)


@pytest.mark.oracle
def test_opensim_loads_the_same_relabelled_file(tmp_path, osim):
    """OpenSim 4.6 itself loads 4.x content behind a 3.5 header (Version >= 30505; with 30000 it
    fails in its own 3.x conversion) and gives the lengths we give."""
    path = _relabel(ARM, tmp_path / "arm.osim", "30516")
    model, caught = _load(path)
    assert len(caught) == 1
    om = osim.Model(str(path))
    state = om.initSystem()
    ours = motion.action_lines(model, np.zeros((1, 1)))
    for k, name in enumerate(model.path_names):
        assert om.getMuscles().get(name).getLength(state) == pytest.approx(ours.lengths[0, k], abs=1e-12)
