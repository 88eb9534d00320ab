"""Read the OpenSim 4.6 reference CSVs of ``../shared/opensim/reference/<Model>/<motion>/``.

Helpers for tests (any helper may import them). All arrays are in the model's order:

- `reference_cases()` -> list of (model file relative to ``opensim/``, reference dir relative to
  ``opensim/``) for every model/motion pair that has references.
- `ReferenceCase(opensim_dir, model_rel, ref_rel)`: lazy access to ``q_used(model)`` (F, C),
  ``body_transforms(model)`` (F, B, 4, 4) (ground = identity), ``path_lengths(model)`` (F, M),
  ``moment_arms()`` long DataFrame, ``metadata``.
"""
from __future__ import annotations

import json
from functools import cached_property
from pathlib import Path

import numpy as np
import pandas as pd

CASES = [
    ("Arm26/arm26.osim", "reference/Arm26/ik_tutorial"),
    ("Arm26/arm26.osim", "reference/Arm26/elbow_flexion_sweep"),
    ("Gait2392_Simbody/gait2392_thelen2003muscle.osim", "reference/Gait2392_Simbody/subject01_walk1_ik"),
] + [
    (f"MomentArmTests/{name}.osim", f"reference/MomentArmTests/{name}")
    for name in ("CoupledCoordinatesMPPsMomentArmTest", "MovingPathPointMomentArmTest",
                 "MovingPointCustomJointMomentArmTest", "MultipleMPPsMomentArmTest",
                 "P2PBallCustomJointMomentArmTest", "P2PBallJointMomentArmTest",
                 "P2PCustomJointMomentArmTest", "PathOnConstrainedBodyMomentArmTest",
                 "WrapPathCustomJointMomentArmTest", "testMomentArmsConstraintA",
                 "testMomentArmsConstraintB")
]


def case_id(case) -> str:
    return case[1].split("/", 1)[1].replace("/", "-")


class ReferenceCase:
    """One model + motion reference folder."""

    def __init__(self, opensim_dir, model_rel: str, ref_rel: str):
        self.model_file = Path(opensim_dir) / model_rel
        self.dir = Path(opensim_dir) / ref_rel

    def _csv(self, name: str) -> pd.DataFrame:
        return pd.read_csv(self.dir / name, keep_default_na=False, na_values=["nan", ""])

    @cached_property
    def metadata(self) -> dict:
        return json.loads((self.dir / "metadata.json").read_text())

    @cached_property
    def coordinates(self) -> pd.DataFrame:
        return self._csv("coordinates.csv")

    @cached_property
    def time(self) -> np.ndarray:
        return self.coordinates.groupby("frame")["time"].first().to_numpy()

    def q_used(self, model) -> np.ndarray:
        """(F, C) the values OpenSim used after assembly, model order."""
        tab = self.coordinates.pivot(index="frame", columns="coordinate", values="value")
        return tab[list(model.coordinate_names)].to_numpy(dtype=float)

    def body_transforms(self, model) -> np.ndarray:
        """(F, B, 4, 4) body frames in ground (model body order; ground = identity)."""
        df = self._csv("body_transforms.csv")
        n_frames = df["frame"].max() + 1
        out = np.zeros((n_frames, len(model.bodies), 4, 4))
        out[:, :, 3, 3] = 1.0
        out[:, 0] = np.eye(4)
        for name, sub in df.groupby("body"):
            b = model.body_index(name)
            sub = sub.sort_values("frame")
            out[sub["frame"].to_numpy(), b, :3, 3] = sub[["tx", "ty", "tz"]].to_numpy()
            out[sub["frame"].to_numpy(), b, :3, :3] = sub[[f"r{i}{j}" for i in range(3) for j in range(3)]
                                                         ].to_numpy().reshape(-1, 3, 3)
        return out

    def path_lengths(self, model) -> np.ndarray:
        """(F, M) path lengths in the model's path order."""
        tab = self._csv("path_lengths.csv").pivot(index="frame", columns="muscle", values="length")
        return tab[list(model.path_names)].to_numpy(dtype=float)

    @cached_property
    def moment_arms(self) -> pd.DataFrame:
        """Long table: frame, muscle, coordinate, coord_status, moment_arm, neg_dLdq_fd."""
        return self._csv("moment_arms.csv")

    @cached_property
    def path_points(self) -> pd.DataFrame:
        return self._csv("path_points.csv")

    def wrapped_paths(self) -> set:
        """Names of paths that have at least one wrap object."""
        return {name for name, p in self.metadata["paths"].items() if p["wrap_objects"]}
