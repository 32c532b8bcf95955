import numpy as np
import pytest


@pytest.fixture
def rng():
    """A fresh, seeded random generator per test."""
    return np.random.default_rng(20261121)
