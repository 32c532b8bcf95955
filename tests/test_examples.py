"""The examples run, and the file and Python routes give the same Task 5 mechanism."""

from __future__ import annotations

import re
from dataclasses import replace

from examples_loader import EXAMPLES, load_example
from sparsekin import load_model, save_model


def test_task5_file_and_python_give_the_same_mechanism():
    from_file = load_model(EXAMPLES / "task5.toml")
    from_python = load_example("task5").build_task5()
    # The file also carries defaults for the command line; the rest is the same mechanism.
    assert from_file == replace(from_python, analysis=from_file.analysis)
    assert from_file.analysis.points == ("A", "J", "K")


def test_task5_script_prints_the_tool_point(capsys):
    load_example("task5").main()
    lines = capsys.readouterr().out.splitlines()
    summary = re.fullmatch(r"Task 5: 1001 samples, (\d+) Newton corrections", lines[0])
    assert summary and 1000 <= int(summary.group(1)) <= 4 * 1000  # 1 to 4 (chord) per step of 10 ms
    assert lines[1].startswith("t =  0.00 s  K = (-1.20000,  0.60000) m")  # K as drawn in task5.md
    assert len(lines) == 12


def test_task5_saved_from_python_loads_back(tmp_path):
    mechanism = load_example("task5").build_task5()
    save_model(mechanism, tmp_path / "task5.toml")
    assert load_model(tmp_path / "task5.toml") == mechanism
