"""OpenSim storage (``.sto``) copies of a run's tables, named and laid out like OpenSim's
MuscleAnalysis output so that OpenSim users can load them straight away (``opensim.Storage``,
``opensim.TimeSeriesTable``, the GUI's plotter).

Files (SI units, ``inDegrees=no``, one row per frame, ``time`` first):

- ``MuscleAnalysis_Length.sto``: one column per action line (OpenSim muscle name), as
  MuscleAnalysis's ``_Length.sto``.
- ``MuscleAnalysis_MomentArm_<coord>.sto``: one column per action line spanning ``coord``.
- ``FibreAnalysis_Length.sto`` / ``FibreAnalysis_MomentArm_<coord>.sto``: the fibre distribution
  per muscle: columns ``<muscle>_p5``, ``<muscle>_median``, ``<muscle>_p95``.
- with ``per_fibre=True``: ``FibreAnalysis_<muscle>_Length.sto`` and
  ``FibreAnalysis_<muscle>_MomentArm_<coord>.sto``, one column per fibre named
  ``<muscle>_fibreNNN`` -- the names of the fibre muscles of ``fibres export-osim``, so these
  tables line up with a MuscleAnalysis of the exported model.

A moment arm that is NaN (a coordinate the line does not span) is written as 0, as OpenSim does.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["write_sto_files"]


def _fibre_names(muscle, n):
    width = max(3, len(str(n - 1)))
    return [f"{muscle}_fibre{k:0{width}d}" for k in range(n)]


def write_sto_files(result, folder, *, per_fibre: bool = False, muscle_stems=None,
                    coordinate_stems=None) -> list:
    """Write the ``.sto`` files of the module docstring into ``folder``; return their paths.

    ``<muscle>`` and ``<coord>`` in the file names are the safe file stems of the names
    (`analysis.file_names`; default: computed here), never the names themselves."""
    from motion import write_sto

    from .file_names import file_stems
    from .output_files import checked_path

    if muscle_stems is None:
        muscle_stems = file_stems(m.name for m in result.muscles)
    if coordinate_stems is None:
        coordinate_stems = file_stems(c for m in result.muscles for c in m.coordinates)
    folder = Path(folder)
    written = []
    lengths, fibre_len = {}, {}
    arms, fibre_arms = {}, {}
    tables = {}
    for m in result.muscles:
        for i, name in enumerate(m.action_lines):
            lengths[name] = m.action_line_lengths[:, i]
        for q, v in zip(("p5", "median", "p95"), np.percentile(m.fibre_lengths, [5, 50, 95], axis=1)):
            fibre_len[f"{m.name}_{q}"] = v
        for c, coord in enumerate(m.coordinates):
            for i, name in enumerate(m.action_lines):
                arms.setdefault(coord, {})[name] = np.nan_to_num(m.action_line_moment_arms[:, i, c])
            pct = np.percentile(m.fibre_moment_arms[:, :, c], [5, 50, 95], axis=1)
            for q, v in zip(("p5", "median", "p95"), pct):
                fibre_arms.setdefault(coord, {})[f"{m.name}_{q}"] = v
        if per_fibre:
            names = _fibre_names(m.name, m.n_fibres)
            stem = muscle_stems[m.name]
            tables[f"FibreAnalysis_{stem}_Length"] = dict(zip(names, m.fibre_lengths.T))
            for c, coord in enumerate(m.coordinates):
                tables[f"FibreAnalysis_{stem}_MomentArm_{coordinate_stems[coord]}"] = dict(
                    zip(names, np.nan_to_num(m.fibre_moment_arms[:, :, c]).T))
    tables.update({"MuscleAnalysis_Length": lengths, "FibreAnalysis_Length": fibre_len})
    tables.update({f"MuscleAnalysis_MomentArm_{coordinate_stems[c]}": v for c, v in arms.items()})
    tables.update({f"FibreAnalysis_MomentArm_{coordinate_stems[c]}": v for c, v in fibre_arms.items()})
    for name, cols in tables.items():
        if cols:
            path = checked_path(folder / f"{name}.sto")
            write_sto(path, result.time, cols, name=name)
            written.append(path)
    return written
