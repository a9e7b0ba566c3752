"""Choosing the MRF's slack weight C, and the shipped method, by cross-validation on a development world.

The development world is a benchmark drawn with its own seed and never
reported, so no figure is computed on folds its settings were chosen on. The
criterion is the headline figure, closed-loop sequence accuracy (arg); ties go
to the higher success rate, then to the smaller C (the simpler model). At the
chosen C, the MRF methods named in the settings are ranked the same way, on
the same folds (ties to the one listed first); the `train` stage ships the
first of them.
"""

from __future__ import annotations

import json
from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import Any

from ..features.context import StepContext
from ..features.dataset import StepMeta
from ..logs.benchmark import Benchmark
from ..settings import Folds, Learner
from .crossval import cross_validate
from .methods import MRFMethod, mrf_methods
from .metrics import summarize


def select_C(grid: tuple[float, ...], learner: Learner, folds: Folds, contexts: list[StepContext],
             meta: list[StepMeta], bench: Benchmark, max_steps: int, n_jobs: int = 1,
             verbose: int = 0) -> dict[str, Any]:
    """Cross-validate the full model for every C of `grid`; returns the choice and every candidate's figures."""
    if not grid:
        raise ValueError("select: the grid of C values is empty")
    names = {f"C={c:g}": c for c in grid}
    methods = {name: partial(MRFMethod, features="full", **replace(learner, C=c).ssvm, name=name)
               for name, c in names.items()}
    results = cross_validate(methods, contexts, meta, bench, n_folds=folds.folds, seed=folds.seed,
                             group_by=folds.group_by, max_steps=max_steps, n_jobs=n_jobs, verbose=verbose)
    summary = summarize(results, contexts, dict.fromkeys(names, True))
    candidates = [{"C": c, "sequence_arg": summary[name]["sequence/arg"], "success": summary[name]["success"],
                   "average_arg": summary[name]["steps"]["average/arg"]} for name, c in names.items()]
    return {"C": best_candidate(candidates)["C"], "criterion": CRITERION, "candidates": candidates}


CRITERION = "sequence_arg, then success, then the smaller C"


def best_candidate(candidates: list[dict[str, Any]]) -> dict[str, Any]:
    """The candidate `CRITERION` prefers; figures equal to 9 decimals count as a tie (sums over folds may differ
    in the last bit), so the choice does not hang on rounding noise."""
    if not candidates:
        raise ValueError("select: no candidates to choose from")
    return max(candidates, key=lambda r: (round(r["sequence_arg"], 9), round(r["success"], 9), -r["C"]))


def _figures(summary: dict[str, Any], name: str) -> dict[str, float]:
    return {"sequence_arg": summary[name]["sequence/arg"], "success": summary[name]["success"],
            "average_arg": summary[name]["steps"]["average/arg"]}


def rank_methods(names: tuple[str, ...], learner: Learner, folds: Folds, contexts: list[StepContext],
                 meta: list[StepMeta], bench: Benchmark, max_steps: int, known: dict[str, dict[str, float]],
                 n_jobs: int = 1, verbose: int = 0) -> list[dict[str, Any]]:
    """The MRF methods `names` at the learner's C, best first: each one's figures, cross-validated on the same
    folds as the choice of C unless `known` already holds them (the full model at the chosen C)."""
    if not names:
        raise ValueError("select: no MRF methods to rank (select.methods is empty)")
    todo = {n: make for n, make in mrf_methods(learner, names=names).items() if n not in known}
    figures = dict(known)
    if todo:
        results = cross_validate(todo, contexts, meta, bench, n_folds=folds.folds, seed=folds.seed,
                                 group_by=folds.group_by, max_steps=max_steps, n_jobs=n_jobs, verbose=verbose)
        summary = summarize(results, contexts, dict.fromkeys(todo, True))
        figures.update({n: _figures(summary, n) for n in todo})
    rows = [{"method": n, **{k: figures[n][k] for k in ("sequence_arg", "success", "average_arg")}} for n in names]
    order = sorted(range(len(rows)), key=lambda i: (-round(rows[i]["sequence_arg"], 9),
                                                   -round(rows[i]["success"], 9), i))
    return [rows[i] for i in order]


def _read(path: Path | str) -> tuple[Path, Any]:
    path = Path(path)
    try:
        return path, json.loads(path.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no selection file; run `taskseq select` (or `dvc repro select`)") from None
    except ValueError as err:
        raise ValueError(f"{path}: not valid JSON: {err}") from None


def read_selected_method(path: Path | str) -> str:
    """The MRF method a `select` stage ranked first on the development world, from its JSON file."""
    path, data = _read(path)
    value = data.get("method") if isinstance(data, dict) else None
    if not isinstance(value, str) or not value:
        raise ValueError(f"{path}: no field 'method' (the method ranked first); the file predates the ranking of "
                         "methods: run `taskseq select` again, or name the method with --set train.method=NAME")
    return value


def read_selection(path: Path | str) -> float:
    """The C a `select` stage chose, from its JSON file, with an error that names the file and field."""
    path, data = _read(path)
    value = data.get("C") if isinstance(data, dict) else None
    if not isinstance(value, (int, float)) or isinstance(value, bool) or value <= 0:
        raise ValueError(f"{path}: field 'C' must be a positive number, got {value!r}")
    return float(value)
