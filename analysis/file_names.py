"""Safe file names for names taken from input files (muscles in the TOML, coordinates in the .osim).

A name from an input file never becomes part of a path unchecked: ``"../../../pwned"`` as a
muscle name must not make `fibres run` write ``pwned.pvd`` three folders up. `file_stems` maps
every name to a file stem that

- holds only ``A-Z a-z 0-9 _ . + -``, starts with a letter, digit or ``_``, holds no ``..`` and
  does not end in ``.`` (no folder separators, no hidden files, no parent references, nothing a
  shell or Windows treats specially);
- is at most 80 characters long;
- is not a reserved Windows device name (``CON``, ``NUL``, ``COM1`` ...);
- is unique among the names of the run, also ignoring case (macOS and Windows file systems do).

A name that already satisfies all of this is kept as it is (``biceps`` -> ``biceps``), so
ordinary runs keep their file names. Any other name becomes its safe characters (runs of other
characters replaced by ``_``) followed by ``-`` and the first 8 hex digits of the SHA-256 of the
name (``"../../../pwned"`` -> ``pwned-55d4ac58``), so that two different unsafe names cannot
share a file. `fibres run` records the mapping in ``run.json`` (``file_names``).
"""
from __future__ import annotations

import hashlib
import re

__all__ = ["file_stems", "is_safe_stem", "MAX_STEM"]

#: longest file stem kept as it is (the frame and plot suffixes add up to 20 more characters)
MAX_STEM = 80
_SAFE = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.+-]*\Z")
_UNSAFE_RUN = re.compile(r"[^A-Za-z0-9_.+-]+")
_RESERVED = {"con", "prn", "aux", "nul"} | {f"{p}{i}" for p in ("com", "lpt") for i in range(1, 10)}


def is_safe_stem(name: str) -> bool:
    """Whether ``name`` can be used as a file stem as it is (module docstring rules, but
    uniqueness)."""
    return (isinstance(name, str) and 0 < len(name) <= MAX_STEM and _SAFE.match(name) is not None
            and ".." not in name and not name.endswith(".")
            and name.split(".")[0].lower() not in _RESERVED)


def _digest(name: str, n: int) -> str:
    return hashlib.sha256(name.encode("utf-8", "surrogatepass")).hexdigest()[:n]


def _mapped(name: str, n_hex: int) -> str:
    body = _UNSAFE_RUN.sub("_", name).replace("..", "_").strip("._-+")[: MAX_STEM - 1 - n_hex]
    body = body.rstrip(".") or "name"
    if body.split(".")[0].lower() in _RESERVED:
        body = "_" + body
    return f"{body}-{_digest(name, n_hex)}"


def file_stems(names) -> dict:
    """Map each name to a safe, unique (case-insensitively) file stem.

    Parameters
    ----------
    names : iterable of str
        Names in their order of use (muscles, coordinates); duplicates are mapped once.

    Returns
    -------
    dict str -> str
        ``name -> stem``; ``stem == name`` wherever the name is already safe and unique.

    Examples
    --------
    >>> file_stems(["biceps", "../../../pwned"])
    {'biceps': 'biceps', '../../../pwned': 'pwned-55d4ac58'}
    """
    out, taken = {}, set()
    ordered = list(dict.fromkeys(str(n) for n in names))
    # safe names keep themselves first, so an unsafe name never takes an ordinary name's file
    for name in ordered:
        if is_safe_stem(name) and name.lower() not in taken:
            out[name] = name
            taken.add(name.lower())
    for name in ordered:
        if name in out:
            continue
        n_hex = 8
        stem = _mapped(name, n_hex)
        while stem.lower() in taken:   # a digest prefix shared with another name: lengthen it
            n_hex += 4
            stem = _mapped(name, n_hex) if n_hex <= 64 else f"{stem}_"
        out[name] = stem
        taken.add(stem.lower())
    return {name: out[name] for name in ordered}
