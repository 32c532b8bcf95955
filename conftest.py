"""Shared by tests/ and benchmarks/: their helper modules and a seeded random generator."""

import sys
from pathlib import Path

import numpy as np
import pytest

# tests/reference.py and tests/examples_loader.py are imported by name from both folders.
sys.path.insert(0, str(Path(__file__).resolve().parent / "tests"))


@pytest.fixture
def rng():
    """A fresh, seeded random generator per test."""
    return np.random.default_rng(20261121)
