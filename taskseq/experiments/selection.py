"""Choosing each MRF method's slack weight C, and the shipped method, by cross-validation on a development world.

The development world is a benchmark drawn with its own seed and never
reported, so no figure is computed on folds its settings were chosen on. Every
method of the settings' list gets its own C: the grid is cross-validated, and
while a method's best C is at an edge of the values tried, one more value
beyond that edge is tried (the grid's spacing there), up to a cap. The
criterion is the headline figure, closed-loop sequence accuracy (arg); ties go
to the higher success rate, then to the smaller C (the simpler model). The
methods, each at its own C, are then ranked the same way (ties to the one
listed first); the `train` stage ships the first of them.

Each method's C is chosen on its own (`choose_method_C`), so a change to one
method re-does its choice alone; ranking reads the choices back.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import Any

from ..demonstrations.benchmark import Benchmark
from ..evaluate.methods import ScorerMethod, configured
from ..evaluate.metrics import summarize
from ..features.context import StepContext
from ..features.dataset import StepMeta
from ..settings import Folds
from .crossval import cross_validate
from .fold_models import train_fold_models, training_jobs

CRITERION = "sequence_arg, then success, then the smaller C"
FIGURES = ("sequence_arg", "success", "average_arg")

# {method: the values of C to try} -> {method: {C: its figures}}
Evaluate = Callable[[dict[str, tuple[float, ...]]], dict[str, dict[float, dict[str, float]]]]


def best_candidate(candidates: list[dict[str, Any]]) -> dict[str, Any]:
    """The candidate `CRITERION` prefers; figures equal to 9 decimals count as a tie (sums over folds may differ
    in the last bit), so the choice does not hang on rounding noise."""
    if not candidates:
        raise ValueError("select: no candidates to choose from")
    return max(candidates, key=lambda r: (round(r["sequence_arg"], 9), round(r["success"], 9), -r["C"]))


def _beyond(value: float, ratio: float) -> float:
    """`value` times `ratio`, to 6 significant digits, so a value tried reads as it is written in the file."""
    return float(f"{value * ratio:.6g}")


def choose_C(methods: Sequence[str], grid: Sequence[float], evaluate: Evaluate,
             max_extensions: int) -> dict[str, dict[str, Any]]:
    """Each method's C: the grid for all methods at once, then, in rounds, one value beyond the edge for every
    method whose best is at an edge, until none is or it has had `max_extensions` of them.

    Returns per method: every C tried with its figures (in increasing C), the chosen C, the extensions made, and
    `capped`, true when the cap ended the search with the best still at an edge.
    """
    grid = tuple(sorted(set(grid)))
    if len(grid) < 2:
        raise ValueError("select: the grid of C needs at least two values (its spacing is how it is extended)")
    down, up = grid[1] / grid[0], grid[-1] / grid[-2]
    tried: dict[str, dict[float, dict[str, float]]] = {m: {} for m in methods}
    extensions = dict.fromkeys(methods, 0)
    pending = {m: grid for m in methods}
    while pending:
        scores = evaluate(pending)
        for m, values in pending.items():
            tried[m].update({c: scores[m][c] for c in values})
        pending = {}
        for m in methods:
            best = _choice(tried[m])
            if best in (min(tried[m]), max(tried[m])) and extensions[m] < max_extensions:
                pending[m] = (_beyond(best, up),) if best == max(tried[m]) else (_beyond(best, 1 / down),)
                extensions[m] += 1
    out = {}
    for m in methods:
        best = _choice(tried[m])
        out[m] = {"C": best, "candidates": _rows(tried[m]), "extensions": extensions[m],
                  "capped": best in (min(tried[m]), max(tried[m]))}
    return out


def _rows(tried: Mapping[float, Mapping[str, float]]) -> list[dict[str, float]]:
    return [{"C": c, **{k: tried[c][k] for k in FIGURES}} for c in sorted(tried)]


def _choice(tried: Mapping[float, Mapping[str, float]]) -> float:
    return best_candidate(_rows(tried))["C"]


@dataclass(frozen=True)
class DevData:
    """The development world's steps and scenarios, and how they are cross-validated."""

    contexts: list[StepContext]
    meta: list[StepMeta]
    bench: Benchmark
    folds: Folds
    max_steps: int


def cross_validate_settings(pending: dict[str, tuple[float, ...]],
                            make: Callable[[str, float], Callable[[], ScorerMethod]], data: DevData, store: Path,
                            n_jobs: int = 1, verbose: int = 0,
                            plain_at: Sequence[float] = ()) -> dict[str, dict[float, dict[str, float]]]:
    """Each method at each of its values of C (`make(method, C)`: its unfitted method at that C), cross-validated
    on the same folds: every distinct model is fitted
    once into the folder `store` (replaced), as the `fold_models` stage does (a DAgger model starts from the
    model without DAgger; `feasible` is `dagger`'s models run with another policy), then every method is run
    from it. At each value of `plain_at` the plain model of each method's features (`ScorerMethod.plain`) is
    fitted too, and not run: the fits of richer training data start from it (`fold_models.plan_tasks`)."""
    makes = {}
    for method, values in pending.items():
        for c in values:
            makes[(method, c)] = partial(configured, make(method, c), name=f"{method} C={c:g}", store=None)
    starts = {f"{method} plain C={c:g}": partial(_plain_of, make(method, c), name=f"{method} plain C={c:g}")
              for method in pending for c in plain_at}
    by_name = {**{make().name: make for make in makes.values()}, **starts}
    folds = data.folds
    jobs = training_jobs(by_name, data.meta, data.bench.scenarios, folds.folds, folds.seed, folds.group_by, ())
    fitted = train_fold_models(by_name, data.contexts, data.meta, data.bench.scenarios, jobs, store, n_jobs, verbose)
    if verbose:
        print(f"{len(fitted)} models, {sum(r['from_cache'] for r in fitted)} of them read back from the fit cache")
    stored = {name: partial(configured, make, name=name, store=str(store)) for name, make in by_name.items()
              if name not in starts}
    results = cross_validate(stored, data.contexts, data.meta, data.bench, n_folds=folds.folds, seed=folds.seed,
                             group_by=folds.group_by, max_steps=data.max_steps, n_jobs=n_jobs, verbose=verbose)
    summary = summarize(results, data.contexts, dict.fromkeys(stored, True))
    out: dict[str, dict[float, dict[str, float]]] = {m: {} for m in pending}
    for (method, c), make in makes.items():
        out[method][c] = _figures(summary, make().name)
    return out


def _plain_of(make: Callable[[], ScorerMethod], name: str) -> ScorerMethod:
    """The plain model of the method `make()` makes, named `name`, without a store (a module-level function, so
    it goes to a worker process)."""
    return replace(make().plain(), name=name, store=None)


def choose_method_C(method: str, make: Callable[[str, float], Callable[[], ScorerMethod]], data: DevData,
                    grid: Sequence[float], max_extensions: int, scratch: Path, n_jobs: int = 1,
                    verbose: int = 0) -> tuple[dict[str, Any], list[float]]:
    """`method`'s choice of C (`choose_C` for it alone) and each round's seconds; the rounds' fold models go to
    folders under `scratch`.

    The grid's round also fits the plain model of the method's features at
    each value of the grid, which its fits of richer training data (chained
    starts, DAgger, noisy copies, drawn rooms) start from, as they do in
    `fold_models`: a method's choice then depends on its own settings only,
    whatever other methods are chosen beside it. A round beyond the grid fits
    its one new value alone.
    """
    seconds: list[float] = []

    def evaluate(pending: dict[str, tuple[float, ...]]) -> dict[str, dict[float, dict[str, float]]]:
        start = time.perf_counter()
        out = cross_validate_settings(pending, make, data, scratch / str(len(seconds)), n_jobs, verbose,
                                      plain_at=() if seconds else tuple(sorted(set(grid))))
        seconds.append(time.perf_counter() - start)
        return out

    return choose_C([method], grid, evaluate, max_extensions)[method], seconds


def _figures(summary: dict[str, Any], name: str) -> dict[str, float]:
    return {"sequence_arg": summary[name]["sequence/arg"], "success": summary[name]["success"],
            "average_arg": summary[name]["steps"]["average/arg"]}


def rank_methods(settings: Mapping[str, Mapping[str, Any]]) -> list[dict[str, Any]]:
    """The methods, each at its chosen C, best first: sequence arg, then success, then the order given."""
    if not settings:
        raise ValueError("select: no MRF methods to rank (no method of params.yaml's methods section names select)")
    rows = []
    for name, choice in settings.items():
        figures = next(r for r in choice["candidates"] if r["C"] == choice["C"])
        rows.append({"method": name, "C": choice["C"], **{k: figures[k] for k in FIGURES}})
    order = sorted(range(len(rows)), key=lambda i: (-round(rows[i]["sequence_arg"], 9),
                                                   -round(rows[i]["success"], 9), i))
    return [rows[i] for i in order]
