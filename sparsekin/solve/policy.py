"""How the linear systems of a run are solved: `plan_linear_solver`, the one ``"auto"`` rule.

``linear_solver="auto"`` picks, from the size of the model and the fill-in of its
factorization, the fastest path measured (benchmarks/RESULTS.md, docs/design-notes.md):

* up to `COMPILED_MAX_COORDINATES` coordinates, the compiled dense loop
  (`sparsekin.solve._compiled`), when the model's laws are all built in and it has as many
  equations as coordinates; otherwise the Python loop on a dense LU;
* above, a refactorization on the fixed pattern (`RefactorSolver`), ordered by METIS from
  `MIN_METIS_COORDINATES` coordinates on when `pymetis` is installed, its first order tiled
  from a short chain for a long repeated chain (`MIN_TILED_COORDINATES`);
* and when that refactorization's L and U hold more than `MAX_REFACTOR_FILL` entries per
  Jacobian entry, its factorization reused across samples (`ReusingSolver`, path ``"reuse"``);
* for a mesh — a model of grid repeats with as many equations as coordinates — from
  `MIN_DISSECTION_COORDINATES` coordinates on, SuperLU in a nested dissection of the bodies
  cut where they are drawn (`DissectionSolver`, no extra needed), its factorization always
  reused across samples.

The plan is a value (`SolverPlan`): the facade, the stepper and the benchmark harness all
ask `plan_linear_solver`, with the thresholds as an argument (`Thresholds`).  Forward
dynamics solves the saddle matrix [[M + …, Φqᵀ], [Φq, 0]] instead of Φq: its plan is
`plan_saddle_solver`, dense LU up to `SADDLE_DENSE_MAX_SIZE` unknowns, a refactorization
above, and for a grid model from `MIN_MESH_SADDLE_SIZE` unknowns on a fresh factorization
each time (`MESH_SADDLE_SOLVER`).

>>> from sparsekin.engine.discretization import discretize
>>> from sparsekin.testset import task5, lattice
>>> plan_linear_solver(discretize(task5()), "auto").loop
'compiled'
>>> plan = plan_linear_solver(discretize(lattice(6, 8)), "auto")
>>> plan.loop, plan.solver, plan.ordering
('python', 'refactor', 'colamd')
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..analysis.rank import SMALLEST_TALL_LU
from ..engine.discretization import Discretization
from ..engine.dissection import DissectionSolver
from ..engine.krylov import ReusingSolver
from ..engine.dense import DenseSolver
from ..engine.linalg import COORDINATES_PER_BODY, RefactorSolver, SuperLUSolver
from ..engine.multipliers import MIN_NORM_ITERATIONS
from ..engine.ordering import MIN_TILED_COORDINATES, metis_installed
from ._compiled import supports_compiled

__all__ = [
    "COMPILED_MAX_COORDINATES",
    "LINEAR_SOLVERS",
    "MAX_REFACTOR_FILL",
    "MIN_METIS_COORDINATES",
    "MIN_DISSECTION_COORDINATES",
    "MIN_MESH_SADDLE_SIZE",
    "MESH_SADDLE_SOLVER",
    "SolverPlan",
    "Thresholds",
    "SADDLE_DENSE_MAX_SIZE",
    "COMPILED_SADDLE_MAX_SIZE",
    "COMPILED_BANDED_MAX_SIZE",
    "MAX_BAND_FRACTION",
    "MAX_BANDED_WORK",
    "MIN_BANDED_SADDLE_SIZE",
    "plan_compiled_factorization",
    "plan_linear_solver",
    "plan_saddle_solver",
]

#: The `linear_solver` names.
LINEAR_SOLVERS = ("auto", "superlu", "refactor", "dense")
#: ``linear_solver="auto"`` runs the compiled dense loop (`sparsekin.solve_kinematics`) or
#: the dense path up to this many coordinates and the refactorization path above: the
#: crossover measured on the test set (benchmarks/RESULTS.md, "Crossover").
COMPILED_MAX_COORDINATES = 120
#: ``linear_solver="auto"`` refactors at every sample while L and U hold at most this
#: many entries per entry of the Jacobian.  With more fill-in (meshes rather than chains)
#: a factorization costs tens of solves, and the run goes on reusing it across samples
#: (`sparsekin.engine.krylov.ReusingSolver`: GMRES preconditioned by the held
#: factorization, path ``"reuse"``); docs/design-notes.md gives the measured fill ratios.
MAX_REFACTOR_FILL = 8.0
#: ``linear_solver="auto"`` orders the refactorization's fresh factorizations by METIS's
#: nested dissection from this many coordinates on, when `pymetis` is installed (the
#: ``meshes`` extra): on the lattice at 10^4 bodies (3·10^4 coordinates) it and COLAMD
#: give the same fill, at 10^5 METIS's refactorization is twice as fast
#: (docs/design-notes.md, "Fill-reducing column order").
MIN_METIS_COORDINATES = 30_000
#: ``linear_solver="auto"`` factors a mesh (grid repeats, as many equations as coordinates)
#: with `DissectionSolver` from this many coordinates on (the lattice at 10^4 bodies): its
#: first sample took about half of one SuperLU factorization from 10^4 to 10^6 bodies, the
#: METIS-ordered refactorization's 4.5–6 times (docs/design-notes.md, "Sparse LU on meshes").
MIN_DISSECTION_COORDINATES = 30_000
#: ``linear_solver="auto"`` of forward dynamics factors the saddle matrix (coordinates plus
#: kept equations) densely up to this size, with `RefactorSolver` above.
SADDLE_DENSE_MAX_SIZE = 400
#: ``linear_solver="auto"`` of forward dynamics factors the saddle matrix of a grid model
#: (grid repeats, the coordinates those of the bodies) from this size on afresh at every
#: factorization (`MESH_SADDLE_SOLVER`) instead of refactoring it with `RefactorSolver`: on
#: lattices with masses a fresh SuperLU's first sample took 0.35–0.77 of the
#: refactorization's from 3·10^3 bodies (18 018 unknowns) to 10^4, its step 0.60–1.04 of
#: it; at 10^5 bodies first samples of 14–20 s against 92–152 s,
#: and a step that factors (a moving lattice) 15–19 s against 43 s (docs/design-notes.md,
#: "Forward dynamics of lattices").
MIN_MESH_SADDLE_SIZE = 18_000
#: The solver of a grid model's saddle matrix above `MIN_MESH_SADDLE_SIZE`: ``"superlu"``
#: (COLAMD, `SuperLUSolver`), measured as fast as or faster than ``"dissection"``
#: (`DissectionSolver`: the bodies' coordinates and multipliers in the geometric nested
#: dissection of where they are drawn) on every saddle measured: the dissection's fill was
#: 0.85–1.4 times COLAMD's, its factorization and solves no faster.
MESH_SADDLE_SOLVER = "superlu"
#: ``linear_solver="auto"`` or ``"dense"`` of forward dynamics runs the compiled block
#: stepper (`sparsekin.solve._compiled_dynamics`) on a dense LU up to this saddle size
#: (coordinates plus equations), when the model's laws are all built in (``"auto"`` also
#: on a banded LU up to `COMPILED_BANDED_MAX_SIZE`); 0: never the compiled loop.
COMPILED_SADDLE_MAX_SIZE = 400
#: The compiled block stepper factors the saddle matrix in a band (the unknowns in reverse
#: Cuthill–McKee order, `sparsekin.solve._saddle_factorization`) from this size on, when
#: the band is narrow enough (`MAX_BAND_FRACTION`, `MAX_BANDED_WORK`); a dense LU below.
#: Measured (benchmarks/RESULTS.md, "Compiled dynamics loop: dense or banded LU"): the
#: banded loop as fast as the dense one at 29 unknowns, 0.9–1.1x at 41–60 (A03, Task 5),
#: 1.1–1.2x at 53, 1.4–1.7x at 101 (N-four-bars), 6x at 485 (A02); the small models keep
#: the dense LU.
MIN_BANDED_SADDLE_SIZE = 50
#: … when its bandwidths below and above the diagonal add up to at most this fraction of
#: the size (measured: banded within 10 % of dense at 0.44–0.6, A03 and Task 5).
MAX_BAND_FRACTION = 0.5
#: … and ``size · (kl + ku)`` is at most this (a step of the banded loop costs about that;
#: the Python stepper's sparse refactorization, its Python overhead spread over more
#: unknowns, overtakes it on large saddles): measured 1.2–1.4x faster than the Python
#: stepper at 43 000–53 000 (N-four-bar N = 200, lattices 8x8 and 4x32), 0.64x at 216 000
#: (N = 1000).
MAX_BANDED_WORK = 60_000
#: ``linear_solver="auto"`` of forward dynamics tries the compiled block stepper on a
#: banded saddle matrix up to this size (above: the Python stepper, no band computed).
COMPILED_BANDED_MAX_SIZE = 6_000

_SOLVER_CLASSES = {"superlu": SuperLUSolver, "refactor": RefactorSolver, "dense": DenseSolver}


@dataclass(frozen=True)
class Thresholds:
    """The sizes at which a run changes path, each measured (see the module constants).

    Tests and studies of the paths pass other values here instead of changing modules.

    Attributes
    ----------
    compiled_max_coordinates : int
        `COMPILED_MAX_COORDINATES`.
    max_refactor_fill : float
        `MAX_REFACTOR_FILL`.
    min_metis_coordinates : int
        `MIN_METIS_COORDINATES`.
    min_dissection_coordinates : int
        `MIN_DISSECTION_COORDINATES`.
    min_tiled_coordinates : int
        `sparsekin.engine.ordering.MIN_TILED_COORDINATES`: a long repeated chain's first
        pivot order tiled from a short chain from this many coordinates on.
    smallest_tall_lu : int
        `sparsekin.analysis.rank.SMALLEST_TALL_LU`: the redundant equations of an
        overconstrained model found by a sparse LU of the tall Jacobian from this many
        coordinates on (a dense analysis below).
    min_norm_iterations : int
        `sparsekin.engine.multipliers.MIN_NORM_ITERATIONS`: conjugate-gradient iterations for
        the minimum-norm multipliers before the augmented LU takes over.
    saddle_dense_max_size : int
        `SADDLE_DENSE_MAX_SIZE`.
    compiled_saddle_max_size : int
        `COMPILED_SADDLE_MAX_SIZE` (0: never the compiled dynamics loop, dense or banded).
    min_banded_saddle_size : int
        `MIN_BANDED_SADDLE_SIZE`.
    max_band_fraction : float
        `MAX_BAND_FRACTION`.
    max_banded_work : int
        `MAX_BANDED_WORK`.
    compiled_banded_max_size : int
        `COMPILED_BANDED_MAX_SIZE` (0: never the compiled dynamics loop on a banded LU).
    min_mesh_saddle_size : int
        `MIN_MESH_SADDLE_SIZE`.
    mesh_saddle_solver : {"superlu", "dissection"}
        `MESH_SADDLE_SOLVER`.
    """

    compiled_max_coordinates: int = COMPILED_MAX_COORDINATES
    max_refactor_fill: float = MAX_REFACTOR_FILL
    min_metis_coordinates: int = MIN_METIS_COORDINATES
    min_dissection_coordinates: int = MIN_DISSECTION_COORDINATES
    min_tiled_coordinates: int = MIN_TILED_COORDINATES
    smallest_tall_lu: int = SMALLEST_TALL_LU
    min_norm_iterations: int = MIN_NORM_ITERATIONS
    saddle_dense_max_size: int = SADDLE_DENSE_MAX_SIZE
    compiled_saddle_max_size: int = COMPILED_SADDLE_MAX_SIZE
    min_banded_saddle_size: int = MIN_BANDED_SADDLE_SIZE
    max_band_fraction: float = MAX_BAND_FRACTION
    max_banded_work: int = MAX_BANDED_WORK
    compiled_banded_max_size: int = COMPILED_BANDED_MAX_SIZE
    min_mesh_saddle_size: int = MIN_MESH_SADDLE_SIZE
    mesh_saddle_solver: str = MESH_SADDLE_SOLVER


@dataclass(frozen=True)
class SolverPlan:
    """How a run solves its linear systems (`plan_linear_solver`).

    Attributes
    ----------
    loop : {"compiled", "python"}
        The compiled loop first (kinematics: dense LU; dynamics: dense or banded LU; it
        hands over to the Python loop at a sample it cannot solve), or the Python loop all
        the way.
    solver : {"dense", "refactor", "superlu", "dissection"}
        The linear solver of the Python loop (``"dissection"``: `DissectionSolver`,
        ``"auto"`` on meshes only).
    ordering : {"colamd", "metis"}
        A refactorization's fill-reducing order.
    chord : bool
        Chord Newton after the first sample (every path but ``"superlu"``).
    reuse_fill : float or None
        Reuse the refactorization across samples once its fill-in exceeds this many
        entries per Jacobian entry (``"auto"`` only); None: never.
    thresholds : Thresholds
    points : ndarray or None
        Where the bodies are drawn, shape (n_bodies, 2): the places `DissectionSolver` cuts
        between (``"dissection"`` only).
    take_out_factors : bool
        `DissectionSolver`'s: solves on its factors taken out of SuperLU (the kinematics),
        or SuperLU's own (forward dynamics's saddle matrix, factored about once a step).
    lean : bool
        `RefactorSolver`'s: without a permuted copy of the pattern (forward dynamics's
        saddle matrix, refactored every tens of steps: 4 bytes per entry fewer for a
        refactorization ~18 % slower).
    """

    loop: str
    solver: str
    ordering: str = "colamd"
    chord: bool = True
    reuse_fill: float | None = None
    thresholds: Thresholds = field(default_factory=Thresholds)
    points: np.ndarray | None = field(default=None, compare=False, repr=False)
    take_out_factors: bool = True
    lean: bool = False

    def make_solver(self):
        """A fresh linear solver of the plan."""
        if self.solver == "dissection":
            return DissectionSolver(self.points, self.take_out_factors)
        if self.solver == "refactor":
            return RefactorSolver(ordering=self.ordering, lean=self.lean)
        return _SOLVER_CLASSES[self.solver]()

    def reuses(self, linear_solver, nnz: int) -> bool:
        """Whether the run should go on reusing `linear_solver`'s factorization across samples:
        a mesh's `DissectionSolver` (it has no refactorization), or a refactorization with
        more fill-in than `reuse_fill` per entry of a Jacobian of `nnz` entries."""
        if self.reuse_fill is None:
            return False
        if isinstance(linear_solver, DissectionSolver):
            return True
        return isinstance(linear_solver, RefactorSolver) and linear_solver.nnz_factors > self.reuse_fill * nnz

    def reusing(self, linear_solver):
        """`linear_solver` wrapped to reuse its factorization, which it holds already."""
        return ReusingSolver(linear_solver, factored=True)


def plan_linear_solver(discretization: Discretization, linear_solver: str = "auto",
                       thresholds: Thresholds | None = None) -> SolverPlan:  # fmt: skip
    """The plan of a run of `discretization` with the `linear_solver` asked for (one of
    `LINEAR_SOLVERS`, validated by the caller: `sparsekin.solve.options.SolveOptions`)."""
    thresholds = Thresholds() if thresholds is None else thresholds
    pattern = discretization.constraints
    n = pattern.n_coordinates
    auto = linear_solver == "auto"
    solver = ("dense" if n <= thresholds.compiled_max_coordinates else "refactor") if auto else linear_solver
    compiled = (
        solver == "dense"
        and pattern.n_equations == n
        and (n > 0 or pattern.n_equations > 0)
        and supports_compiled(discretization.mechanism)
    )
    metis = auto and n >= thresholds.min_metis_coordinates and metis_installed()
    if auto and solver == "refactor" and n >= thresholds.min_dissection_coordinates and _is_mesh(discretization):
        return SolverPlan(loop="python", solver="dissection", reuse_fill=thresholds.max_refactor_fill,
                          thresholds=thresholds, points=_drawn_places(discretization))  # fmt: skip
    return SolverPlan(
        loop="compiled" if compiled else "python",
        solver=solver,
        ordering="metis" if metis else "colamd",
        chord=solver != "superlu",
        reuse_fill=thresholds.max_refactor_fill if auto else None,
        thresholds=thresholds,
    )


def _is_mesh(discretization: Discretization) -> bool:
    """Whether the model is a mesh `DissectionSolver` takes: a grid model (`_is_grid`) with as
    many equations as coordinates (an overconstrained grid keeps the refactorization of its
    reduced system)."""
    pattern = discretization.constraints
    return _is_grid(discretization) and pattern.n_equations == pattern.n_coordinates


def _is_grid(discretization: Discretization) -> bool:
    """Whether the model has grid repeats and its coordinates are those of the bodies."""
    pattern, mechanism = discretization.constraints, discretization.mechanism
    return (any(copies.is_grid for copies in mechanism.copies)
            and pattern.n_coordinates == COORDINATES_PER_BODY * mechanism.n_bodies)  # fmt: skip


def _drawn_places(discretization: Discretization) -> np.ndarray:
    """Where the bodies are drawn, shape (n_bodies, 2): their origins."""
    return discretization.constraints.initial_coordinates.reshape(-1, COORDINATES_PER_BODY)[:, :2].copy()


def plan_saddle_solver(size: int, linear_solver: str = "auto", thresholds: Thresholds | None = None,
                       compilable: bool = False, discretization: Discretization | None = None) -> SolverPlan:  # fmt: skip
    """The plan of forward dynamics's saddle matrix of `size` unknowns (coordinates plus
    kept equations) with the `linear_solver` asked for (one of `LINEAR_SOLVERS`):
    ``"dense"`` up to `Thresholds.saddle_dense_max_size` with ``"auto"``, ``"refactor"``
    above, and for a grid model (its `discretization` given: grid repeats, the
    coordinates those of the bodies; redundant equations may be left out) from
    `Thresholds.min_mesh_saddle_size` on `Thresholds.mesh_saddle_solver`, a fresh
    factorization each time (``"superlu"``; or ``"dissection"``: `DissectionSolver` on the
    saddle matrix, the bodies' unknowns in a nested dissection of where they are drawn,
    with SuperLU's own solves); never reused across steps (the integrator holds its own
    factorization while Newton contracts).  A dense plan of a `compilable` model (its laws
    all built in) up to `Thresholds.compiled_saddle_max_size`, or an ``"auto"`` one up to
    `Thresholds.compiled_banded_max_size`, runs the compiled block stepper (loop
    ``"compiled"``, `sparsekin.solve._compiled_dynamics`; its own LU, dense or banded, is
    planned after the start, when the saddle pattern is known:
    `plan_compiled_factorization`), else the Python loop; error-controlled steps (``rtol``)
    as well as fixed ones (the compiled loop runs `sparsekin.solve.error_control`'s
    controller, `sparsekin.solve._error_control_kernels`).

    >>> plan_saddle_solver(60, compilable=True).loop, plan_saddle_solver(60, compilable=False).loop
    ('compiled', 'python')
    >>> plan = plan_saddle_solver(485, compilable=True)
    >>> plan.loop, plan.solver
    ('compiled', 'refactor')
    """
    thresholds = Thresholds() if thresholds is None else thresholds
    auto = linear_solver == "auto"
    if auto:
        if (discretization is not None and size >= max(thresholds.min_mesh_saddle_size, 1)
                and size > thresholds.saddle_dense_max_size and _is_grid(discretization)):  # fmt: skip
            if thresholds.mesh_saddle_solver not in ("superlu", "dissection"):
                raise ValueError("`Thresholds.mesh_saddle_solver` must be 'superlu' or 'dissection', got "
                                 f"{thresholds.mesh_saddle_solver!r}.")  # fmt: skip
            if thresholds.mesh_saddle_solver == "dissection":
                return SolverPlan(loop="python", solver="dissection", chord=False, thresholds=thresholds,
                                  points=_drawn_places(discretization), take_out_factors=False)  # fmt: skip
            return SolverPlan(loop="python", solver=thresholds.mesh_saddle_solver, chord=False, thresholds=thresholds)
        linear_solver = "dense" if size <= thresholds.saddle_dense_max_size else "refactor"
    compiled = compilable and thresholds.compiled_saddle_max_size > 0 and (
        (linear_solver == "dense" and size <= thresholds.compiled_saddle_max_size)
        or (auto and thresholds.min_banded_saddle_size <= size <= thresholds.compiled_banded_max_size))  # fmt: skip
    return SolverPlan(loop="compiled" if compiled else "python", solver=linear_solver, chord=False,
                      thresholds=thresholds, lean=True)  # fmt: skip


def plan_compiled_factorization(size: int, lower: int | None, upper: int | None,
                                thresholds: Thresholds | None = None) -> str | None:  # fmt: skip
    """How the compiled block stepper factors a saddle matrix of `size` unknowns whose
    bandwidths below and above the diagonal are `lower` and `upper` in reverse
    Cuthill–McKee order (None: not computed): ``"banded"`` from
    `Thresholds.min_banded_saddle_size` to `Thresholds.compiled_banded_max_size` when
    ``lower + upper`` is at most `Thresholds.max_band_fraction` of the size and
    ``size * (lower + upper)`` at most `Thresholds.max_banded_work`, else
    ``"dense"`` up to `Thresholds.compiled_saddle_max_size`, else None (the Python stepper).

    >>> plan_compiled_factorization(485, 9, 9), plan_compiled_factorization(41, None, None)
    ('banded', 'dense')
    >>> print(plan_compiled_factorization(5000, 2000, 2000))
    None
    """
    thresholds = Thresholds() if thresholds is None else thresholds
    if (lower is not None and upper is not None
            and thresholds.min_banded_saddle_size <= size <= thresholds.compiled_banded_max_size
            and lower + upper <= thresholds.max_band_fraction * size
            and size * (lower + upper) <= thresholds.max_banded_work):  # fmt: skip
        return "banded"
    if size <= thresholds.compiled_saddle_max_size:
        return "dense"
    return None
