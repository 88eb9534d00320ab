"""Every sub-package ships: a non-editable ``pip install .`` installs only the packages listed in
pyproject.toml (``[tool.setuptools] packages``), so a new folder of `fibres`, `motion` or
`analysis` that is not listed would work in a checkout and break for users."""
from __future__ import annotations

import sys
from pathlib import Path

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]


def test_every_package_folder_is_listed_in_pyproject():
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts) for top in ("fibres", "motion", "analysis")
             for p in (ROOT / top).rglob("__init__.py") if "__pycache__" not in p.parts}
    assert found, "no package found"
    assert found <= listed, f"not listed in pyproject.toml: {sorted(found - listed)}"
    assert not {p for p in listed - found if p != "analysis.example"}, "listed but missing"


def test_no_module_of_the_package_is_over_500_lines():
    """The house rule of docs/DESIGN.md: modules of one concept, at most 500 lines."""
    sizes = {str(p.relative_to(ROOT)): len(p.read_text().splitlines())
             for top in ("fibres", "motion", "analysis") for p in (ROOT / top).rglob("*.py")}
    assert sizes, "no module found"
    assert not {k: n for k, n in sizes.items() if n > 500}
