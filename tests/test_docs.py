"""The documentation that is generated from the code is up to date, and the contract
lists every kind that the code registers."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

from sparsekin.model.elements import DRIVER_KINDS, JOINT_KINDS
from sparsekin.model.laws import BUILT_IN_LAWS

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


# ---------------------------------------------------------------------- code on the pages
#: Pages whose Python code runs here, and the modules it needs beyond the core.
PAGES_WITH_CODE = {
    "tutorial.md": ("matplotlib", "PIL"),
    "tutorial-linkage.md": ("matplotlib",),
    "how-to/lock-up-and-redundancy.md": (),
    "how-to/inverse-kinematics.md": (),
    "how-to/linear-solver.md": (),
    "how-to/reading-results.md": ("pandas", "xarray"),
    "how-to/chained-mechanisms.md": ("xarray",),
    "how-to/lattices.md": (),
    "how-to/forces.md": (),
    "how-to/dynamics.md": (),
    "how-to/design-studies.md": ("distributed",),
    "reference/python/index.md": (),
}


def python_blocks(page: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", (DOCS / page).read_text(encoding="utf-8"), re.MULTILINE | re.DOTALL)


def test_every_page_with_python_code_is_run():
    pages = {path.relative_to(DOCS).as_posix() for path in DOCS.rglob("*.md") if python_blocks(path.relative_to(DOCS))}
    assert pages <= set(PAGES_WITH_CODE) | {"index.md", "adding-an-element.md"}  # those show fragments


@pytest.mark.parametrize("page", sorted(PAGES_WITH_CODE))
def test_the_python_code_of_a_page_runs(page, tmp_path, monkeypatch):
    """The blocks of a page run in order in one namespace, in a folder holding examples/
    and tests/ as the repository does."""
    for module in PAGES_WITH_CODE[page]:
        pytest.importorskip(module, reason=f"{page} needs {module}")
    for name in ("examples", "tests"):
        (tmp_path / name).symlink_to(DOCS.parent / name, target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__docs__"}
    for number, block in enumerate(python_blocks(page)):
        exec(compile(block, f"{page}, block {number + 1}", "exec"), namespace)  # the pages assert what they claim


def test_the_model_file_fragments_of_the_tutorial_are_task5_toml():
    """Every line of the TOML fragments in the tutorial is a line of examples/task5.toml."""
    example = {line.strip() for line in (DOCS.parent / "examples" / "task5.toml").read_text().splitlines()}
    fragments = re.findall(r"^```toml\n(.*?)^```", (DOCS / "tutorial.md").read_text(encoding="utf-8"),
                           re.MULTILINE | re.DOTALL)  # fmt: skip
    assert len(fragments) >= 6
    for fragment in fragments:
        for line in fragment.splitlines():
            assert line.strip() in example, line
