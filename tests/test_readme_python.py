"""Every call in the Python blocks of README.md ("## Python") and docs/INTERFACE.md ("## Python
API") names a function of the packages (both said ``motion.wrapping.action_lines(model, mot)``, a
module since the package was regrouped: TypeError on a new user's first try)."""
from __future__ import annotations

import importlib
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


import pytest


@pytest.mark.parametrize("doc, heading", [("README.md", "## Python\n"), ("docs/INTERFACE.md", "## Python API")])
def test_python_blocks_call_callables(doc, heading):
    text = (ROOT / doc).read_text()
    block = text.split(heading, 1)[1].split("```python\n", 1)[1].split("```", 1)[0]
    calls = re.findall(r"\b((?:motion|fibres|analysis)(?:\.\w+)+)\(", block)
    assert len(calls) >= 6, calls
    for dotted in calls:
        package, *attrs = dotted.split(".")
        obj = importlib.import_module(package)
        for a in attrs:
            obj = getattr(obj, a)
        assert callable(obj) and not isinstance(obj, type(importlib)), dotted
