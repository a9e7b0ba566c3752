"""Uncertainty of Table I over worlds: cluster-bootstrap intervals and paired tests between methods.

Every figure of Table I is a ratio of counts pooled over a world's scenarios
(programs right over programs for the sequence figures, steps right over
steps for the per-step ones), then averaged over the world seeds. Both the
worlds and the scenarios are draws: a world is one sample of the simulated
benchmark, a scenario one sample of a world. The bootstrap resamples them in
that order (worlds with replacement, then, inside each drawn world, its
scenarios with replacement, each scenario with all of its steps), and
recomputes the figure exactly as the table does. Every method sees the same
resamples, so intervals of differences between methods are paired too.

Two methods' programs are paired: the same scenario of the same world. The
exact McNemar test asks whether, among the pairs where exactly one of the
two is right, one of them is right more often than a fair coin would make
it (a two-sided binomial test on the discordant pairs, `scipy.stats.binomtest`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy.stats import binomtest

from ..sim.primitives import PRIMITIVES

# Table I's figures: sequence ones from the closed-loop programs, per-step ones (the "average" columns, over the
# steps whose demonstrated primitive is one of the seven) from the teacher-forced steps
SEQUENCE_FIGURES = {"sequence_arg": "arg_correct", "sequence_prim": "prim_correct", "success": "success"}
STEP_FIGURES = {"average_prim": "prim_correct", "average_arg": "arg_correct"}
FIGURES = (*SEQUENCE_FIGURES, *STEP_FIGURES)
TEST = "exact McNemar (two-sided binomial test on the discordant pairs)"


@dataclass(frozen=True)
class World:
    """One world's outcomes: per (method, figure), hits and counts per scenario, scenarios in `scenarios` order."""

    scenarios: tuple[str, ...]
    hits: dict[tuple[str, str], np.ndarray]
    counts: dict[tuple[str, str], np.ndarray]

    def rate(self, key: tuple[str, str]) -> float:
        """The figure in percent over every scenario, as Table I computes it."""
        return 100.0 * float(self.hits[key].sum()) / float(self.counts[key].sum())


@dataclass(frozen=True)
class Interval:
    method: str
    figure: str
    value: float  # mean over worlds, as Table I
    low: float
    high: float


@dataclass(frozen=True)
class Comparison:
    method: str
    against: str
    role: str  # why this comparator: the paper's model or the best baseline
    figure: str
    rate: float  # the method's figure, mean over worlds
    against_rate: float
    difference: float  # rate - against_rate, percentage points
    low: float  # bootstrap interval of the difference
    high: float
    better: int  # programs right for the method and wrong for the comparator
    worse: int  # wrong for the method and right for the comparator
    pairs: int  # programs paired by (world, scenario)
    p_value: float
    p_holm: float  # Holm's adjustment over every comparison of the table


def _flag(text: str, where: str) -> int:
    if text not in ("0", "1"):
        raise ValueError(f"{where}: expected 0 or 1, got {text!r}")
    return int(text)


def world_outcomes(sequences: Iterable[Mapping[str, str]], steps: Iterable[Mapping[str, str]],
                   name: str = "world") -> World:
    """Outcomes from a world's `crossval_sequences.csv` and `crossval_steps.csv` rows.

    Raises `ValueError` when a method lacks a scenario another has, or has one twice: the
    figures would not be paired.
    """
    seq_hits: dict[tuple[str, str], dict[str, int]] = {}
    seen: set[tuple[str, str]] = set()
    scenarios: set[str] = set()
    for i, r in enumerate(sequences, start=2):
        method, scenario = r["method"], r["scenario"]
        if (method, scenario) in seen:
            raise ValueError(f"{name}: crossval_sequences.csv has scenario {scenario} twice for method {method}")
        seen.add((method, scenario))
        scenarios.add(scenario)
        for figure, column in SEQUENCE_FIGURES.items():
            seq_hits.setdefault((method, figure), {})[scenario] = _flag(r[column], f"{name}: programs, record {i}")
    step_hits: dict[tuple[str, str], dict[str, list[int]]] = {}
    for i, r in enumerate(steps, start=2):
        if r["primitive"] not in PRIMITIVES:  # `done` steps are outside the average, as in Table I
            continue
        scenarios.add(r["scenario"])
        for figure, column in STEP_FIGURES.items():
            if r[column] == "":  # the method predicts no arguments
                continue
            cell = step_hits.setdefault((r["method"], figure), {}).setdefault(r["scenario"], [0, 0])
            cell[0] += _flag(r[column], f"{name}: steps, record {i}")
            cell[1] += 1
    order = tuple(sorted(scenarios))
    hits, counts = {}, {}
    for key, per in seq_hits.items():
        missing = [s for s in order if s not in per]
        if missing:
            raise ValueError(f"{name}: method {key[0]} has no program for scenarios {missing[:3]}")
        hits[key] = np.array([per[s] for s in order], dtype=float)
        counts[key] = np.ones(len(order))
    for key, per in step_hits.items():
        hits[key] = np.array([per.get(s, [0, 0])[0] for s in order], dtype=float)
        counts[key] = np.array([per.get(s, [0, 0])[1] for s in order], dtype=float)
    return World(order, hits, counts)


def _common_keys(worlds: Sequence[World]) -> list[tuple[str, str]]:
    """The (method, figure) pairs every world has; one that only some worlds have is an error."""
    keys = [set(w.hits) for w in worlds]
    partial = sorted(set().union(*keys) - set.intersection(*keys))
    if partial:
        raise ValueError(f"figures present in some worlds only: {partial[:3]}")
    return sorted(keys[0])


def bootstrap_rates(worlds: Sequence[World], keys: Sequence[tuple[str, str]], resamples: int,
                    seed: int) -> np.ndarray:
    """Each key's figure on each resample, shape (resamples, len(keys)): worlds drawn with replacement, then each
    drawn world's scenarios with replacement, the figure the mean over drawn worlds of each one's pooled rate."""
    if resamples < 1:
        raise ValueError(f"resamples must be at least 1, got {resamples}")
    rng = np.random.default_rng(seed)
    n_worlds = len(worlds)
    drawn = rng.integers(n_worlds, size=(resamples, n_worlds))
    total = np.zeros((resamples, len(keys)))
    for j in range(n_worlds):  # the j-th drawn world of every resample
        for k, world in enumerate(worlds):
            rows = np.flatnonzero(drawn[:, j] == k)
            n = len(world.scenarios)
            picks = rng.integers(n, size=(len(rows), n))
            weights = np.zeros((len(rows), n))
            np.add.at(weights, (np.repeat(np.arange(len(rows)), n), picks.ravel()), 1.0)
            hits = np.stack([world.hits[key] for key in keys], axis=1)
            counts = np.stack([world.counts[key] for key in keys], axis=1)
            with np.errstate(invalid="ignore", divide="ignore"):
                total[rows] += 100.0 * (weights @ hits) / (weights @ counts)
    return total / n_worlds


def _interval(samples: np.ndarray, confidence: float) -> tuple[float, float]:
    tail = 100.0 * (1.0 - confidence) / 2.0
    low, high = np.nanpercentile(samples, [tail, 100.0 - tail])
    return float(low), float(high)


def confidence_intervals(worlds: Sequence[World], resamples: int, seed: int,
                         confidence: float = 0.95) -> list[Interval]:
    """A percentile interval for every figure of every method the worlds hold, by method then figure order."""
    if not worlds:
        raise ValueError("no worlds to bootstrap")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must lie strictly between 0 and 1, got {confidence}")
    keys = _common_keys(worlds)
    samples = bootstrap_rates(worlds, keys, resamples, seed)
    out = {}
    for i, key in enumerate(keys):
        value = float(np.mean([w.rate(key) for w in worlds]))
        out[key] = Interval(key[0], key[1], value, *_interval(samples[:, i], confidence))
    methods = list(dict.fromkeys(m for m, _ in keys))
    return [out[(m, f)] for m in methods for f in FIGURES if (m, f) in out]


def mcnemar_exact(method: np.ndarray, other: np.ndarray) -> tuple[int, int, float]:
    """(better, worse, p): programs only `method` gets right, only `other` does, and the exact two-sided p-value."""
    a, b = np.asarray(method, dtype=bool), np.asarray(other, dtype=bool)
    if a.shape != b.shape:
        raise ValueError(f"paired outcomes must have the same length, got {a.shape} and {b.shape}")
    better, worse = int(np.sum(a & ~b)), int(np.sum(~a & b))
    p = binomtest(better, better + worse, 0.5, alternative="two-sided").pvalue if better + worse else 1.0
    return better, worse, float(p)


def holm(p_values: Sequence[float]) -> list[float]:
    """Holm's step-down adjustment: each p-value such that rejecting below 0.05 bounds the family-wise error."""
    order = np.argsort(p_values, kind="stable")
    m = len(p_values)
    out = [0.0] * m
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (m - rank) * p_values[i]))
        out[i] = running
    return out


def best_baseline(worlds: Sequence[World], baselines: Sequence[str], figure: str = "sequence_arg") -> str:
    """The baseline with the highest mean `figure` over worlds (the first in `baselines` on a tie)."""
    scored = [(float(np.mean([w.rate((b, figure)) for w in worlds])), -i, b)
              for i, b in enumerate(baselines) if all((b, figure) in w.hits for w in worlds)]
    if not scored:
        raise ValueError(f"no baseline among {list(baselines)} has the figure {figure}")
    return max(scored)[2]


def paired_comparisons(worlds: Sequence[World], pairs: Sequence[tuple[str, str, str]], resamples: int, seed: int,
                       confidence: float = 0.95) -> list[Comparison]:
    """Each (method, against, role) on every sequence figure: difference, its bootstrap interval and McNemar's test.

    Programs are paired by (world, scenario); the bootstrap draws are those of
    `confidence_intervals` with the same seed, so the two tables agree.
    """
    keys = _common_keys(worlds)
    samples = bootstrap_rates(worlds, keys, resamples, seed)
    column = {key: i for i, key in enumerate(keys)}
    rows = []
    for method, against, role in pairs:
        for figure in SEQUENCE_FIGURES:
            a, b = (method, figure), (against, figure)
            if a not in column or b not in column:
                raise ValueError(f"no {figure} to compare for {method if a not in column else against}")
            better, worse, p = mcnemar_exact(np.concatenate([w.hits[a] for w in worlds]),
                                             np.concatenate([w.hits[b] for w in worlds]))
            rate, other = (float(np.mean([w.rate(k) for w in worlds])) for k in (a, b))
            low, high = _interval(samples[:, column[a]] - samples[:, column[b]], confidence)
            rows.append(Comparison(method, against, role, figure, rate, other, rate - other, low, high, better,
                                   worse, sum(len(w.scenarios) for w in worlds), p, p))
    adjusted = holm([r.p_value for r in rows])
    return [replace(r, p_holm=q) for r, q in zip(rows, adjusted, strict=True)]
