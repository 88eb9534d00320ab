"""The one-way import rule (docs/DESIGN.md, "Layering"): `fibres` imports neither `motion` nor
`analysis`; `motion` may import `fibres` (its geometry: the closest point of a triangle) but
never `analysis`; `analysis` uses both."""
import ast
import importlib
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FORBIDDEN = {"motion": {"analysis"}, "fibres": {"motion", "analysis"}, "analysis": set()}


def _imported_top_names(path: Path):
    tree = ast.parse(path.read_text(), filename=str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name.split(".")[0], node.lineno
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            yield node.module.split(".")[0], node.lineno


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_no_forbidden_imports(package):
    bad = []
    for path in sorted((ROOT / package).rglob("*.py")):
        for name, line in _imported_top_names(path):
            if name in FORBIDDEN[package]:
                bad.append(f"{path.relative_to(ROOT)}:{line} imports {name}")
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("package", ["motion", "fibres"])
def test_importing_does_not_load_other_packages(package):
    """At run time too (catches importlib tricks): a fresh interpreter importing the package."""
    code = (f"import sys, {package}; "
            f"print(','.join(sorted(m for m in {sorted(FORBIDDEN[package])!r} if m in sys.modules)))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                         check=True).stdout.strip()
    assert out == ""


def test_rule_detector_detects():
    """The AST scan must see both import forms (so the rule test can fail)."""
    src = "import fibres.x\nfrom analysis import y\nfrom . import z\n"
    tmp = ROOT / "tests" / "_tmp_rule_probe.py"
    tmp.write_text(src)
    try:
        names = {n for n, _ in _imported_top_names(tmp)}
    finally:
        tmp.unlink()
    assert names == {"fibres", "analysis"}


@pytest.mark.parametrize("package", ["motion", "fibres", "analysis"])
def test_import_is_cheap(package):
    """Importing a package does no heavy imports (pyvista, matplotlib, opensim, casadi)."""
    code = (f"import sys, {package}; heavy = ['pyvista', 'matplotlib', 'opensim', 'casadi', 'vtk']; "
            "print(','.join(h for h in heavy if h in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                         check=True).stdout.strip()
    assert out == ""
    importlib.import_module(package)
