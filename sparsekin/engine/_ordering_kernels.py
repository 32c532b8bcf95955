"""numba kernel of the nested-dissection ordering (`sparsekin.engine.ordering.fill_reducing_column_order`).

Symbols (for this kernel only): a graph of ``n`` vertices in CSR form, ``xadj``
(shape (n + 1,)) and ``adjacency`` (the neighbours of vertex v are
``adjacency[xadj[v]:xadj[v + 1]]``, no self loops, each edge stored both ways).  The
result ``order`` lists the vertices in elimination order.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .._jit import JIT as _JIT


#: Least share of a part on either side of its separator level: lower admits smaller
#: separators at the price of deeper recursion; a third is the usual choice for level
#: structures (George and Liu).
_BALANCE = 1.0 / 3.0


@njit(**_JIT)
def _relabel(label, vertices, lo, hi, value):
    """Give ``vertices[lo:hi]`` the label `value`."""
    for k in range(lo, hi):
        label[vertices[k]] = value


@njit(**_JIT)
def _grown(array):
    """`array` in an array twice as long."""
    grown = np.empty(2 * array.size, dtype=array.dtype)
    grown[: array.size] = array
    return grown


@njit(**_JIT)
def _level_structure(xadj, adjacency, label, part, root, level, queue):
    """Breadth-first levels from `root` within the vertices labelled `part`.

    Fills ``level[v]`` (vertices reached) and ``queue[:count]`` (them, by level).
    Returns ``(count, depth)``: vertices reached and levels.
    """
    queue[0] = root
    level[root] = 0
    head, tail = 0, 1
    while head < tail:
        v = queue[head]
        head += 1
        for p in range(xadj[v], xadj[v + 1]):
            w = adjacency[p]
            if label[w] == part and level[w] < 0:
                level[w] = level[v] + 1
                queue[tail] = w
                tail += 1
    return tail, level[queue[tail - 1]] + 1


@njit(**_JIT)
def nested_dissection(xadj, adjacency, leaf_size):
    """Elimination order of the graph's vertices by nested dissection with level-set separators.

    Each part of the graph is split by one level of a breadth-first level structure rooted
    at a pseudo-peripheral vertex (George and Liu's automatic nested dissection): the level
    with fewest vertices among those leaving at least `_BALANCE` of the part on either
    side, thinned of the vertices with no neighbour beyond it.  Both sides are ordered
    first (recursively), the separator last.  A part that is not connected is split into
    its reached component and the rest without a separator; parts of at most `leaf_size`
    vertices keep their breadth-first order.  Cost O((n + edges) log n).
    """
    n = xadj.size - 1
    order = np.empty(n, dtype=np.int64)
    vertices = np.arange(n)  # vertices[lo:hi] are the part whose order fills order[lo:hi]
    label = np.zeros(n, dtype=np.int64)
    level = np.full(n, -1, dtype=np.int64)
    queue = np.empty(n, dtype=np.int64)
    scratch = np.empty(n, dtype=np.int64)
    stack_lo = np.empty(64, dtype=np.int64)
    stack_hi = np.empty_like(stack_lo)
    stack_lo[0], stack_hi[0] = 0, n
    top = 1
    next_label = 1
    while top > 0:
        if top + 2 > stack_lo.size:
            stack_lo = _grown(stack_lo)
            stack_hi = _grown(stack_hi)
        top -= 1
        lo, hi = stack_lo[top], stack_hi[top]
        size = hi - lo
        if size == 0:
            continue
        part = label[vertices[lo]]
        # A pseudo-peripheral root: restart from the farthest vertex of least degree while
        # the depth grows (at most 4 sweeps).
        root = vertices[lo]
        depth = 0
        count = 0
        for sweep in range(4):
            for k in range(lo, hi):
                level[vertices[k]] = -1
            count, new_depth = _level_structure(xadj, adjacency, label, part, root, level, queue)
            grew = new_depth > depth
            depth = new_depth
            if not grew or sweep == 3:
                break
            best, best_degree = root, n + 1
            for k in range(count - 1, -1, -1):
                v = queue[k]
                if level[v] != depth - 1:
                    break
                degree = xadj[v + 1] - xadj[v]
                if degree < best_degree:
                    best, best_degree = v, degree
            if best == root:
                break
            root = best
        if size <= leaf_size and count == size:
            for k in range(count):
                order[lo + k] = queue[k]
            continue
        if count < size:  # not connected: the reached component, then the rest
            n_rest = 0
            for k in range(lo, hi):
                if level[vertices[k]] < 0:
                    scratch[n_rest] = vertices[k]
                    n_rest += 1
            for k in range(count):
                vertices[lo + k] = queue[k]
            for k in range(n_rest):
                vertices[lo + count + k] = scratch[k]
            _relabel(label, vertices, lo, lo + count, next_label)
            _relabel(label, vertices, lo + count, hi, next_label + 1)
            next_label += 2
            stack_lo[top], stack_hi[top] = lo, lo + count
            stack_lo[top + 1], stack_hi[top + 1] = lo + count, hi
            top += 2
            continue
        # Level sizes, and the separator level: fewest vertices with both sides balanced.
        sizes = np.zeros(depth, dtype=np.int64)
        for k in range(count):
            sizes[level[queue[k]]] += 1
        below = 0
        cut, cut_size = -1, n + 1
        for d in range(depth):
            above = size - below - sizes[d]
            if below >= _BALANCE * size and above >= _BALANCE * size and sizes[d] < cut_size:
                cut, cut_size = d, sizes[d]
            below += sizes[d]
        if cut < 0:  # too shallow to balance (a star, a clique): the middle level
            below = 0
            for d in range(depth):
                if below + sizes[d] >= size // 2:
                    cut = d
                    break
                below += sizes[d]
        # Split: side A = levels < cut (+ separator vertices with no neighbour beyond the
        # cut), separator S, side B = levels > cut.
        n_a = 0
        n_s = 0
        for k in range(count):
            v = queue[k]
            lv = level[v]
            if lv == cut:
                beyond = False
                for p in range(xadj[v], xadj[v + 1]):
                    w = adjacency[p]
                    if label[w] == part and level[w] == cut + 1:
                        beyond = True
                        break
                if beyond:
                    scratch[n_s] = v
                    n_s += 1
                    continue
                lv = cut - 1  # thinned: joins side A
            if lv < cut:
                vertices[lo + n_a] = v
                n_a += 1
        n_b = 0
        for k in range(count):
            v = queue[k]
            if level[v] > cut:
                vertices[lo + n_a + n_b] = v
                n_b += 1
        if n_a == size or n_b == size:  # no level separates (a clique): breadth-first order
            for k in range(count):
                order[lo + k] = queue[k]
            continue
        for k in range(n_s):
            vertices[hi - n_s + k] = scratch[k]
            order[hi - n_s + k] = scratch[k]
        _relabel(label, vertices, lo, lo + n_a, next_label)
        _relabel(label, vertices, lo + n_a, lo + n_a + n_b, next_label + 1)
        _relabel(label, vertices, hi - n_s, hi, next_label + 2)
        next_label += 3
        stack_lo[top], stack_hi[top] = lo, lo + n_a
        stack_lo[top + 1], stack_hi[top + 1] = lo + n_a, lo + n_a + n_b
        top += 2
    return order


@njit(**_JIT)
def geometric_dissection(xadj, adjacency, points, leaf_size):
    """Elimination order of the graph's vertices by nested dissection with geometric cuts.

    ``points[v]`` is vertex v's place in the plane (shape (n, 2)).  Each part is cut at
    the median of its points along the longer side of their bounding box (points on the
    cut all go to one side, so a row of bodies drawn on one line stays together); the
    separator is the side's vertices with a neighbour across the cut, on the side with
    fewer of them.  Both sides are ordered first, the separator last; parts of at most
    `leaf_size` vertices keep their order.  Cost O(n log n + edges · depth), no sort.
    """
    n = points.shape[0]
    order = np.arange(n)  # order[lo:hi] holds a part, rearranged to [side A, side B, separator]
    label = np.full(n, -1, dtype=np.int64)  # 2 · part + side, for the part being cut
    scratch = np.empty(n, dtype=np.int64)
    values = np.empty(n)
    left = np.zeros(n, dtype=np.bool_)
    stack_lo = np.empty(64, dtype=np.int64)
    stack_hi = np.empty_like(stack_lo)
    stack_lo[0], stack_hi[0] = 0, n
    top = 1
    part = 0
    while top > 0:
        if top + 2 > stack_lo.size:
            stack_lo = _grown(stack_lo)
            stack_hi = _grown(stack_hi)
        top -= 1
        lo, hi = stack_lo[top], stack_hi[top]
        size = hi - lo
        if size <= leaf_size:
            continue
        low_x = high_x = points[order[lo], 0]
        low_y = high_y = points[order[lo], 1]
        for k in range(lo, hi):
            v = order[k]
            low_x, high_x = min(low_x, points[v, 0]), max(high_x, points[v, 0])
            low_y, high_y = min(low_y, points[v, 1]), max(high_y, points[v, 1])
        axis = 0 if high_x - low_x >= high_y - low_y else 1
        for k in range(size):
            values[k] = points[order[lo + k], axis]
        cut = np.median(values[:size])
        n_left = 0
        for k in range(size):
            left[k] = values[k] < cut
            n_left += left[k]
        if n_left == 0:  # more than half on the lowest value: those on the cut go left
            for k in range(size):
                left[k] = values[k] <= cut
                n_left += left[k]
        if n_left == size:  # all on one point: halve by position
            n_left = size // 2
            for k in range(size):
                left[k] = k < n_left
        a, b = 2 * part, 2 * part + 1
        part += 1
        for k in range(size):
            label[order[lo + k]] = a if left[k] else b
        # Boundary sizes of either side; the separator is the smaller boundary.
        boundary = np.zeros(2, dtype=np.int64)
        for k in range(size):
            v = order[lo + k]
            across = b if left[k] else a
            for p in range(xadj[v], xadj[v + 1]):
                if label[adjacency[p]] == across:
                    boundary[0 if left[k] else 1] += 1
                    break
        separated = a if boundary[0] <= boundary[1] else b
        other = b if separated == a else a
        n_s = 0
        for k in range(size):  # the separator, at the end of the part
            v = order[lo + k]
            if label[v] == separated:
                for p in range(xadj[v], xadj[v + 1]):
                    if label[adjacency[p]] == other:
                        n_s += 1
                        scratch[hi - n_s] = v
                        label[v] = -1  # neither side
                        break
        n_a = n_b = 0
        for k in range(size):  # side A, then side B
            v = order[lo + k]
            if label[v] == a:
                scratch[lo + n_a] = v
                n_a += 1
        for k in range(size):
            v = order[lo + k]
            if label[v] == b:
                scratch[lo + n_a + n_b] = v
                n_b += 1
        for k in range(lo, hi):
            order[k] = scratch[k]
        stack_lo[top], stack_hi[top] = lo, lo + n_a
        stack_lo[top + 1], stack_hi[top + 1] = lo + n_a, lo + n_a + n_b
        top += 2
    return order
