"""Choosing the MRF's slack weight C by cross-validation on a development world.

The development world is a benchmark drawn with its own seed and never
reported, so no figure is computed on folds its settings were chosen on. The
criterion is the headline figure, closed-loop sequence accuracy (arg); ties go
to the higher success rate, then to the smaller C (the simpler model).
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
from .methods import MRFMethod
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


def read_selection(path: Path | str) -> float:
    """The C a `select` stage chose, from its JSON file, with an error that names the file and field."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no selection file; run `taskseq select` (or `dvc repro select`)") from None
    except ValueError as err:
        raise ValueError(f"{path}: not valid JSON: {err}") from None
    value = data.get("C") if isinstance(data, dict) else None
    if not isinstance(value, (int, float)) or isinstance(value, bool) or value <= 0:
        raise ValueError(f"{path}: field 'C' must be a positive number, got {value!r}")
    return float(value)
