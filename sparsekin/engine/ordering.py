"""Orders for the LU of a Jacobian: a pivot order tiled from a short chain, and a
fill-reducing column order for meshes.

`fill_reducing_column_order` orders the columns of any sparse matrix (square or tall) by
nested dissection of its column intersection graph: METIS's (the ``meshes`` extra) or
level-set separators without dependency.  The rest of this docstring is about chains.

The first factorization of `RefactorSolver` runs SuperLU (COLAMD ordering, partial
pivoting) to fix the order in which the equations are eliminated and the coordinate each
is pivoted on; every later factorization reuses them.  On a chain of 10^5 repeated units
that first SuperLU costs seconds and more memory than the rest of the run.  But a copy of
a unit deep in a chain is eliminated like a copy deep in a short chain: `tiled_ordering`
factors the same mechanism with a few copies of each unit, and repeats the order it found
for a middle copy over every copy of the long chain (the first and last copies take the
short chain's first and last).  When the units vary in a cycle (copies drawn at eleven
phases, say), the short chain holds a whole cycle and each copy takes the order of the
copy of its phase.

The order is a suggestion: `RefactorSolver` refactors on it with its usual guard (pivot
ratio, growth), and falls back to SuperLU when the guard trips.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import ModelError
from ..model.mechanism import Analysis
from ..model.units import Cycle, Step
from .assembly import Assembler
from .discretization import Discretization, discretize

__all__ = [
    "tiled_ordering",
    "hub_last_ordering",
    "hub_coordinates",
    "HUB_DEGREE",
    "fill_reducing_column_order",
    "fill_reducing_row_order",
    "geometric_column_order",
    "metis_installed",
    "MIN_TILED_COORDINATES",
    "DISSECTION_LEAF_SIZE",
]

#: Below this many coordinates SuperLU on the whole model is quick: no tiling.
MIN_TILED_COORDINATES = 30_000
#: Copies of each unit in the short chain besides the first and the last: a whole cycle of
#: varied units (at most this many), or one.
MAX_MIDDLE_COPIES = 64
#: A coordinate with more Jacobian entries than this is a hub's: many bodies attached to one.
HUB_DEGREE = 48
#: Parts of the column graph of at most this many columns are not dissected further (they
#: keep their breadth-first order): below about this size a separator saves less fill than
#: it costs in balance (docs/design-notes.md, "Fill-reducing column order").
DISSECTION_LEAF_SIZE = 16


def tiled_ordering(discretization: Discretization, t: float = 0.0):
    """``(perm_r, perm_c)`` for the first factorization of ``jacobian.T`` (SuperLU's
    convention: ``Pr A Pc = L U``), tiled from a short chain; None if the mechanism has no
    repeats, names a copy that the short chain lacks (an own driver on ``u4999.crank``,
    a repeat's `first`), or the tiling does not give a permutation.

    Parameters
    ----------
    discretization : Discretization
        The mechanism's arrays; its constraints square.
    t : float
        The time of the first sample (the short chain's Jacobian is taken there, at its
        drawing).
    """
    mechanism, pattern = discretization.mechanism, discretization.constraints
    if not mechanism.copies or pattern.n_equations != pattern.n_coordinates:
        return None
    if any(c.is_grid or c.total("bodies") != c.count * c.n_bodies or c.n_left_out() for c in mechanism.copies):
        return None  # a grid, or parts left out of some copies: no short chain to tile from
    middles = [_middle_copies(copies) for copies in mechanism.copies]
    try:
        short_mechanism = dataclasses.replace(
            mechanism,
            analysis=Analysis(),
            repeats=tuple(dataclasses.replace(c.repeat, count=min(c.count, m + 2))
                          for c, m in zip(mechanism.copies, middles)),  # fmt: skip
        )
    except ModelError:
        # The model names a copy beyond the short chain (its own driver on ``u4999.crank``,
        # another repeat's `first`): no short chain, SuperLU orders the long one.
        return None
    short = discretize(short_mechanism)
    short_pattern = short.constraints
    assembler = Assembler(short)
    assembler.set_time(t)
    assembler.fill_residual_jacobian(short_pattern.initial_coordinates)
    try:
        from scipy.sparse.linalg import splu  # here: a long chain's run, not every run

        lu = splu(assembler.jacobian.T.tocsc(), permc_spec="COLAMD")
    except RuntimeError:  # singular at the drawing: let the long chain's own factorization say so
        return None
    # The short chain's assignment: equation e is eliminated at step perm_c[e], pivoted on
    # the coordinate that goes to that step.
    steps = lu.perm_c.astype(np.int64)
    coordinate_at_step = np.empty_like(steps)
    coordinate_at_step[lu.perm_r] = np.arange(steps.size)
    pivot = coordinate_at_step[steps]

    equation_map, equation_shift = _equation_map(discretization, short, middles)
    # big equation -> its representative in the short chain, shifted by whole copies
    key = steps[equation_map] + equation_shift * steps.size
    order = np.argsort(key, kind="stable")
    perm_c = np.empty_like(order)
    perm_c[order] = np.arange(order.size)
    # its pivot: the representative's pivot coordinate, in the same shifted copy
    short_pivot = pivot[equation_map]
    pivot_body = short_pivot // 3
    big_body = _unmap(pivot_body, equation_shift, mechanism, short_mechanism)
    if big_body is None:
        return None
    pivot_coordinate = 3 * big_body + short_pivot % 3
    perm_r = np.full(pivot_coordinate.size, -1, dtype=np.int64)
    perm_r[pivot_coordinate] = perm_c
    if np.any(perm_r < 0):  # two equations pivoted on one coordinate: not a permutation
        return None
    return perm_r, perm_c


def hub_coordinates(pattern) -> np.ndarray:
    """The three coordinates of every body that many others are attached to (a crankshaft,
    a frame, a hub): one of its columns of the Jacobian has more than `HUB_DEGREE` entries."""
    degree = np.bincount(pattern.indices, minlength=pattern.n_coordinates)
    bodies = np.flatnonzero((degree > HUB_DEGREE).reshape(-1, 3).any(axis=1))
    return (3 * bodies[:, None] + np.arange(3)).ravel()


def hub_last_ordering(discretization: Discretization, t: float = 0.0):
    """``(perm_r, perm_c)`` (as `tiled_ordering`'s) that eliminates a hub's coordinates last;
    None without a hub, or when the hub's own equations do not pivot on it.

    A hub is a body many others are attached to: its coordinates' columns are nearly dense.
    SuperLU's COLAMD with partial pivoting may pivot on them early, after which every later
    copy fills in against them (1000 legs welded to one crankshaft ran 30–50× slower per
    step than the same legs welded one to the next).  Here the equations that involve only
    hub coordinates (the hub's joint to the ground, its driver) are pivoted on them, last;
    the rest of the Jacobian, without the hub's columns, is ordered by SuperLU (COLAMD) at
    the start of its constraints (`~ConstraintPattern.initial_coordinates`).  The hub's
    columns then fill only their own rows of L (three per hub body), and the matrix is block
    triangular: no other fill.
    """
    pattern = discretization.constraints
    if pattern.n_equations != pattern.n_coordinates or not pattern.n_equations:
        return None
    hub = np.zeros(pattern.n_coordinates, dtype=bool)
    hub[hub_coordinates(pattern)] = True
    if not hub.any():
        return None
    assembler = Assembler(discretization)
    assembler.set_time(t)
    assembler.fill_residual_jacobian(pattern.initial_coordinates)
    jacobian = assembler.jacobian
    row_of_entry = np.repeat(np.arange(pattern.n_equations), np.diff(pattern.indptr))
    hub_only = np.bincount(row_of_entry[~hub[pattern.indices]], minlength=pattern.n_equations) == 0
    if hub_only.sum() != hub.sum():
        return None
    from scipy.sparse.linalg import splu  # here: a hub's run, not every run

    perm_r = np.empty(pattern.n_coordinates, dtype=np.int64)
    perm_c = np.empty(pattern.n_equations, dtype=np.int64)
    first = 0
    for rows, columns in ((~hub_only, ~hub), (hub_only, hub)):
        block = jacobian[np.flatnonzero(rows)][:, np.flatnonzero(columns)]
        try:
            lu = splu(block.T.tocsc(), permc_spec="COLAMD")
        except RuntimeError:  # singular without the hub: SuperLU orders the whole
            return None
        perm_c[rows] = first + lu.perm_c
        perm_r[columns] = first + lu.perm_r
        first += block.shape[0]
    return perm_r, perm_c


def _middle_copies(copies) -> int:
    """How many middle copies the short chain needs: a whole cycle of the variations."""
    variations = copies.repeat.vary.values()
    if any(isinstance(v, Step) for v in variations):
        return 1  # no period: every middle copy takes the one middle copy's order
    lengths = [len(v.values) for v in variations if isinstance(v, Cycle)]
    return min(int(np.lcm.reduce(lengths)) if lengths else 1, MAX_MIDDLE_COPIES)


def _representative(k: np.ndarray, count: int, short_count: int, middles: int) -> np.ndarray:
    """The short chain's copy that copy k of the long one takes its order from."""
    s = 1 + (k - 1) % middles
    s = np.where(k == 0, 0, s)
    if count > short_count:
        s = np.where(k == count - 1, short_count - 1, s)
    else:
        s = k
    return s


def _equation_map(long: Discretization, short: Discretization, middles):
    """For every equation of the long chain: its representative in the short one, and the
    copy shift."""
    mechanism, pattern = long.mechanism, long.constraints
    short_pattern, short = short.constraints, short.mechanism
    maps, shifts = [], []
    for kind in ("joints", "drivers"):
        first = 0 if kind == "joints" else mechanism.n_joints
        first_short = 0 if kind == "joints" else short.n_joints
        own = len(mechanism.own(kind))
        element, element_short = [np.arange(own)], [np.arange(own)]
        shift = [np.zeros(own, dtype=np.int64)]
        for c, cs, m in zip(mechanism.copies, short.copies, middles):
            size = c.n_joints if kind == "joints" else c.n_drivers
            start = c.first_joint if kind == "joints" else c.first_driver
            start_short = cs.first_joint if kind == "joints" else cs.first_driver
            k = np.repeat(np.arange(c.count), size)
            local = np.tile(np.arange(size), c.count)
            s = _representative(k, c.count, cs.count, m)
            element.append(start + k * size + local)
            element_short.append(start_short + s * size + local)
            shift.append(k - s)
        element, element_short, shift = (np.concatenate(a) for a in (element, element_short, shift))
        rows_first = pattern.element_first_row[first + element]
        counts = pattern.element_first_row[first + element + 1] - rows_first
        within = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
        maps.append(np.repeat(short_pattern.element_first_row[first_short + element_short], counts) + within)
        shifts.append(np.repeat(shift, counts))
    return np.concatenate(maps), np.concatenate(shifts)


def _unmap(short_body, shift, mechanism, short):
    """The long chain's body that is the short chain's body `short_body` moved by `shift`
    copies of its repeat; None when that leaves the copies (or moves an own body)."""
    out = np.full_like(short_body, -1)
    own = short_body < len(short.own("bodies"))
    if np.any(own & (shift != 0)):
        return None
    out[own] = short_body[own]
    for c, cs in zip(mechanism.copies, short.copies):
        inside = (short_body >= cs.first_body) & (short_body < cs.first_body + cs.count * cs.n_bodies)
        within = short_body[inside] - cs.first_body
        k = within // cs.n_bodies + shift[inside]
        if np.any((k < 0) | (k >= c.count)):
            return None
        out[inside] = c.first_body + k * c.n_bodies + within % cs.n_bodies
    return None if np.any(out < 0) else out


def fill_reducing_column_order(matrix, *, method: str = "auto", block: int = 1) -> np.ndarray:
    """A fill-reducing column order for the LU factorization of a sparse matrix.

    Nested dissection of the column intersection graph (columns are adjacent when they
    share a row: the pattern of ``matrix.T @ matrix``).  For any row pivoting, the fill of
    ``L + U`` of ``matrix[:, order]`` is bounded by that of the Cholesky factor of
    ``matrix.T @ matrix`` in this order (George and Ng), which nested dissection keeps
    small on planar meshes.

    Parameters
    ----------
    matrix : sparse array, shape (m, n), m >= n
        For a Jacobian: rows are equations, columns coordinates; a tall matrix (more
        equations than coordinates) is accepted.  Only the pattern is read.
    method : {"auto", "metis", "level-sets"}
        ``"metis"``: METIS's multilevel nested dissection (``pip install
        sparsekin[meshes]``, the `pymetis` binding).  ``"level-sets"``: separators from
        breadth-first level structures (`sparsekin.engine._ordering_kernels`), no
        dependency, but more fill than METIS and than SuperLU's COLAMD on the lattice
        (docs/design-notes.md, "Fill-reducing column order").  ``"auto"``: METIS if
        installed, else level sets.
    block : int
        Columns come in consecutive blocks of this many (a body's three coordinates),
        kept together in the order: the blocks are ordered by the graph of the matrix
        whose column k is the union of block k's, a graph `block` times smaller, which
        METIS orders several times faster (docs/design-notes.md, "Sparse LU on meshes").

    Returns
    -------
    ndarray of int64, shape (n,)
        ``order[k]`` is the column eliminated k-th: factor ``matrix[:, order]``.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.sparse import csr_array
    >>> order = fill_reducing_column_order(csr_array(np.eye(4) + np.eye(4, k=1)))
    >>> sorted(order.tolist())
    [0, 1, 2, 3]
    """
    if method not in ("auto", "metis", "level-sets"):
        raise ValueError(f"`method` must be 'auto', 'metis' or 'level-sets', got {method!r}.")
    _check_matrix_and_block(matrix, block)
    order = _dissection(*_column_graph(matrix, int(block)), method)
    if block == 1:
        return order
    return (block * order[:, None] + np.arange(block)).ravel()


def geometric_column_order(matrix, points, *, block: int = 3, groups=None) -> np.ndarray:
    """A fill-reducing column order for the LU of a mesh's Jacobian from where its bodies are drawn.

    Nested dissection of the bodies' graph (bodies adjacent when an equation holds both;
    a body's `block` coordinates, consecutive columns, kept together) with geometric
    cuts: each part is cut at the median of its bodies' places along its longer side, the
    bodies beside the cut on one side are the separator, ordered after both sides
    (`sparsekin.engine._ordering_kernels.geometric_dissection`).  On a planar mesh that is
    METIS's fill for a small share of its time, without the ``meshes`` extra
    (docs/design-notes.md, "Sparse LU on meshes").

    With `groups` the matrix is square and structurally symmetric, its unknowns held by
    the bodies (forward dynamics's saddle matrix: each body's coordinates and the
    multipliers of the equations placed with it): ``groups[j]`` is the body of unknown j,
    bodies are adjacent when an entry couples their unknowns (the graph of the matrix,
    not of its columns' intersections: a symmetric matrix is factored on its diagonal's
    side), and a body's unknowns are kept together in their own order.

    Parameters
    ----------
    matrix : sparse array, shape (m, n), m >= n
        The Jacobian: rows are equations, columns coordinates; only the pattern is read.
    points : array_like, shape (n // block, 2)
        Each body's place in the plane (its origin at the drawing, say).
    block : int
        Coordinates per body (without `groups`).
    groups : array_like of int, shape (n,), optional
        The body of each column, each body holding one at least (instead of `block`).

    Returns
    -------
    ndarray of int64, shape (n,)
        ``order[k]`` is the column eliminated k-th: factor ``matrix[:, order]``.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.sparse import csr_array
    >>> chain = csr_array(np.eye(6) + np.eye(6, k=2))  # three bodies of two coordinates
    >>> geometric_column_order(chain, [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]], block=2).size
    6
    """
    n = _check_matrix_and_block(matrix, block if groups is None else 1)
    points = np.ascontiguousarray(points, dtype=float)
    n_bodies = n // block if groups is None else points.shape[0]
    if points.shape != (n_bodies, 2) or not np.all(np.isfinite(points)):
        raise ValueError(f"`points` must be {n_bodies} finite places (x, y), one a body, got shape {points.shape}.")
    from ._ordering_kernels import geometric_dissection

    if groups is None:
        order = geometric_dissection(*_column_graph(matrix, int(block)), points, DISSECTION_LEAF_SIZE)
        return (block * order[:, None] + np.arange(block)).ravel()
    groups = _checked_groups(groups, matrix.shape, n_bodies)
    order = geometric_dissection(*_group_graph(matrix, groups, n_bodies), points, DISSECTION_LEAF_SIZE)
    place = np.empty(n_bodies, dtype=np.int64)
    place[order] = np.arange(n_bodies)
    return np.argsort(place[groups], kind="stable")  # each body's columns in their own order


def _check_matrix_and_block(matrix, block) -> int:
    """Refuse what a column order cannot take; the number of columns."""
    if not hasattr(matrix, "tocsr") or len(matrix.shape) != 2:
        raise ValueError(f"`matrix` must be a 2-D scipy.sparse array, got {type(matrix).__name__}.")
    m, n = matrix.shape
    if m < n:
        raise ValueError(f"`matrix` must have at least as many rows as columns, got shape {matrix.shape}.")
    if isinstance(block, bool) or not isinstance(block, (int, np.integer)) or block < 1 or n % block:
        raise ValueError(f"`block` must be a whole number >= 1 dividing the {n} columns, got {block!r}.")
    return n


def fill_reducing_row_order(matrix, *, method: str = "auto") -> np.ndarray:
    """A fill-reducing order of the rows of a sparse matrix (any shape): nested dissection
    of its row intersection graph (rows are adjacent when they share a column: the pattern
    of ``matrix @ matrix.T``), as `fill_reducing_column_order` orders columns.  For the LU
    of a tall Jacobian's transpose that picks independent rows
    (`sparsekin.analysis.tall_lu`)."""
    if method not in ("auto", "metis", "level-sets"):
        raise ValueError(f"`method` must be 'auto', 'metis' or 'level-sets', got {method!r}.")
    if not hasattr(matrix, "tocsr") or len(matrix.shape) != 2:
        raise ValueError(f"`matrix` must be a 2-D scipy.sparse array, got {type(matrix).__name__}.")
    return _dissection(*_column_graph(matrix.T), method)


def _dissection(xadj: np.ndarray, adjacency: np.ndarray, method: str) -> np.ndarray:
    """Nested dissection of a graph by `method` (``"auto"``: METIS if installed)."""
    if method == "auto":
        method = "metis" if metis_installed() else "level-sets"
    if method == "metis":
        return _metis_order(xadj, adjacency)
    from ._ordering_kernels import nested_dissection

    return nested_dissection(xadj, adjacency, DISSECTION_LEAF_SIZE)


def metis_installed() -> bool:
    """Whether `pymetis` (the ``meshes`` extra) can be imported."""
    import importlib.util

    return importlib.util.find_spec("pymetis") is not None


def _column_graph(matrix, block: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """``(xadj, adjacency)``: the column intersection graph of `matrix` with its columns
    merged in consecutive blocks of `block`, without loops."""
    from scipy.sparse import csr_array

    csr = matrix if getattr(matrix, "format", None) == "csr" else csr_array(matrix)
    shape = (csr.shape[0], csr.shape[1] // block)
    pattern = csr_array((np.ones(csr.nnz, dtype=np.float32), csr.indices // block, csr.indptr.copy()), shape=shape)
    return _without_loops(pattern.T @ pattern)


def _group_graph(matrix, groups: np.ndarray, n_groups: int) -> tuple[np.ndarray, np.ndarray]:
    """``(xadj, adjacency)``: the graph of a square `matrix` (and its transpose) with row
    and column j merged into vertex ``groups[j]``, without loops."""
    from scipy.sparse import coo_array

    coo = coo_array(matrix)
    ones = np.ones(coo.nnz, dtype=np.float32)
    merged = coo_array((ones, (groups[coo.row], groups[coo.col])), shape=(n_groups, n_groups)).tocsr()
    return _without_loops(merged + merged.T)


def _without_loops(graph) -> tuple[np.ndarray, np.ndarray]:
    graph = graph.tocsr()
    graph.setdiag(0.0)
    graph.eliminate_zeros()
    return graph.indptr.astype(np.int64), graph.indices.astype(np.int64)


def _checked_groups(groups, shape: tuple, n_groups: int) -> np.ndarray:
    """`groups` as int64, or a ValueError: one group of ``range(n_groups)`` per unknown of a
    square matrix, each group holding one at least."""
    groups = np.asarray(groups)
    n = shape[1]
    valid = (shape[0] == n and groups.shape == (n,) and groups.dtype.kind in "iu"
             and (n == 0 or (groups.min() >= 0 and groups.max() < n_groups)))  # fmt: skip
    if not valid or np.count_nonzero(np.bincount(groups, minlength=n_groups)) != n_groups:
        raise ValueError(f"`groups` must give each unknown of the square {shape} matrix one of the {n_groups} bodies, "
                         "each body holding one at least.")  # fmt: skip
    return groups.astype(np.int64, copy=False)


def _metis_order(xadj: np.ndarray, adjacency: np.ndarray) -> np.ndarray:
    """METIS_NodeND through pymetis: its `perm` (new position -> vertex) is the order."""
    try:
        import pymetis
    except ImportError:
        raise ImportError("METIS orderings need pymetis: pip install 'sparsekin[meshes]'") from None
    if xadj.size == 1:
        return np.zeros(0, dtype=np.int64)
    graph = pymetis.CSRAdjacency(xadj.astype(np.int32), adjacency.astype(np.int32))
    perm, _ = pymetis.nested_dissection(graph)
    return np.asarray(perm, dtype=np.int64)
