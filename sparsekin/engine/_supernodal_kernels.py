"""numba kernels of the supernodal LU of `sparsekin.engine.supernodal.SupernodalSolver`.

Symbols (for these kernels only):

* ``B`` — the matrix factored, ``B[p, q] = J[rows[p], cols[q]]``: the Jacobian's rows in a
  matching's order (a large entry on the diagonal), its columns in a nested dissection.
  ``B = L U`` with row swaps only *within* a supernode's diagonal block.
* ``S`` — the pattern of ``B + Bᵀ`` (CSR, symmetric), whose elimination tree and fill give
  the supernodes and their fronts; ``post`` relabels it (``B``'s index ``p`` is ``S``'s
  ``post[p]``), ``inv_post`` is its inverse.
* Supernode ``s`` — the indices ``first[s] <= p < first[s + 1]`` (``k`` of them) eliminated
  together; the supernodes come in a postorder of their tree, so the contribution blocks
  of a supernode's children lie on top of a stack when it is assembled.
  ``struct_idx[struct_ptr[s]:struct_ptr[s + 1]]`` (``m`` of them, increasing) are the
  indices after the supernode that its columns of ``L`` and rows of ``U`` reach (fill
  included); its *front* is the dense ``f × f`` matrix (``f = k + m``) on its own indices
  followed by those.
* Factors of ``s`` — ``lower[lower_ptr[s]:]``: the front's first ``k`` columns, ``f × k``
  row-major (the top ``k × k`` holds ``L11``, unit lower, below the diagonal and ``U11`` on
  and above it; then ``L21``); ``upper[upper_ptr[s]:]``: ``U12``, ``k × m`` row-major;
  ``pivots[first[s] + j]``: the row of the supernode (counted from its first) that was
  swapped with row ``j`` at step ``j``.
* Right-hand sides have shape (n, n_rhs): a solve reads each block of the factors once
  for all of them.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .._jit import JIT as _JIT

#: Columns of a panel of a front's blocked LU: the trailing update is a matrix product
#: (BLAS through `np.dot`) of this rank.
PANEL = 32
#: Below this many multiply-adds a trailing update runs as loops (a BLAS call and its
#: temporaries cost more on the small fronts at the leaves of the tree).
_SMALL_UPDATE = 8192


@njit(**_JIT)
def elimination_tree(indptr, indices):
    """The elimination tree of the symmetric pattern ``(indptr, indices)`` (parent -1: a root)."""
    n = indptr.size - 1
    parent = np.full(n, -1, dtype=np.int64)
    ancestor = np.full(n, -1, dtype=np.int64)
    for k in range(n):
        for p in range(indptr[k], indptr[k + 1]):
            i = indices[p]
            while i != -1 and i < k:
                after = ancestor[i]
                ancestor[i] = k
                if after == -1:
                    parent[i] = k
                i = after
    return parent


@njit(**_JIT)
def postorder(parent):
    """A postorder of the forest `parent`, children in increasing order: ``post[p]`` is the
    p-th index visited."""
    n = parent.size
    head = np.full(n, -1, dtype=np.int64)
    following = np.full(n, -1, dtype=np.int64)
    for j in range(n - 1, -1, -1):  # prepended in decreasing order: lists increase
        if parent[j] != -1:
            following[j] = head[parent[j]]
            head[parent[j]] = j
    post = np.empty(n, dtype=np.int64)
    stack = np.empty(n, dtype=np.int64)
    count = 0
    for root in range(n):
        if parent[root] != -1:
            continue
        top = 0
        stack[0] = root
        while top >= 0:
            j = stack[top]
            child = head[j]
            if child == -1:
                top -= 1
                post[count] = j
                count += 1
            else:
                head[j] = following[child]  # the next child on the next visit
                top += 1
                stack[top] = child
    return post


@njit(**_JIT)
def supernode_starts(parent):
    """The first index of each supernode and n (shape (n_supernodes + 1,)): index j joins
    j - 1's supernode when it is j - 1's parent and has no other child (a chain of the tree:
    a separator of the dissection)."""
    n = parent.size
    children = np.zeros(n, dtype=np.int64)
    for j in range(n):
        if parent[j] != -1:
            children[parent[j]] += 1
    starts = np.empty(n + 1, dtype=np.int64)
    count = 0
    for j in range(n):
        if j == 0 or not (parent[j - 1] == j and children[j] == 1):
            starts[count] = j
            count += 1
    starts[count] = n
    return starts[: count + 1].copy()


@njit(**_JIT)
def supernodal_structure(indptr, indices, post, inv_post, first):
    """The fronts' index sets beyond their supernodes (``struct_ptr``, ``struct_idx``) and the
    supernodal tree (``super_parent``, -1 for a root), from the pattern S (its own labels,
    relabelled through `post`/`inv_post`): a supernode's set is its columns' entries of S
    below it and its children's sets beyond it."""
    n_super = first.size - 1
    n = post.size
    struct_ptr = np.zeros(n_super + 1, dtype=np.int64)
    capacity = 4 * n + 16
    struct_idx = np.empty(capacity, dtype=np.int64)
    super_parent = np.full(n_super, -1, dtype=np.int64)
    super_of = np.empty(n, dtype=np.int64)
    for s in range(n_super):
        super_of[first[s] : first[s + 1]] = s
    head = np.full(n_super, -1, dtype=np.int64)  # children lists, built as supernodes end
    following = np.full(n_super, -1, dtype=np.int64)
    mark = np.full(n, -1, dtype=np.int64)
    gathered = np.empty(n, dtype=np.int64)
    for s in range(n_super):
        end = first[s + 1]
        count = 0
        for j in range(first[s], end):
            old = post[j]
            for p in range(indptr[old], indptr[old + 1]):
                i = inv_post[indices[p]]
                if i >= end and mark[i] != s:
                    mark[i] = s
                    gathered[count] = i
                    count += 1
        child = head[s]
        while child != -1:
            for p in range(struct_ptr[child], struct_ptr[child + 1]):
                i = struct_idx[p]
                if i >= end and mark[i] != s:
                    mark[i] = s
                    gathered[count] = i
                    count += 1
            child = following[child]
        start = struct_ptr[s]
        if start + count > capacity:
            capacity = max(2 * capacity, start + count)
            grown = np.empty(capacity, dtype=np.int64)
            grown[:start] = struct_idx[:start]
            struct_idx = grown
        struct_idx[start : start + count] = np.sort(gathered[:count])
        struct_ptr[s + 1] = start + count
        if count > 0:
            p = super_of[struct_idx[start]]
            super_parent[s] = p
            following[s] = head[p]
            head[p] = s
    return struct_ptr, struct_idx[: struct_ptr[n_super]].copy(), super_parent


@njit(**_JIT)
def amalgamated_starts(first, struct_ptr, super_parent, small, zeros_share):
    """Fewer, larger supernodes: a supernode joins its parent when it ends where the parent
    begins and either both are small (at most `small` indices together) or the zeros the
    dense blocks gain are at most `zeros_share` of the joined blocks' entries.  (A child's
    set lies within its parent's indices and set, so the joined set is the parent's.)
    Returns the new first indices (the index sets are then made again)."""
    n_super = first.size - 1
    columns = np.diff(first)  # of the group that ends with each supernode, as groups form
    start = first[:-1].copy()
    needed = np.empty(n_super)  # the group's entries before any joining
    for s in range(n_super):
        needed[s] = columns[s] * (columns[s] + 2.0 * (struct_ptr[s + 1] - struct_ptr[s]))
    joined = np.zeros(n_super, dtype=np.bool_)  # joined to its parent
    for s in range(n_super):
        p = super_parent[s]
        if p == -1 or first[s + 1] != first[p]:
            continue
        # p has joined nothing yet: a single child ends where it begins
        k = columns[s] + first[p + 1] - first[p]
        together = k * (k + 2.0 * (struct_ptr[p + 1] - struct_ptr[p]))
        if k <= small or together - needed[s] - needed[p] <= zeros_share * together:
            joined[s] = True
            columns[p] = k
            needed[p] += needed[s]
            start[p] = start[s]
    count = 0
    starts = np.empty(n_super + 1, dtype=np.int64)
    for s in range(n_super):
        if not joined[s]:
            starts[count] = start[s]
            count += 1
    starts[count] = first[n_super]
    return starts[: count + 1].copy()


@njit(**_JIT)
def _front_place(g, s, first, struct_ptr, struct_idx):
    """Where index `g` sits in supernode s's front (its own indices first, then its set)."""
    if g < first[s + 1]:
        return g - first[s]
    lo = struct_ptr[s]
    hi = struct_ptr[s + 1]
    while lo < hi:  # g is in the set: binary search
        mid = (lo + hi) // 2
        if struct_idx[mid] < g:
            lo = mid + 1
        else:
            hi = mid
    return first[s + 1] - first[s] + lo - struct_ptr[s]


@njit(**_JIT)
def front_maps(j_indptr, j_indices, row_place, col_place, first, struct_ptr, struct_idx, super_parent):
    """Everything the numeric factorization needs besides the values:

    * ``entry_ptr``, ``entry_src``, ``entry_pos`` — the Jacobian's entries (``J.data``
      positions) assembled into each supernode's front, at flat front positions;
    * ``relative`` — where each index of a supernode's set sits in its parent's front;
    * ``lower_ptr``, ``upper_ptr`` — offsets of each supernode's factor blocks (the totals last);
    * ``largest_front`` — the largest front's size f² (the work array).

    `row_place`/`col_place` give the row/column of B of each row/column of J."""
    n_super = first.size - 1
    n = row_place.size
    super_of = np.empty(n, dtype=np.int64)
    for s in range(n_super):
        super_of[first[s] : first[s + 1]] = s
    nnz = j_indptr[n]
    owner = np.empty(nnz, dtype=np.int64)
    entry_ptr = np.zeros(n_super + 1, dtype=np.int64)
    for i in range(n):
        r = row_place[i]
        for e in range(j_indptr[i], j_indptr[i + 1]):
            s = super_of[min(r, col_place[j_indices[e]])]
            owner[e] = s
            entry_ptr[s + 1] += 1
    for s in range(n_super):
        entry_ptr[s + 1] += entry_ptr[s]
    fill = entry_ptr[:-1].copy()
    entry_src = np.empty(nnz, dtype=np.int64)
    entry_pos = np.empty(nnz, dtype=np.int64)
    for i in range(n):
        r = row_place[i]
        for e in range(j_indptr[i], j_indptr[i + 1]):
            s = owner[e]
            f = first[s + 1] - first[s] + struct_ptr[s + 1] - struct_ptr[s]
            c = col_place[j_indices[e]]
            row = _front_place(r, s, first, struct_ptr, struct_idx)
            col = _front_place(c, s, first, struct_ptr, struct_idx)
            entry_src[fill[s]] = e
            entry_pos[fill[s]] = row * f + col
            fill[s] += 1
    relative = np.empty(struct_idx.size, dtype=np.int64)
    lower_ptr = np.zeros(n_super + 1, dtype=np.int64)
    upper_ptr = np.zeros(n_super + 1, dtype=np.int64)
    largest_front = 0
    for s in range(n_super):
        k = first[s + 1] - first[s]
        m = struct_ptr[s + 1] - struct_ptr[s]
        p = super_parent[s]
        for t in range(struct_ptr[s], struct_ptr[s + 1]):
            relative[t] = _front_place(struct_idx[t], p, first, struct_ptr, struct_idx)
        lower_ptr[s + 1] = lower_ptr[s] + (k + m) * k
        upper_ptr[s + 1] = upper_ptr[s] + k * m
        largest_front = max(largest_front, (k + m) * (k + m))
    return entry_ptr, entry_src, entry_pos, relative, lower_ptr, upper_ptr, largest_front


@njit(**_JIT)
def stack_offsets(struct_ptr, super_parent):
    """Where each supernode's contribution block lies on the stack, the stack's peak size,
    and each supernode's children (``child_ptr``, ``children``); the peak is -1 if the
    supernodes are not in a postorder (a supernode's children not on top of the stack)."""
    n_super = super_parent.size
    child_ptr = np.zeros(n_super + 1, dtype=np.int64)
    for s in range(n_super):
        if super_parent[s] != -1:
            child_ptr[super_parent[s] + 1] += 1
    for s in range(n_super):
        child_ptr[s + 1] += child_ptr[s]
    children = np.empty(child_ptr[n_super], dtype=np.int64)
    fill = child_ptr[:-1].copy()
    for s in range(n_super):  # increasing: the order they were pushed
        p = super_parent[s]
        if p != -1:
            children[fill[p]] = s
            fill[p] += 1
    offset = np.empty(n_super, dtype=np.int64)
    owner = np.empty(n_super, dtype=np.int64)  # the supernodes whose blocks are on the stack
    depth = 0
    top = 0
    peak = 0
    for s in range(n_super):
        popped = 0
        while depth > 0 and super_parent[owner[depth - 1]] == s:  # its children, on top
            depth -= 1
            top = offset[owner[depth]]
            popped += 1
        if popped != child_ptr[s + 1] - child_ptr[s]:
            return offset, -1, child_ptr, children
        m = struct_ptr[s + 1] - struct_ptr[s]
        offset[s] = top
        if m > 0:
            owner[depth] = s
            depth += 1
            top += m * m
            peak = max(peak, top)
    return offset, peak, child_ptr, children


@njit(**_JIT)
def _factor_front(front, k, pivots, threshold):
    """LU of the front's first k columns with row swaps among its first k rows, in panels;
    the trailing block becomes the Schur complement.  Returns the smallest ratio of a pivot
    to the largest entry of its column below the supernode (1 when they are all smaller),
    or -1 when a pivot is below `threshold` times that entry, zero or not finite."""
    f = front.shape[0]
    worst = 1.0
    for p0 in range(0, k, PANEL):
        p1 = min(p0 + PANEL, k)
        for j in range(p0, p1):
            best = j
            big = abs(front[j, j])
            for i in range(j + 1, k):
                size = abs(front[i, j])
                if size > big:
                    best = i
                    big = size
            below = 0.0
            for i in range(k, f):
                below = max(below, abs(front[i, j]))
            if not (big > 0.0 and big < np.inf) or big < threshold * below:
                return -1.0
            if big < below:
                worst = min(worst, big / below)
            pivots[j] = best
            if best != j:
                for c in range(f):
                    swapped = front[j, c]
                    front[j, c] = front[best, c]
                    front[best, c] = swapped
            inverse = 1.0 / front[j, j]
            for i in range(j + 1, f):
                multiplier = front[i, j] * inverse
                front[i, j] = multiplier
                if multiplier != 0.0:
                    for c in range(j + 1, p1):
                        front[i, c] -= multiplier * front[j, c]
        for j in range(p0 + 1, p1):  # the panel's rows of U beyond it
            for r in range(p0, j):
                multiplier = front[j, r]
                if multiplier != 0.0:
                    for c in range(p1, f):
                        front[j, c] -= multiplier * front[r, c]
        rest = f - p1
        if rest == 0:
            continue
        if rest * rest * (p1 - p0) >= _SMALL_UPDATE:
            trailing = front[p1:, p1:]
            panel = np.ascontiguousarray(front[p1:, p0:p1])
            trailing -= np.dot(panel, np.ascontiguousarray(front[p0:p1, p1:]))
        else:
            for i in range(p1, f):
                for r in range(p0, p1):
                    multiplier = front[i, r]
                    if multiplier != 0.0:
                        for c in range(p1, f):
                            front[i, c] -= multiplier * front[r, c]
    return worst


@njit(**_JIT)
def factor_supernodal(values, first, struct_ptr, entry_ptr, entry_src, entry_pos, relative, child_ptr,
                      children, stack_offset, lower_ptr, upper_ptr, lower, upper, pivots, front, stack,
                      threshold):  # fmt: skip
    """Numeric LU of B from the Jacobian's `values` into `lower`, `upper`, `pivots`.

    Returns (failed supernode or -1, smallest pivot ratio of `_factor_front`)."""
    n_super = first.size - 1
    worst = 1.0
    for s in range(n_super):
        k = first[s + 1] - first[s]
        m = struct_ptr[s + 1] - struct_ptr[s]
        f = k + m
        flat = front[: f * f]
        flat[:] = 0.0
        for t in range(entry_ptr[s], entry_ptr[s + 1]):
            flat[entry_pos[t]] += values[entry_src[t]]
        for q in range(child_ptr[s], child_ptr[s + 1]):  # extend-add of the children's blocks
            child = children[q]
            mc = struct_ptr[child + 1] - struct_ptr[child]
            base = stack_offset[child]
            rel = relative[struct_ptr[child] : struct_ptr[child + 1]]
            for a in range(mc):
                row = rel[a] * f
                source = base + a * mc
                for b in range(mc):
                    flat[row + rel[b]] += stack[source + b]
        matrix = flat.reshape((f, f))
        ratio = _factor_front(matrix, k, pivots[first[s] : first[s + 1]], threshold)
        if ratio < 0.0:
            return s, worst
        worst = min(worst, ratio)
        block = lower[lower_ptr[s] : lower_ptr[s + 1]]
        for i in range(f):
            for j in range(k):
                block[i * k + j] = matrix[i, j]
        block = upper[upper_ptr[s] : upper_ptr[s + 1]]
        for i in range(k):
            for t in range(m):
                block[i * m + t] = matrix[i, k + t]
        base = stack_offset[s]
        for a in range(m):
            for b in range(m):
                stack[base + a * m + b] = matrix[k + a, k + b]
    return -1, worst


#: Below this many entries a supernode's off-diagonal block is applied by loops in the solves
#: (a BLAS call costs more on the small ones at the leaves).
_SMALL_BLOCK = 512


@njit(**_JIT)
def _swap_rows(w, a, pivots, k, backwards):
    """The supernode's row swaps on w (rows a..a+k), in order or undone."""
    for step in range(k):
        j = k - 1 - step if backwards else step
        p = pivots[a + j]
        if p != j:
            for c in range(w.shape[1]):
                swapped = w[a + j, c]
                w[a + j, c] = w[a + p, c]
                w[a + p, c] = swapped


@njit(**_JIT)
def _push_into_set(w, a, k, rows, block):
    """``w[rows] -= block @ w[a:a + k]`` (block of shape (rows.size, k), any layout)."""
    m = rows.size
    if m * k >= _SMALL_BLOCK:
        product = np.dot(block, w[a : a + k])
        for t in range(m):
            for c in range(w.shape[1]):
                w[rows[t], c] -= product[t, c]
    else:
        for t in range(m):
            g = rows[t]
            for j in range(k):
                entry = block[t, j]
                for c in range(w.shape[1]):
                    w[g, c] -= entry * w[a + j, c]


@njit(**_JIT)
def _pull_from_set(w, a, k, rows, block):
    """``w[a:a + k] -= block @ w[rows]`` (block of shape (k, rows.size), any layout)."""
    m = rows.size
    if m * k >= _SMALL_BLOCK:
        known = np.empty((m, w.shape[1]))
        for t in range(m):
            known[t] = w[rows[t]]
        product = np.dot(block, known)
        for i in range(k):
            for c in range(w.shape[1]):
                w[a + i, c] -= product[i, c]
    else:
        for i in range(k):
            for t in range(m):
                entry = block[i, t]
                g = rows[t]
                for c in range(w.shape[1]):
                    w[a + i, c] -= entry * w[g, c]


@njit(**_JIT)
def _blocks(s, first, struct_ptr, struct_idx, lower_ptr, upper_ptr, lower, upper):
    """Supernode s's first index, size, set (its rows beyond it), and blocks L21 (m × k) and
    U12 (k × m) as views of the factors."""
    a = first[s]
    k = first[s + 1] - a
    rows = struct_idx[struct_ptr[s] : struct_ptr[s + 1]]
    m = rows.size
    base = lower_ptr[s]
    below = lower[base + k * k : base + (k + m) * k].reshape((m, k))
    beside = upper[upper_ptr[s] : upper_ptr[s] + k * m].reshape((k, m))
    return a, k, rows, below, beside


@njit(**_JIT)
def _solve_lu(first, struct_ptr, struct_idx, lower_ptr, upper_ptr, lower, upper, pivots, w):
    """B z = w in place (w of shape (n, n_rhs)): L forward, then U backward, supernode by
    supernode; the off-diagonal blocks by matrix products (BLAS) unless small."""
    n_super = first.size - 1
    r = w.shape[1]
    for s in range(n_super):
        a, k, rows, below, _ = _blocks(s, first, struct_ptr, struct_idx, lower_ptr, upper_ptr, lower, upper)
        base = lower_ptr[s]
        _swap_rows(w, a, pivots, k, False)
        for i in range(1, k):  # L11, unit lower
            row = base + i * k
            for j in range(i):
                entry = lower[row + j]
                for c in range(r):
                    w[a + i, c] -= entry * w[a + j, c]
        _push_into_set(w, a, k, rows, below)
    for s in range(n_super - 1, -1, -1):
        a, k, rows, _, beside = _blocks(s, first, struct_ptr, struct_idx, lower_ptr, upper_ptr, lower, upper)
        base = lower_ptr[s]
        _pull_from_set(w, a, k, rows, beside)
        for i in range(k - 1, -1, -1):  # U11
            row = base + i * k
            for j in range(i + 1, k):
                entry = lower[row + j]
                for c in range(r):
                    w[a + i, c] -= entry * w[a + j, c]
            inverse = 1.0 / lower[row + i]
            for c in range(r):
                w[a + i, c] *= inverse


@njit(**_JIT)
def _solve_lu_transposed(first, struct_ptr, struct_idx, lower_ptr, upper_ptr, lower, upper, pivots, w):
    """Bᵀ z = w in place: Uᵀ forward, then Lᵀ backward and the swaps undone."""
    n_super = first.size - 1
    r = w.shape[1]
    for s in range(n_super):
        a, k, rows, _, beside = _blocks(s, first, struct_ptr, struct_idx, lower_ptr, upper_ptr, lower, upper)
        base = lower_ptr[s]
        for j in range(k):  # U11ᵀ, each solved entry pushed along its row of U11
            row = base + j * k
            inverse = 1.0 / lower[row + j]
            for c in range(r):
                w[a + j, c] *= inverse
            for i in range(j + 1, k):
                entry = lower[row + i]
                for c in range(r):
                    w[a + i, c] -= entry * w[a + j, c]
        _push_into_set(w, a, k, rows, beside.T)
    for s in range(n_super - 1, -1, -1):
        a, k, rows, below, _ = _blocks(s, first, struct_ptr, struct_idx, lower_ptr, upper_ptr, lower, upper)
        base = lower_ptr[s]
        _pull_from_set(w, a, k, rows, below.T)
        for i in range(k - 1, 0, -1):  # L11ᵀ, each solved entry pushed along its row of L11
            row = base + i * k
            for j in range(i):
                entry = lower[row + j]
                for c in range(r):
                    w[a + j, c] -= entry * w[a + i, c]
        _swap_rows(w, a, pivots, k, True)


@njit(**_JIT)
def solve_supernodal(factors, rhs, out, work, transposed):
    """Solve J x = rhs (or Jᵀ x = rhs if `transposed`) with the factors of B, rhs and out of
    shape (n, n_rhs) (out may be rhs), work of the same shape.  Returns whether every
    entry of the solution is finite."""
    rows, cols, first, struct_ptr, struct_idx, lower_ptr, upper_ptr, lower, upper, pivots = factors
    n, r = rhs.shape
    into, outof = (cols, rows) if transposed else (rows, cols)
    for p in range(n):
        for c in range(r):
            work[p, c] = rhs[into[p], c]
    if transposed:
        _solve_lu_transposed(first, struct_ptr, struct_idx, lower_ptr, upper_ptr, lower, upper, pivots, work)
    else:
        _solve_lu(first, struct_ptr, struct_idx, lower_ptr, upper_ptr, lower, upper, pivots, work)
    finite = True
    for p in range(n):
        for c in range(r):
            value = work[p, c]
            out[outof[p], c] = value
            finite &= np.isfinite(value)
    return finite
