"""The command synopses of README.md and docs/INTERFACE.md name every option `fibres <cmd> --help`
has (a new user reads the README first; options missing there were found only in --help)."""
from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

from analysis import cli

ROOT = Path(__file__).resolve().parents[2]
COMMANDS = ("run", "lines", "decompose", "export-osim", "render", "study")


def _options(command: str) -> set:
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {s for a in sub.choices[command]._actions for s in a.option_strings
            if s.startswith("--") and s not in ("--help", "--debug")}


def _readme_synopsis(command: str) -> str:
    text = (ROOT / "README.md").read_text()
    block = text.split("## Commands\n```\n", 1)[1].split("```", 1)[0]
    entries = re.split(r"\n(?=fibres )", block)
    return next(e for e in entries if e.startswith(f"fibres {command} "))


@pytest.mark.parametrize("command", COMMANDS)
def test_readme_synopsis_names_every_option(command):
    synopsis = _readme_synopsis(command)
    missing = sorted(o for o in _options(command) if not re.search(rf"(?<![\w-]){re.escape(o)}(?![\w-])", synopsis))
    assert not missing, f"README.md's `fibres {command}` synopsis lacks {missing}"


@pytest.mark.parametrize("command", COMMANDS)
def test_interface_names_every_option(command):
    text = (ROOT / "docs" / "INTERFACE.md").read_text()
    start = text.index(f"fibres {command} ")
    nearby = text[start:start + 1500]
    missing = sorted(o for o in _options(command) if not re.search(rf"(?<![\w-]){re.escape(o)}(?![\w-])", nearby))
    assert not missing, f"docs/INTERFACE.md's `fibres {command}` synopsis lacks {missing}"


def test_frames_help_says_the_range_is_checked():
    """--frames 0:500 on 27 rows is an error, not a Python slice clipped at the end."""
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for command in ("run", "lines", "export-osim"):
        help_text = next(a.help for a in sub.choices[command]._actions if "--frames" in a.option_strings)
        assert "Python slice" not in help_text and "STOP" in help_text, help_text
