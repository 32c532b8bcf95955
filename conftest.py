"""Shared by tests/ and benchmarks/: helper modules, a seeded random generator, and the
benchmarks' ``--sizes`` option (``smoke``, the default, or ``full``)."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

# tests/reference.py and tests/examples_loader.py are imported by name from both folders.
sys.path.insert(0, str(Path(__file__).resolve().parent / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent / "benchmarks"))


def pytest_addoption(parser):
    parser.addoption(
        "--sizes",
        choices=("smoke", "full"),
        default="smoke",
        help="benchmark sizes: smoke (up to 100 bodies, the default) or full (up to 10^6 bodies)",
    )


@pytest.fixture
def rng():
    """A fresh, seeded random generator per test."""
    return np.random.default_rng(20261121)


#: Doctests that need an optional dependency, and the extra that installs it: skipped
#: (with that reason) when it is missing.
OPTIONAL_DOCTESTS = {"sparsekin.results.kinematics.KinematicsResult.to_dataframe": ("pandas", "pandas")}


def pytest_collection_modifyitems(config, items):
    for item in items:
        module, extra = OPTIONAL_DOCTESTS.get(item.name, (None, None))
        if module and importlib.util.find_spec(module) is None:
            item.add_marker(pytest.mark.skip(reason=f'needs {module}: pip install "sparsekin[{extra}]"'))
