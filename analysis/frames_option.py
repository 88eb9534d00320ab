"""The ``--frames START:STOP:STEP`` option shared by ``fibres lines`` and ``fibres run``.

Syntax (Python slice, non-negative integers, every part optional): ``10:50`` frames 10..49,
``::5`` every fifth frame, ``100:`` from frame 100 to the end, ``7`` frame 7 alone. Frames are
0-based indices into the motion's rows. The syntax is checked when the command line is parsed
(`parse_frames`, an argparse ``type``: a usage error); the range is checked against the motion
once it is read (`resolve_frames`: an `InputError` giving the valid range).
"""
from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from .errors import InputError

__all__ = ["FrameSelection", "parse_frames", "add_frames_argument", "resolve_frames"]


@dataclasses.dataclass(frozen=True)
class FrameSelection:
    """A parsed ``--frames`` value: ``start``, ``stop`` (None = to the end), ``step`` (>= 1)."""

    start: int = 0
    stop: int | None = None
    step: int = 1
    text: str = ":"

    def __post_init__(self):
        if self.start < 0 or (self.stop is not None and self.stop < 0):
            raise ValueError("START and STOP must be >= 0")
        if self.step < 1:
            raise ValueError("STEP must be >= 1")
        if self.stop is not None and self.stop <= self.start:
            raise ValueError("STOP must be greater than START")


def parse_frames(text: str) -> FrameSelection:
    """Parse ``START:STOP:STEP`` (argparse ``type``); a bad value is an argparse usage error.

    Parameters
    ----------
    text : str

    Returns
    -------
    FrameSelection
    """
    raw = str(text).strip()
    parts = raw.split(":")
    if not raw or len(parts) > 3:
        raise argparse.ArgumentTypeError(
            f"invalid --frames value {text!r}: use START:STOP:STEP, e.g. 0:100:2 or ::5")
    try:
        values = [int(p) if p.strip() else None for p in parts]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"invalid --frames value {text!r}: START, STOP and STEP must be whole numbers "
            "(e.g. 0:100:2)") from None
    if len(values) == 1:  # a single frame
        if values[0] is None:
            raise argparse.ArgumentTypeError(f"invalid --frames value {text!r}")
        values = [values[0], values[0] + 1, 1]
    start, stop, step = (values + [None, None])[:3]
    try:
        return FrameSelection(start=0 if start is None else start, stop=stop,
                              step=1 if step is None else step, text=raw)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"invalid --frames value {text!r}: {exc}") from None


def add_frames_argument(parser) -> None:
    """Add ``--frames START:STOP:STEP`` to an argparse parser (dest ``frames``, default all)."""
    parser.add_argument("--frames", type=parse_frames, default=None, metavar="START:STOP:STEP",
                        help="use only these motion rows: 0-based, STOP excluded, STEP optional; "
                             "START and STOP must lie within the motion (default: all)")


def resolve_frames(selection, n_frames: int, *, source=None) -> np.ndarray:
    """Row indices of the motion selected by ``--frames``.

    Parameters
    ----------
    selection : FrameSelection, str or None
        None selects every frame.
    n_frames : int
        F, the number of rows of the motion.
    source : str or os.PathLike, optional
        The motion file (named in the error).

    Returns
    -------
    (F2,) int
        Increasing row indices, at least one.

    Raises
    ------
    InputError
        START or STOP outside the motion, with the valid range.
    """
    if selection is None:
        return np.arange(n_frames)
    if isinstance(selection, str):
        try:
            selection = parse_frames(selection)
        except argparse.ArgumentTypeError as exc:
            raise InputError(str(exc), file=source, where="--frames") from None
    last = n_frames - 1
    valid = f"the motion has {n_frames} frames: START must be 0 to {last} and STOP 1 to {n_frames}"
    if selection.start > last:
        raise InputError(f"START {selection.start} is out of range", file=source,
                         where=f"--frames {selection.text}", fix=f"{valid[0].upper()}{valid[1:]}.")
    if selection.stop is not None and selection.stop > n_frames:
        raise InputError(f"STOP {selection.stop} is out of range", file=source,
                         where=f"--frames {selection.text}", fix=f"{valid[0].upper()}{valid[1:]}.")
    return np.arange(selection.start, n_frames if selection.stop is None else selection.stop,
                     selection.step)
