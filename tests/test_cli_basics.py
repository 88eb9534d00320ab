"""The command line's own behaviour: usage errors are one line with exit status 2."""
import subprocess
import sys

from analysis.cli import main


def test_unknown_option_is_exit_2(capsys):
    try:
        code = main(["lines", "--no-such-option"])
    except SystemExit as exc:
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert "error" in err and "Traceback" not in err


def test_help_lists_commands():
    out = subprocess.run([sys.executable, "-m", "analysis.cli", "--help"], capture_output=True,
                         text=True).stdout
    for name in ("run", "lines", "decompose"):
        assert name in out
