"""The rank analysis of a long chain (`sparsekin.analyse_jacobian`): the Jacobian of a
``task5_chain`` at t = 0, whole (full rank) and with one joint left out (two free motions).

These are the timings tests/test_diagnostics.py once asserted (about 1 s and 3 s at 10^5
bodies on the project's machine); the unit tests check the answers at 10^5 bodies, this
file how long they take.  ``--sizes=full`` runs 10^4 and 10^5 bodies; the smoke size 100.
"""

from __future__ import annotations

import dataclasses

import pytest

from sparsekin.engine.discretization import Discretization
from sparsekin import analyse_jacobian, testset
from sparsekin.engine.assembly import Assembler
from sparsekin.engine.pattern import build_pattern

#: Bodies of the chain (10 per copy of the unit).
CHAIN_SIZES = {"smoke": (100,), "full": (10_000, 100_000)}


def pytest_generate_tests(metafunc):
    if "bodies" in metafunc.fixturenames:
        sizes = CHAIN_SIZES[metafunc.config.getoption("--sizes")]
        metafunc.parametrize("bodies", sizes, ids=[f"{b}bodies" for b in sizes])


def jacobian_at_start(mechanism):
    pattern = build_pattern(mechanism)
    assembler = Assembler(Discretization(mechanism, pattern))
    assembler.set_time(0.0)
    assembler.fill_residual_jacobian(pattern.initial_coordinates)
    return assembler.jacobian.copy()


def without_joint_at(mechanism, point: str):
    """The chain written out without its joint at `point` (two free motions)."""
    expanded = mechanism.expanded()
    joints = tuple(joint for joint in expanded.joints if getattr(joint, "at", None) != point)
    assert len(joints) == len(expanded.joints) - 1
    return dataclasses.replace(expanded, joints=joints)


@pytest.mark.parametrize("joint_left_out", [False, True], ids=["whole", "one_joint_left_out"])
def test_chain_rank(benchmark, bodies, joint_left_out):
    copies = bodies // 10
    chain = testset.task5_chain(copies)
    if joint_left_out:
        chain = without_joint_at(chain, f"u{copies // 2}.E")  # the middle copy's rocker turns freely
    jacobian = jacobian_at_start(chain)
    analysis = benchmark.pedantic(analyse_jacobian, args=(jacobian,), rounds=3, iterations=1)
    n = 3 * chain.n_bodies
    assert analysis.rank == (n - 2 if joint_left_out else n) and analysis.n_redundant == 0
    benchmark.extra_info.update(family="task5_chain", bodies=chain.n_bodies, free=analysis.n_free)
