"""`analysis.fibre_checks.short_path_notes`: an action line not longer than its tendon slack
length gets a warning (its normalized length (L - l_ts) / l_opt would be <= 0 unannounced; the
LHDL hip model's placeholder l_ts = 0.2 m is longer than gluteus medius' 0.1-0.15 m paths)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from analysis.fibre_checks import line_normalized_lengths, short_path_notes

MODELS = Path(__file__).resolve().parents[2] / "models"


def test_short_paths_are_named_with_their_frames():
    import motion

    model = motion.load_model(MODELS / "arm_example.osim")   # every l_ts 0.01 m
    lengths = np.array([[0.25, 0.15], [0.009, 0.12], [0.010, 0.011]])
    notes = short_path_notes(model, ("BIClong", "BRA"), lengths)
    assert len(notes) == 1 and notes[0].startswith("warning: action line paths not longer")
    assert "BIClong (9.0-10.0 mm, l_ts 10.0 mm, 2 of 3 frames)" in notes[0] and "BRA" not in notes[0]
    assert len(short_path_notes(model, ("BIClong", "BICshort"), np.full((3, 2), 0.005))) == 1   # one per muscle
    normalized = line_normalized_lengths(model, ("BIClong", "BRA"), lengths)
    assert (normalized[1:, 0] <= 0).all() and (normalized[:, 1] > 0).all()    # what the note is about
    assert short_path_notes(model, ("BRA",), lengths[:, 1:]) == ()
