"""The test-set families and sizes the benchmarks run, by approximate number of bodies.

``python3 -m pytest benchmarks --sizes=full`` runs every size of `SIZES`; the default
(``--sizes=smoke``, what the test suite runs) only those up to `SMOKE_MAX_BODIES`.
"""

from __future__ import annotations

import math

from sparsekin import testset
from sparsekin.model.mechanism import Mechanism

__all__ = [
    "FAMILIES",
    "SIZES",
    "SMOKE_MAX_BODIES",
    "DENSE_MAX_BODIES",
    "MESH_BASELINE_MAX_BODIES",
    "MESHES",
    "build",
    "steps_per_round",
]

#: Approximate numbers of bodies per family; each builder picks the nearest model.
SIZES = {
    "task5_chain": (10, 100, 1_000, 10_000, 100_000, 1_000_000),
    "four_bar_chain": (10, 100, 1_000, 10_000, 20_000, 100_000, 1_000_000),  # 20 001: issue 4's target
    "lattice": (10, 100, 1_000, 10_000, 100_000, 1_000_000),
}
#: The baselines that factor at every Newton iteration (`superlu`, `coo_spsolve`) stop here
#: on meshes: on the lattice at 10^5 bodies one such factorization takes 1–3 s with fill
#: ratio 9.5, at 10^6 it would take minutes per step (docs/design-notes.md,
#: "Fill-reducing column order").
MESH_BASELINE_MAX_BODIES = 100_000
#: The families that are meshes.
MESHES = frozenset({"lattice"})
#: The test suite's smoke run stops here.
SMOKE_MAX_BODIES = 100
#: The dense baseline stops here: one dense solve at 3·10^4 coordinates (10^4 bodies)
#: would need 7 GB and about 10 minutes on this machine (see RESULTS.md).
DENSE_MAX_BODIES = 1_000
#: Time step of every benchmark run, s.
STEP = 0.01


def _lattice(bodies: int) -> Mechanism:
    # rows · (2 · cols + 1) bodies with rows ≈ cols
    rows = max(1, round(math.sqrt(bodies / 2)))
    cols = max(1, round((bodies / rows - 1) / 2))
    return testset.lattice(rows, cols)


#: Family name → builder from an approximate number of bodies.
FAMILIES = {
    "task5_chain": lambda bodies: testset.task5_chain(max(1, bodies // 10)),
    "four_bar_chain": lambda bodies: testset.four_bar_chain(max(1, bodies // 2)),
    "lattice": _lattice,
}


def build(family: str, bodies: int) -> Mechanism:
    """The member of `family` with about `bodies` bodies."""
    return FAMILIES[family](bodies)


def steps_per_round(bodies: int, solver: str = "sparsekin") -> int:
    """Time steps per timed round: about 10^5 body-steps, between 2 and 200.

    The dense baseline, whose cost grows as bodies³, gets about 2·10^3 body-steps.
    """
    budget = 2_000 if solver == "dense" else 100_000
    return int(min(200, max(2, budget // bodies)))
