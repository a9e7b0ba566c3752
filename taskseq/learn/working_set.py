"""The working-set QP of a cutting-plane SSVM, solved in its dual by pairwise (SMO) steps.

Every cut k belongs to one slack group g(k) and carries a constraint vector
d_k and a loss L_k. The dual of the working-set problem is

    max_a  L . a - 0.5 ||sum_k a_k d_k||^2    s.t.  a >= 0,  sum_{k in g} a_k <= C  for every group g.

Why a hand-written solver: the feasible set is a product of simplices (each
group's budget C, with an implicit "no cut" variable taking what is left), the
optimum is sparse, and consecutive problems differ by a few cuts. Pairwise
steps that move weight between two variables of one group (Platt's SMO, with
the second-order choice of the pair) start from the previous optimum and touch
only the cuts that change, so a solve costs O(K) per step and no factorisation.
General QP solvers (Clarabel, OSQP, quadprog, ProxQP) refactor the dense K x K
Gram matrix at every call, O(K^3): measured on this problem, 20 ms at K = 200
and 0.3 to 0.7 s at K = 800, where this solver needs milliseconds.

Why sparse cuts: with one slack per example (the n-slack problem, which the
pipeline trains) a cut is the difference of two joint features of one step, a
few hundred non-zeros out of thousands, and an iteration adds hundreds of
cuts. Their Gram columns are sparse products, and `w` is a sparse product
too, so neither costs K x d dense work.

Why shrinking: with hundreds of groups most cuts sit at zero weight with a
gradient below every cut that could give them weight, and they stay there.
The solver sets such cuts aside (Joachims 1999; Fan, Chen and Lin 2005) and
steps over the rest; before it reports convergence it brings every cut back,
recomputes all gradients exactly and checks the gap over the whole working
set, so shrinking changes the time of a solve, never what it certifies.

Why Numba: the steps are sequential (each picks its pair from the gradient the
previous one left), so NumPy can only vectorise inside a step, over arrays of a
few hundred entries, where its per-call overhead dominated: 36 us a step in
NumPy, about 1 us compiled (`taskseq bench` shows the share of training time in
the QP). The compiled function is cached on disk, so a process compiles it once.

Why a second way to take the steps, for large working sets: the Gram matrix
takes K^2 memory and every cut that moves updates K gradients, so the work of
a pass over the groups grows with the square of the training steps. On a
world of 8,570 steps the first iterations hold about 17,000 cuts: 4 GB of Gram
matrix, and 79 to 93% of the fit in the QP (docs/scaling-benchmark.md). Past
`gram_limit` cuts the set drops its Gram matrix and keeps the weights
`w = sum_k a_k d_k` themselves instead (dual coordinate ascent, as liblinear
does for linear SVMs and Chang and Yih 2013 for structured ones): a cut's
gradient is one sparse product with `w`, a group's steps need only its own
cuts' cross products, and moving weight updates `w` over the cut's non-zeros,
so a pass costs time and memory in proportion to the set's non-zeros. It needs
more passes than the greedy order above to close a tight gap (on a paper-shaped
world's 886 steps, the relations model's QP takes 2.9 s this way against 1.5 s
with the Gram matrix), so when pruning brings the set back under the limit the
Gram matrix is formed again and the steps go back to it. A fit that never holds
more than `gram_limit` cuts takes only the greedy steps, bit for bit.

Any feasible `a` gives a valid lower bound on the working-set optimum, and so
on the SSVM optimum; the solver stops when the Frank-Wolfe gap of the dual,
an upper bound on its own suboptimality, is below the tolerance it is given.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numba import njit

from .products import dot

# Cuts up to which the set keeps their Gram matrix (128 MB of it at the limit). The fits of the paper-shaped
# worlds stay below it (the largest set of world 0's fold models held 3,524 cuts), so they take the greedy steps
# they always took; on 8,570 steps the sets start at about 17,000 cuts and fall to 2,600.
GRAM_LIMIT = 4000


class WorkingSet:
    """The cuts of a cutting-plane SSVM (sparse rows), their dual variables and, up to `gram_limit` cuts, their
    Gram matrix (past it, the weights the dual variables give).

    The Gram matrix grows by half its size when full, so adding cuts never
    copies it per iteration.
    """

    def __init__(self, dim: int, n_groups: int, C: float, gram_limit: int | None = None) -> None:
        self.C = float(C)
        self.dim = dim
        self.n_groups = n_groups
        self._size = 0
        self._deltas = sp.csr_matrix((0, dim))  # constraint vectors d_k, one row each
        self._losses = np.zeros(0)  # L_k
        self._groups = np.zeros(0, dtype=np.int64)  # g(k)
        self._last_active = np.zeros(0, dtype=np.int64)  # iteration at which a_k was last positive
        self.gram_limit = GRAM_LIMIT if gram_limit is None else gram_limit
        self._gram: np.ndarray | None = np.zeros((0, 0))  # None while the set holds more than gram_limit cuts
        self._w = np.zeros(dim)  # sum_k a_k d_k, kept only while there is no Gram matrix
        self._alpha = np.zeros(0)
        self._grad = np.zeros(0)  # L_k - d_k . w at the last solve's alpha
        self.n_steps = 0  # pairwise steps taken, over all solves
        self.n_shrinks = 0  # times a solve set cuts aside, over all solves
        self.n_sweeps = 0  # passes over the groups on explicit weights, over all solves

    def __len__(self) -> int:
        return self._size

    @property
    def deltas(self) -> sp.csr_matrix:
        return self._deltas

    @property
    def losses(self) -> np.ndarray:
        return self._losses[: self._size]

    @property
    def groups(self) -> np.ndarray:
        return self._groups[: self._size]

    @property
    def alpha(self) -> np.ndarray:
        return self._alpha[: self._size]

    @property
    def w(self) -> np.ndarray:
        if self._gram is None:
            return self._w.copy()
        return self._deltas.T @ self.alpha if self._size else np.zeros(self.dim)

    def dual(self, w: np.ndarray | None = None) -> float:
        """The dual objective; `w` may pass the current weights when the caller has them."""
        w = self.w if w is None else w
        return dot(self.losses, self.alpha) - 0.5 * dot(w, w)  # not BLAS: the same bits on every processor

    def slacks(self) -> np.ndarray:
        """(n_groups,): each group's slack at the last solve, max(0, max_k L_k - d_k . w) over its cuts.

        A new cut violated by no more than its group's slack is satisfied by
        the working set's solution: adding it would not move the optimum.
        """
        out = np.zeros(self.n_groups)
        if self._size:
            np.maximum.at(out, self.groups, self._grad[: self._size])
        return out

    def _reserve(self, size: int) -> None:
        capacity = len(self._losses)
        if size <= capacity:
            return
        new = max(size + size // 2, capacity + capacity // 2, 64)
        k = self._size

        def grown(a: np.ndarray) -> np.ndarray:
            out = np.zeros(new, dtype=a.dtype)
            out[:k] = a[:k]
            return out

        self._losses, self._groups = grown(self._losses), grown(self._groups)
        self._last_active, self._alpha, self._grad = grown(self._last_active), grown(self._alpha), grown(self._grad)
        if self._gram is not None:
            gram = np.zeros((new, new))  # the first K rows and columns are set by add; `_cross_update` reads past
            # them into its scratch entries (zeros: no NaN or subnormal there to slow it)
            gram[:k, :k] = self._gram[:k, :k]
            self._gram = gram

    def add(self, deltas: np.ndarray | sp.spmatrix, losses: np.ndarray, groups: np.ndarray, iteration: int) -> None:
        """Append cuts (rows of `deltas`, dense or sparse) with zero dual weight (the solution stays feasible)."""
        m = len(losses)
        if m == 0:
            return
        new = sp.csr_matrix(deltas, dtype=float)
        new.sum_duplicates()  # one entry per feature, in ascending order, as `_cross_products` needs (sums made by
        # scipy, as the oracle's cuts are, have it already: then this only sorts)
        k = self._size
        w = self.w
        if self._gram is not None and k + m > self.gram_limit:
            self._gram, self._w = None, w  # too many cuts for their Gram matrix: explicit weights from here
        self._reserve(k + m)
        self._deltas = sp.vstack([self._deltas, new], format="csr")
        if self._gram is not None:
            _gram_columns(self._deltas, new, self._gram, k)
        self._losses[k : k + m] = losses
        self._groups[k : k + m] = groups
        self._last_active[k : k + m] = iteration
        self._alpha[k : k + m] = 0.0
        self._grad[k : k + m] = losses - new @ w
        self._size = k + m

    def seed(self, deltas: sp.spmatrix, losses: np.ndarray, groups: np.ndarray, alpha: np.ndarray) -> None:
        """Fill an empty set with cuts and their dual weights (a neighbouring fit's, `ssvm.Cuts`).

        Each group's weights must sum to at most C, so the start is feasible
        and its dual a valid lower bound; the gradients are made exact for it.
        """
        if self._size:
            raise ValueError("only an empty working set can be seeded")
        alpha = np.asarray(alpha, dtype=float)
        budget = np.zeros(self.n_groups)
        np.add.at(budget, groups, alpha)
        if np.any(alpha < 0) or np.any(budget > self.C * (1 + 1e-12)):
            raise ValueError("seeded dual weights must be non-negative and sum to at most C in every group")
        self.add(deltas, losses, groups, iteration=0)
        self._alpha[: self._size] = alpha
        w = self._deltas.T @ self.alpha
        if self._gram is None:
            self._w = w
        self._grad[: self._size] = self.losses - self._deltas @ w

    def prune(self, iteration: int, window: int) -> None:
        """Drop cuts whose dual weight has been zero for `window` iterations (0 keeps all)."""
        k = self._size
        self._last_active[:k][self._alpha[:k] > 0] = iteration
        if not window:
            return
        keep = np.flatnonzero(iteration - self._last_active[:k] < window)
        if len(keep) == k:
            return
        m = len(keep)
        for a in (self._losses, self._groups, self._last_active, self._alpha, self._grad):
            a[:m] = a[keep]
        self._deltas = self._deltas[keep]
        if self._gram is not None:
            _compact(self._gram, keep)
        self._size = m

    def solve(self, tol: float, max_steps: int = 10_000_000) -> float:
        """Improve `alpha` until the dual's Frank-Wolfe gap is at most `tol`; returns that gap.

        Each step moves weight, within one group, from a cut j to the cut i of
        largest gradient (or between a cut and the group's unused budget); j is
        the one whose exact line search gains most (Fan, Chen and Lin 2005's
        second-order choice), which takes far fewer steps than the steepest pair
        when cuts are nearly parallel, as consecutive cuts are.
        """
        if self._size == 0:
            return 0.0
        size = self._size
        if self._gram is None and size <= self.gram_limit:
            # back under the limit: the Gram matrix again, every cut against every cut, and greedy steps; the
            # buffers shrink to the set first, so the matrix is no larger than the cuts it holds
            self._losses, self._groups, self._last_active, self._alpha, self._grad = (
                a[:size].copy() for a in (self._losses, self._groups, self._last_active, self._alpha, self._grad))
            self._gram = np.empty((size, size))
            _gram_columns(self._deltas, self._deltas, self._gram, 0)
        if self._gram is None:
            d = self._deltas
            gap, steps, sweeps = _sweeps(d.indptr, d.indices, d.data, self.losses, self.groups, self.alpha,
                                         self._grad[:size], self._w, self.C, self.n_groups, tol, max_steps)
            self.n_sweeps += sweeps
        else:
            # the whole Gram buffer goes in (its first K rows and columns are the cuts'): no copy per solve
            gap, steps, shrinks = _pairwise_steps(self._gram, self.losses, self.groups, self.alpha, self._grad,
                                                  self.C, self.n_groups, tol, max_steps)
            self.n_shrinks += shrinks
        self.n_steps += steps
        return gap


def _gram_columns(deltas: sp.csr_matrix, new: sp.csr_matrix, gram: np.ndarray, k: int) -> None:
    """The Gram entries of the `new` cuts, the last rows of `deltas` from row k on, against every cut."""
    by_feature = new.tocsc()  # the new cuts having each feature
    # the feature and cut indices unsigned: Numba then indexes with them without testing for a negative index,
    # which took a fifth of `_cross_products`' time (the values, and so the products, are the same)
    _cross_products(deltas.indptr, deltas.indices.astype(np.uint32), deltas.data, by_feature.indptr,
                    by_feature.indices.astype(np.uint32), by_feature.data, gram, k)


@njit(cache=True)
def _cross_products(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, f_indptr: np.ndarray,
                    f_indices: np.ndarray, f_data: np.ndarray, gram: np.ndarray, k: int) -> None:
    """gram[i, k + j] = d_i . n_j for the rows d_i of a CSR matrix (the k cuts held, then the m new ones) and the
    columns n_j of a CSC one (the new cuts, a row per feature), mirrored to gram[k + j, i].

    The products are summed over each d_i's features in ascending order, as
    scipy's sparse product sums them, so the Gram matrix is the same bits;
    written dense, without that product's sparse result (dense in fact, K x m
    entries) and its conversion, which took a third of a relations fit's QP.
    Each row goes straight into the Gram matrix (and its mirror): a K x m block
    written out and then copied in twice added 1 GB to the peak memory of a fit
    on 8,570 steps (5.1 GB, now 4.1).

    Among the new cuts, row k + r takes only the columns j >= r and mirrors
    them: d_r . n_j and d_j . n_r add the same products (one per feature the
    two share, the rows having one entry per feature) in the same ascending
    order, so the entries left out are the same bits as their mirror. That
    halves the work of a set formed at once (k = 0) and of the first
    iterations, whose cuts are mostly new (30% less time in this function
    over a full fit). Each column of the CSC matrix lists its cuts in
    ascending order, so `first` skips, once per feature and row, the cuts
    before r.
    """
    n_rows = indptr.shape[0] - 1
    m = n_rows - k
    row = np.empty(m)
    first = f_indptr[:-1].copy()  # per feature, where its new cuts from the current row's own on begin
    for i in range(n_rows):
        lo = max(i - k, 0)  # the first new cut to take: the row's own for a new cut, else all
        row[lo:] = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            f, a = indices[p], data[p]
            begin, end = first[f], f_indptr[f + 1]
            if lo:
                while begin < end and f_indices[begin] < lo:
                    begin += 1
                first[f] = begin
            for q in range(begin, end):
                row[f_indices[q]] += a * f_data[q]
        for j in range(lo, m):
            gram[i, k + j] = row[j]
        for j in range(lo + 1 if i >= k else 0, m):
            gram[k + j, i] = row[j]


@njit(cache=True)
def _compact(gram: np.ndarray, keep: np.ndarray) -> None:
    """gram[:m, :m] = gram[keep][:, keep] in place (`keep` increasing, m = len(keep)): no m x m temporary.

    Row r is read from row keep[r] >= r, which no earlier row overwrote, and
    within a row column c from keep[c] >= c, which is still to be written.
    """
    m = keep.shape[0]
    for r in range(m):
        src = keep[r]
        for c in range(m):
            gram[r, c] = gram[src, keep[c]]


@njit(cache=True)
def _members(groups: np.ndarray, n_groups: int) -> tuple[np.ndarray, np.ndarray]:
    """The cuts of every group in index order: group g's are members[start[g]:start[g + 1]]."""
    start = np.zeros(n_groups + 1, np.int64)
    for k in range(groups.shape[0]):
        start[groups[k] + 1] += 1
    for g in range(n_groups):
        start[g + 1] += start[g]
    members = np.empty(groups.shape[0], np.int64)
    fill = start[:n_groups].copy()
    for k in range(groups.shape[0]):
        members[fill[groups[k]]] = k
        fill[groups[k]] += 1
    return start, members


@njit(cache=True)
def _gradients(gram: np.ndarray, losses: np.ndarray, alpha: np.ndarray, grad: np.ndarray) -> None:
    """grad[:K] = L - Gram a, summed over the cuts with weight only (the optimum is sparse)."""
    K = losses.shape[0]
    for k in range(K):
        grad[k] = losses[k]
    for m in range(K):
        a = alpha[m]
        if a > 0.0:
            for k in range(K):
                grad[k] -= a * gram[m, k]


@njit(cache=True)
def _pairwise_steps(gram: np.ndarray, losses: np.ndarray, groups: np.ndarray, alpha: np.ndarray,
                    grad: np.ndarray, C: float, n_groups: int, tol: float, max_steps: int) -> tuple[float, int, int]:
    """SMO on the dual above, in place on `alpha` (K entries); returns (Frank-Wolfe gap, steps, shrinkings).

    Block by block: a pass over the active cuts gives every group's own
    Frank-Wolfe gap (the sum of them is the dual's gap); the groups whose gap
    is at least half the largest are then solved one after the other, each by
    pairwise steps among its own cuts (O(its cuts) a step), after which the
    other cuts' gradients are updated once for the weights that moved (O(K)
    per cut that moved, not per step). A group's "no cut" variable (its unused
    budget C - sum a_k) has gradient 0, so a step may move weight between it
    and a cut as between two cuts. On return `grad` holds the exact gradients
    at `alpha`.

    The pass reads the active cuts listed group by group (listed again only
    when shrinking changes them), so each group's gap is summed in registers
    and its visit finds its cuts in one slice; the sums are the same terms in
    the same order as a pass over the cuts in index order, and so the same
    bits (0.6 to 0.7 of the time the same solves took over the cuts in index order).
    """
    K = losses.shape[0]
    B = n_groups
    # every index array the loops read unsigned: Numba indexes with an unsigned value without testing whether it is
    # negative, which took a fifth of a choice fit's solves and a tenth of a full one's (the same arithmetic)
    group_of = groups.astype(np.uint32)
    _gradients(gram, losses, alpha, grad)
    diag = np.empty(K)
    dmax = 0.0
    for k in range(K):
        diag[k] = gram[k, k]
        dmax = max(dmax, diag[k])
    tiny = 1e-12 * max(1.0, dmax)
    spare = np.full(B, C)
    for k in range(K):
        spare[group_of[k]] -= alpha[k]
    is_active = np.ones(K, np.bool_)
    active = np.arange(K).astype(np.uint32)
    n_active, shrunk, since_shrink = K, False, 0
    shrink_every = max(200, B // 2)  # group visits between shrinkings
    low = np.empty(B)
    seen = np.full(B, -1, np.int64)  # the listing of `touched` in which a group was last met
    touched = np.empty(B, np.uint32)  # the groups of the active cuts, in order of their first active cut
    slot = np.empty(B, np.uint32)  # a listed group's place t in `touched`
    offset = np.empty(B + 1, np.uint64)  # listed group t's active cuts are grouped[offset[t]:offset[t + 1]]
    grouped = np.empty(K, np.uint32)
    own_gap = np.empty(B)  # of listed group t, at the last pass
    local = np.empty(K, np.uint32)  # a group's active cuts, during its visit
    moved = np.zeros(K)  # weight moved per cut during a visit
    moved_cut = np.empty(K, np.uint32)  # the cuts that moved in a visit, and by how much
    moved_by = np.empty(K)
    saved = np.empty(K)  # a visited group's own gradients, kept across the update of the others
    gap = np.inf
    steps = shrinks = 0
    listing, stale = 0, True
    n_touched = 0
    while True:
        if stale:
            # the groups change only with the active cuts (shrinking, unshrinking), not every pass: listed again
            # only then, a pass reads each active cut once, with no test of whether its group was met before
            listing += 1
            n_touched = 0
            for q in range(n_active):
                g = group_of[active[q]]
                if seen[g] != listing:
                    seen[g] = listing
                    slot[g] = n_touched
                    touched[n_touched] = g
                    n_touched += 1
            # and the active cuts listed group by group (a counting sort, so each group's in index order, the order
            # the gradients' sums take): a pass then reads a group's cuts together and sums in registers
            offset[: n_touched + 1] = 0
            for q in range(n_active):
                offset[slot[group_of[active[q]]] + 1] += 1
            for t in range(n_touched):
                offset[t + 1] += offset[t]
            for q in range(n_active):  # each cut at its group's next free place, which moves one on
                k = active[q]
                t = slot[group_of[k]]
                grouped[offset[t]] = k
                offset[t] += 1
            for t in range(n_touched, 0, -1):  # every group's end is now the next one's start
                offset[t] = offset[t - 1]
            offset[0] = 0
            stale = False
        gap, largest = 0.0, 0.0
        for t in range(n_touched):
            # every listed group has an active cut: the first taken out of the loop (most groups have one)
            q0 = offset[t]
            k = grouped[q0]
            up = grad[k] if grad[k] > 0.0 else 0.0  # the spare's gradient: a group's slack is never negative
            own = 0.0 - alpha[k] * grad[k]
            for q in range(q0 + 1, offset[t + 1]):
                k = grouped[q]
                if grad[k] > up:
                    up = grad[k]
                own -= alpha[k] * grad[k]
            own += C * up
            own_gap[t] = own
            gap += own
            largest = max(largest, own)
        if gap <= tol or steps >= max_steps or largest <= 0.0:
            if not shrunk:
                break
            # every cut back, exact gradients, and the gap checked over all of them
            _gradients(gram, losses, alpha, grad)
            active = np.arange(K).astype(np.uint32)
            is_active[:] = True
            n_active, shrunk, since_shrink, stale = K, False, 0, True
            continue
        if since_shrink >= shrink_every:
            # set aside the cuts with no weight whose gradient is below every cut (or spare) that could give
            # them weight: no pairwise step would move them now
            for t in range(n_touched):
                g = touched[t]
                low[g] = 0.0 if spare[g] > 0.0 else np.inf
            for q in range(n_active):
                k = active[q]
                if alpha[k] > 0.0 and grad[k] < low[group_of[k]]:
                    low[group_of[k]] = grad[k]
            kept = 0
            for q in range(n_active):
                k = active[q]
                if alpha[k] > 0.0 or grad[k] > low[group_of[k]]:
                    active[kept] = k
                    kept += 1
                else:
                    is_active[k] = False
            if kept < n_active:
                shrunk, stale = True, True
                shrinks += 1
            n_active, since_shrink = kept, 0
        for t in range(n_touched):
            if own_gap[t] < 0.5 * largest:
                continue
            g = touched[t]
            since_shrink += 1
            # the group's own problem, by pairwise steps among its active cuts
            m = 0
            for q in range(offset[t], offset[t + 1]):
                k = grouped[q]
                if is_active[k]:
                    local[m] = k
                    m += 1
            target = 0.1 * own_gap[t]
            for _ in range(10 * m + 10):
                up, i = 0.0, -1  # i = -1: the spare
                weighted = 0.0
                for q in range(m):
                    k = local[q]
                    if grad[k] > up:
                        up, i = grad[k], k
                    weighted += alpha[k] * grad[k]
                if C * up - weighted <= target:
                    break
                # j: the cut with weight whose pairing with i gains most, or the spare into i
                j, gain_j, curv_j = -2, 0.0, 0.0
                if i >= 0 and spare[g] > 0.0:
                    j, curv_j = -1, max(diag[i], tiny)
                    gain_j = up * up / curv_j
                for q in range(m):
                    k = local[q]
                    if alpha[k] <= 0.0 or k == i:
                        continue
                    diff = up - grad[k]
                    if diff <= 0.0:
                        continue
                    curv = max(diag[i] + diag[k] - 2.0 * gram[i, k] if i >= 0 else diag[k], tiny)
                    gain = diff * diff / curv
                    if gain > gain_j:
                        j, gain_j, curv_j = k, gain, curv
                if j == -2:
                    break
                if j >= 0:
                    room = alpha[j]
                    step = min(room, (up - grad[j]) / curv_j)
                    alpha[j] = 0.0 if step == room else alpha[j] - step
                    moved[j] -= step
                else:
                    room = spare[g]
                    step = min(room, up / curv_j)
                    spare[g] = 0.0 if step == room else spare[g] - step
                if i >= 0:
                    alpha[i] += step
                    moved[i] += step
                else:
                    spare[g] += step
                for q in range(m):
                    k = local[q]
                    if i >= 0:
                        grad[k] -= step * gram[i, k]
                    if j >= 0:
                        grad[k] += step * gram[j, k]
                steps += 1
            # the other active cuts' gradients, once for every weight of this group that moved
            n_moved = 0
            for q in range(m):
                c = local[q]
                if moved[c] != 0.0:
                    moved_cut[n_moved] = c
                    moved_by[n_moved] = moved[c]
                    n_moved += 1
                    moved[c] = 0.0
            if n_moved:
                for q in range(m):
                    saved[q] = grad[local[q]]
                _cross_update(gram, grad, K, moved_cut, moved_by, n_moved)
                for q in range(m):  # the group's own gradients were updated step by step: put them back
                    grad[local[q]] = saved[q]
    return gap, steps, shrinks


@njit(cache=True)
def _cross_update(gram: np.ndarray, grad: np.ndarray, K: int, cuts: np.ndarray, by: np.ndarray, n: int) -> None:
    """grad[k] -= by[j] * gram[cuts[j], k] for every cut k < K, j = 0..n-1 in that order.

    The hot loop of a solve (about a third of a full model's solve time,
    sampled with perf): every cut of a visited group that moved updates the
    gradient of every cut. Each gradient takes the same subtractions in the
    same order as one pass per moved cut would, so the results are the same
    bits. It runs over every cut, with no branch, so the compiler vectorises
    it: the cuts set aside by shrinking get updates they do not need (their
    gradients are recomputed before they are read again), and the caller
    restores the visited group's own gradients, which its steps already
    updated. It runs on past K, up to a multiple of 32 entries where the
    buffers hold them, so that the compiled loop ends on whole vectors and not
    on a scalar remainder of up to 31 (3% of a solve): the entries past K are
    scratch, never read as gradients (`_gradients` sets the first K at every
    solve, `add` a new cut's), and the Gram buffer's are finite (`_reserve`
    zeroes it, `_compact` leaves old entries).
    """
    Kp = min((K + 31) // 32 * 32, gram.shape[1], grad.shape[0])
    for j in range(n):
        c, d = cuts[j], by[j]
        for k in range(Kp):
            grad[k] -= d * gram[c, k]


@njit(cache=True)
def _sparse_gradients(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, losses: np.ndarray, w: np.ndarray,
               grad: np.ndarray) -> None:
    """grad[k] = L_k - d_k . w for every row d_k of a CSR matrix, each product summed over the row's entries."""
    for k in range(losses.shape[0]):
        s = 0.0
        for p in range(indptr[k], indptr[k + 1]):
            s += data[p] * w[indices[p]]
        grad[k] = losses[k] - s


@njit(cache=True)
def _weights(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, alpha: np.ndarray, w: np.ndarray) -> None:
    """w = sum_k a_k d_k, cut by cut in index order: one fixed order of sums."""
    w[:] = 0.0
    for k in range(alpha.shape[0]):
        a = alpha[k]
        if a > 0.0:
            for p in range(indptr[k], indptr[k + 1]):
                w[indices[p]] += a * data[p]


@njit(cache=True)
def _sweeps(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, losses: np.ndarray, groups: np.ndarray,
            alpha: np.ndarray, grad: np.ndarray, w: np.ndarray, C: float, n_groups: int, tol: float,
            max_steps: int) -> tuple[float, int, int]:
    """Block coordinate ascent on the dual, in place on `alpha` and `w`; returns (gap, steps, sweeps).

    Each sweep starts exact: `w` from `alpha`, every gradient from `w`, and
    each group's own Frank-Wolfe gap (their sum is the dual's gap). It then
    visits, in index order, every group with a gap: the group's gradients are taken afresh from the current `w`, its
    cuts' cross products d_i . d_j are formed, pairwise steps run among its
    cuts, and `w` takes the weight that moved. A group's "no cut" variable
    (its unused budget C - sum a_k) has gradient 0, so a step may move weight
    between it and a cut as between two cuts. On return `w` and `grad` are
    exact at `alpha`.
    """
    K = losses.shape[0]
    B = n_groups
    start, members = _members(groups, B)  # the cuts of each group, in index order
    widest = 0
    for g in range(B):
        widest = max(widest, start[g + 1] - start[g])
    spare = np.full(B, C)
    for k in range(K):
        spare[groups[k]] -= alpha[k]
    best_up = np.empty(B)
    own_gap = np.empty(B)
    cross = np.empty((widest, widest))  # a visited group's d_i . d_j
    moved = np.empty(widest)  # weight moved per cut of a visited group
    scratch = np.zeros(w.shape[0])  # one cut scattered dense, for its cross products
    gap = np.inf
    steps = sweeps = 0
    while True:
        _weights(indptr, indices, data, alpha, w)
        _sparse_gradients(indptr, indices, data, losses, w, grad)
        best_up[:] = 0.0  # the spare's gradient: a group's slack is never negative
        own_gap[:] = 0.0
        for k in range(K):
            g = groups[k]
            if grad[k] > best_up[g]:
                best_up[g] = grad[k]
            own_gap[g] -= alpha[k] * grad[k]
        gap, largest = 0.0, 0.0
        for g in range(B):
            own_gap[g] += C * best_up[g]
            gap += own_gap[g]
            largest = max(largest, own_gap[g])
        if gap <= tol or steps >= max_steps or largest <= 0.0:
            return gap, steps, sweeps
        sweeps += 1
        for g in range(B):
            if own_gap[g] <= 0.0:
                continue
            first, m = start[g], start[g + 1] - start[g]
            for a in range(m):
                i = members[first + a]
                s = 0.0
                for p in range(indptr[i], indptr[i + 1]):
                    s += data[p] * w[indices[p]]
                grad[i] = losses[i] - s
                for p in range(indptr[i], indptr[i + 1]):
                    scratch[indices[p]] = data[p]
                for b in range(a, m):
                    j = members[first + b]
                    s = 0.0
                    for p in range(indptr[j], indptr[j + 1]):
                        s += data[p] * scratch[indices[p]]
                    cross[a, b] = s
                    cross[b, a] = s
                for p in range(indptr[i], indptr[i + 1]):
                    scratch[indices[p]] = 0.0
                moved[a] = 0.0
            tiny = 1e-12
            for a in range(m):
                tiny = max(tiny, 1e-12 * cross[a, a])
            weighted = 0.0
            up = 0.0
            for a in range(m):
                i = members[first + a]
                up = max(up, grad[i])
                weighted += alpha[i] * grad[i]
            target = 0.1 * (C * up - weighted)
            for _ in range(10 * m + 10):
                up, u = 0.0, -1  # u = -1: the spare
                weighted = 0.0
                for a in range(m):
                    i = members[first + a]
                    if grad[i] > up:
                        up, u = grad[i], a
                    weighted += alpha[i] * grad[i]
                if C * up - weighted <= target:
                    break
                # v: the cut with weight whose pairing with u gains most, or the spare into u
                v, gain_v, curv_v = -2, 0.0, 0.0
                if u >= 0 and spare[g] > 0.0:
                    v, curv_v = -1, max(cross[u, u], tiny)
                    gain_v = up * up / curv_v
                for a in range(m):
                    j = members[first + a]
                    if alpha[j] <= 0.0 or a == u:
                        continue
                    diff = up - grad[j]
                    if diff <= 0.0:
                        continue
                    curv = max(cross[u, u] + cross[a, a] - 2.0 * cross[u, a] if u >= 0 else cross[a, a], tiny)
                    gain = diff * diff / curv
                    if gain > gain_v:
                        v, gain_v, curv_v = a, gain, curv
                if v == -2:
                    break
                if v >= 0:
                    j = members[first + v]
                    room = alpha[j]
                    step = min(room, (up - grad[j]) / curv_v)
                    alpha[j] = 0.0 if step == room else alpha[j] - step
                    moved[v] -= step
                else:
                    room = spare[g]
                    step = min(room, up / curv_v)
                    spare[g] = 0.0 if step == room else spare[g] - step
                if u >= 0:
                    alpha[members[first + u]] += step
                    moved[u] += step
                else:
                    spare[g] += step
                for a in range(m):
                    i = members[first + a]
                    if u >= 0:
                        grad[i] -= step * cross[u, a]
                    if v >= 0:
                        grad[i] += step * cross[v, a]
                steps += 1
            for a in range(m):  # w takes the weight that moved
                if moved[a] != 0.0:
                    i = members[first + a]
                    for p in range(indptr[i], indptr[i + 1]):
                        w[indices[p]] += moved[a] * data[p]
