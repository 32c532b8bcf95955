"""The documentation that is generated from the code is up to date, and the contract
lists every kind that the code registers."""

import re
import subprocess
import sys
from pathlib import Path

from sparsekin.elements import DRIVER_KINDS, JOINT_KINDS
from sparsekin.laws import BUILT_IN_LAWS

DOCS = Path(__file__).resolve().parents[1] / "docs"


def test_the_element_reference_is_generated_from_the_declarations():
    check = subprocess.run(
        [sys.executable, str(DOCS / "make_element_reference.py"), "--check"], capture_output=True, text=True
    )
    assert check.returncode == 0, check.stderr


def test_the_model_format_names_every_kind_and_its_keys():
    text = (DOCS / "model-format.md").read_text(encoding="utf-8")
    for kind in (*JOINT_KINDS.values(), *DRIVER_KINDS.values(), *BUILT_IN_LAWS):
        assert re.search(rf"`{kind.type_name}`", text), kind.type_name
        for key in kind.file_keys.keys:  # as `key` or `key = ...`
            assert re.search(rf"`{key}( = [^`]*)?`", text), (kind.type_name, key)
