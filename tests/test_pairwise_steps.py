"""The compiled SMO solver ends where the plain algorithm its docstring states ends, bit for bit: as many steps and
shrinkings, the same gap, weights and gradients.

`working_set._pairwise_steps` is written for speed (cuts listed group by
group, first cuts peeled out of loops, padded vector updates); each of those
must leave every sum with the same terms in the same order, or the weights of
every fit, and so every reported figure, would move. The reference below is
that algorithm in plain Python floats (IEEE doubles, no fused operations),
read straight off the description: a pass over the active cuts in index order
gives each group's gap; the groups whose gap is at least half the largest are
visited in order of their first active cut; a visit takes pairwise steps
among its active cuts, then updates every other cut's gradient for the
weights that moved; every `max(200, groups // 2)` visits the cuts with no
weight and a gradient below every cut that could give them weight are set
aside, and all come back (gradients recomputed) before the gap may stop it.
"""

from __future__ import annotations

import numpy as np
import pytest

from taskseq.learn.working_set import _pairwise_steps


def _gradients(gram, losses, alpha):
    K = len(losses)
    grad = list(losses)
    for m in range(K):
        if alpha[m] > 0.0:
            for k in range(K):
                grad[k] -= alpha[m] * gram[m][k]
    return grad


def reference_steps(gram, losses, groups, alpha, C, B, tol, max_steps):
    """(gap, steps, shrinkings, alpha, gradients) of the solver's algorithm, step for step."""
    K = len(losses)
    grad = _gradients(gram, losses, alpha)
    diag = [gram[k][k] for k in range(K)]
    tiny = 1e-12 * max(1.0, max(diag))
    spare = [C] * B
    for k in range(K):
        spare[groups[k]] -= alpha[k]
    active = list(range(K))
    shrunk, since_shrink, steps, shrinks = False, 0, 0, 0
    shrink_every = max(200, B // 2)
    while True:
        touched = list(dict.fromkeys(groups[k] for k in active))
        best_up, own_gap = {g: 0.0 for g in touched}, {g: 0.0 for g in touched}
        for k in active:
            g = groups[k]
            if grad[k] > best_up[g]:
                best_up[g] = grad[k]
            own_gap[g] -= alpha[k] * grad[k]
        gap, largest = 0.0, 0.0
        for g in touched:
            own_gap[g] += C * best_up[g]
            gap += own_gap[g]
            largest = max(largest, own_gap[g])
        if gap <= tol or steps >= max_steps or largest <= 0.0:
            if not shrunk:
                return gap, steps, shrinks, alpha, grad
            grad = _gradients(gram, losses, alpha)
            active, shrunk, since_shrink = list(range(K)), False, 0
            continue
        if since_shrink >= shrink_every:
            low = {g: 0.0 if spare[g] > 0.0 else np.inf for g in touched}
            for k in active:
                if alpha[k] > 0.0 and grad[k] < low[groups[k]]:
                    low[groups[k]] = grad[k]
            kept = [k for k in active if alpha[k] > 0.0 or grad[k] > low[groups[k]]]
            if len(kept) < len(active):
                shrunk = True
                shrinks += 1
            active, since_shrink = kept, 0
        for g in touched:
            if own_gap[g] < 0.5 * largest:
                continue
            since_shrink += 1
            local = [k for k in active if groups[k] == g]
            moved = {}
            target = 0.1 * own_gap[g]
            for _ in range(10 * len(local) + 10):
                up, i, weighted = 0.0, -1, 0.0
                for k in local:
                    if grad[k] > up:
                        up, i = grad[k], k
                    weighted += alpha[k] * grad[k]
                if C * up - weighted <= target:
                    break
                j, gain_j, curv_j = -2, 0.0, 0.0
                if i >= 0 and spare[g] > 0.0:
                    j, curv_j = -1, max(diag[i], tiny)
                    gain_j = up * up / curv_j
                for k in local:
                    if alpha[k] <= 0.0 or k == i or up - grad[k] <= 0.0:
                        continue
                    diff = up - grad[k]
                    curv = max(diag[i] + diag[k] - 2.0 * gram[i][k] if i >= 0 else diag[k], tiny)
                    if diff * diff / curv > gain_j:
                        j, gain_j, curv_j = k, diff * diff / curv, curv
                if j == -2:
                    break
                if j >= 0:
                    step = min(alpha[j], (up - grad[j]) / curv_j)
                    alpha[j] = 0.0 if step == alpha[j] else alpha[j] - step
                    moved[j] = moved.get(j, 0.0) - step
                else:
                    step = min(spare[g], up / curv_j)
                    spare[g] = 0.0 if step == spare[g] else spare[g] - step
                if i >= 0:
                    alpha[i] += step
                    moved[i] = moved.get(i, 0.0) + step
                else:
                    spare[g] += step
                for k in local:
                    if i >= 0:
                        grad[k] -= step * gram[i][k]
                    if j >= 0:
                        grad[k] += step * gram[j][k]
                steps += 1
            # every other cut's gradient, once per cut that moved, in the order the cuts are listed
            own = {k: grad[k] for k in local}
            for c in sorted(k for k in local if moved.get(k, 0.0) != 0.0):
                for k in range(K):
                    grad[k] -= moved[c] * gram[c][k]
            for k, value in own.items():  # the group's own gradients were kept up step by step
                grad[k] = value


def _problem(seed: int, K: int, B: int, d: int):
    rng = np.random.default_rng(seed)
    deltas = rng.normal(size=(K, d)) * (rng.uniform(size=(K, d)) < 0.4)  # sparse, nearly parallel rows: hard
    deltas += rng.normal(size=d)
    gram = deltas @ deltas.T
    losses = rng.uniform(0.5, 2.0, size=K)
    groups = rng.integers(0, B, size=K)
    alpha = np.zeros(K)
    return gram, losses, groups, alpha


@pytest.mark.parametrize("seed, K, B, C, tol, max_steps, shrinks", [
    (0, 240, 90, 0.8, 1e-9, 10_000_000, True),  # many small groups, cuts set aside and brought back
    (1, 60, 1, 2.0, 1e-10, 10_000_000, False),  # one group: the 1-slack problem
    (2, 400, 300, 0.3, 1e-8, 10_000_000, True),
    (3, 300, 12, 1.0, 1e-9, 10_000_000, False),  # few large groups: long sums per group
    (0, 240, 90, 0.8, 1e-9, 57, False),  # stopped by the step bound, the gap still open
])
def test_the_compiled_solver_takes_the_reference_steps_bit_for_bit(seed, K, B, C, tol, max_steps, shrinks):
    gram, losses, groups, alpha = _problem(seed, K, B, 8)
    # a start with weight already on some cuts, as every solve after the first has
    alpha[::7] = C / (np.bincount(groups, minlength=B)[groups[::7]] + 1.0)
    want_gap, want_steps, want_shrinks, want_alpha, want_grad = reference_steps(
        gram.tolist(), losses.tolist(), groups.tolist(), alpha.tolist(), C, B, tol, max_steps)
    # the compiled solver reads the first K rows and columns of a larger buffer, as the working set hands it over,
    # and writes scratch entries past K: there they hold what an earlier, larger set left
    buffer = np.full((K + 40, K + 40), 1.7)
    buffer[:K, :K] = gram
    got_alpha, grad = alpha.copy(), np.full(K + 40, -3.0)
    gap, steps, got_shrinks = _pairwise_steps(buffer, losses, groups, got_alpha, grad, C, B, tol, max_steps)
    assert steps > 20  # not solved in a few steps
    assert (want_shrinks > 0) == shrinks  # the case covers what it is meant to
    assert (steps, got_shrinks) == (want_steps, want_shrinks)
    assert gap == want_gap and (gap > tol) == (max_steps < 10_000_000)
    assert got_alpha.tobytes() == np.array(want_alpha).tobytes()
    assert grad[:K].tobytes() == np.array(want_grad).tobytes()
