"""The first run after an install says, once, that it compiles the kernels."""

from __future__ import annotations

import io
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from examples_loader import EXAMPLES

from sparsekin import load_model, solve_kinematics
from sparsekin.cli.compiling import COMPILING_NOTE, announce_compilation, kernels_cached

ROOT = Path(__file__).resolve().parents[1]


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_an_empty_cache_is_seen_and_a_filled_one_too(tmp_path):
    solve_kinematics(load_model(EXAMPLES / "task5.toml"), np.linspace(0.0, 0.1, 3))  # fills this cache
    assert kernels_cached()
    environment = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path), PYTHONPATH=str(ROOT))
    probe = "from sparsekin.cli.compiling import kernels_cached; print(kernels_cached())"
    empty = subprocess.run([sys.executable, "-c", probe], env=environment, capture_output=True, text=True, check=True)
    assert empty.stdout.strip() == "False"


def test_the_note_is_one_line_on_a_terminal_only_and_not_when_quiet(monkeypatch):
    monkeypatch.setattr("sparsekin.cli.compiling.kernels_cached", lambda: False)
    terminal = _Terminal()
    assert announce_compilation(quiet=False, stream=terminal)
    assert terminal.getvalue() == f"sparsekin: {COMPILING_NOTE}\n"
    for quiet, stream in ((True, _Terminal()), (False, io.StringIO())):  # --quiet; stderr piped to a file
        assert not announce_compilation(quiet=quiet, stream=stream) and stream.getvalue() == ""
    monkeypatch.setattr("sparsekin.cli.compiling.kernels_cached", lambda: True)
    assert not announce_compilation(quiet=False, stream=_Terminal())
