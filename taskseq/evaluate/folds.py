"""Grouped folds: no scenario (or, optionally, no environment) is in both train and test."""

from __future__ import annotations

import numpy as np


def grouped_folds(groups: list[str], n_folds: int, seed: int) -> list[np.ndarray]:
    """Test indices of each fold; every group lands in exactly one fold.

    Groups are shuffled with `seed` and dealt round robin, largest first, so
    folds are of similar size and the same seed always gives the same folds.
    """
    unique = sorted(set(groups))
    if n_folds < 2:
        raise ValueError(f"need at least 2 folds, got {n_folds}")
    if len(unique) < n_folds:
        raise ValueError(f"{len(unique)} groups cannot fill {n_folds} folds")
    rng = np.random.default_rng(seed)
    order = [unique[i] for i in rng.permutation(len(unique))]
    sizes = {g: 0 for g in unique}
    for g in groups:
        sizes[g] += 1
    order.sort(key=lambda g: -sizes[g])  # stable: ties keep the shuffled order
    load = [0] * n_folds
    fold_of: dict[str, int] = {}
    for g in order:
        k = int(np.argmin(load))
        fold_of[g] = k
        load[k] += sizes[g]
    index = np.array([fold_of[g] for g in groups])
    return [np.flatnonzero(index == k) for k in range(n_folds)]
