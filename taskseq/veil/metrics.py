"""Figures of a method on people's sequences: edit distance to people, the goal reached, intervals and tests.

People reach one objective in many ways (the release's sequences of one
environment and objective differ from person to person), so a closed-loop run
is compared with the nearest person's sequence of its environment and objective
(normalised edit distance), and scored by the share of the objective's goal it
reaches. Intervals resample environments, not sequences: the sequences of one
environment share its objects and are not independent draws.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from dataclasses import dataclass

import numpy as np


def edit_distance(a: Sequence[Hashable], b: Sequence[Hashable]) -> int:
    """Levenshtein distance between two step sequences (insert, delete, substitute: 1 each)."""
    previous = list(range(len(b) + 1))
    for i, x in enumerate(a, start=1):
        current = [i]
        for j, y in enumerate(b, start=1):
            current.append(min(previous[j] + 1, current[j - 1] + 1, previous[j - 1] + (x != y)))
        previous = current
    return previous[-1]


def nearest_edit_distance(run: Sequence[Hashable], references: Sequence[Sequence[Hashable]]) -> float:
    """Edit distance to the nearest reference, over the longer of the two (0: the same steps; 1: nothing shared)."""
    if not references:
        raise ValueError("no reference sequence to compare with")
    return min(edit_distance(run, ref) / max(len(run), len(ref), 1) for ref in references)


def goal_share(facts: frozenset, goal: frozenset) -> float:
    """The share of the goal's facts that hold (1.0 for an empty goal: nothing was asked)."""
    return 1.0 if not goal else len(goal & facts) / len(goal)


@dataclass(frozen=True)
class Interval:
    mean: float
    low: float
    high: float


def bootstrap_by_group(values: Sequence[float], groups: Sequence[Hashable], resamples: int = 2000,
                       seed: int = 0, confidence: float = 0.95) -> Interval:
    """The mean of `values` with a percentile interval from resampling whole groups (environments)."""
    values = np.asarray(values, dtype=float)
    if values.size == 0:
        raise ValueError("no values to bootstrap")
    keys = sorted(set(groups), key=str)
    index = {k: i for i, k in enumerate(keys)}
    g = np.array([index[k] for k in groups])
    sums, counts = np.bincount(g, values, len(keys)), np.bincount(g, minlength=len(keys)).astype(float)
    rng = np.random.default_rng(seed)
    draws = rng.integers(len(keys), size=(resamples, len(keys)))
    means = sums[draws].sum(axis=1) / counts[draws].sum(axis=1)
    tail = (1 - confidence) / 2
    return Interval(float(values.mean()), float(np.quantile(means, tail)), float(np.quantile(means, 1 - tail)))


def paired_sign_flip(a: Sequence[float], b: Sequence[float], resamples: int = 20000, seed: int = 0) -> float:
    """Two-sided p-value that paired values `a` and `b` have the same mean (random sign flips of the differences).

    The +1 in numerator and denominator counts the observed flip, so p is never 0."""
    d = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    if d.size == 0:
        raise ValueError("no pairs to test")
    observed = abs(d.mean())
    rng = np.random.default_rng(seed)
    signs = rng.choice((-1.0, 1.0), size=(resamples, d.size))
    flipped = np.abs((signs * d).mean(axis=1))
    return float((1 + np.count_nonzero(flipped >= observed - 1e-12)) / (resamples + 1))
