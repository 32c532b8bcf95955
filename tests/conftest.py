"""Fixtures shared by the test modules."""

from __future__ import annotations

import pytest


@pytest.fixture
def compiled_loops(monkeypatch):
    """The compiled dynamics loops (`CompiledDynamicsLoop`) the test's runs made, in order:
    to check that the compiled path did run, and which factorization it held."""
    from sparsekin.solve import _compiled_dynamics

    loops = []

    class Recorded(_compiled_dynamics.CompiledDynamicsLoop):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            loops.append(self)

    monkeypatch.setattr(_compiled_dynamics, "CompiledDynamicsLoop", Recorded)
    return loops
