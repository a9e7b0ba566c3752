"""Step metrics, teacher-forced: the true state and history, predict the step."""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from ..features.context import StepContext
from ..sim.primitives import ALL_PRIMITIVES, PRIMITIVES
from .failures import failure_counts

Y = tuple[int, int, int]


def step_accuracy(contexts: list[StepContext], predictions: list[Y]) -> dict[str, float]:
    """`prim` (primitive right) and `arg` (primitive and both arguments right), in percent.

    Per primitive of the demonstration, over the seven primitives (`average`, as
    the paper's Table I), and for `done` on its own.
    """
    hits: dict[str, list[tuple[bool, bool]]] = defaultdict(list)
    for x, y_hat in zip(contexts, predictions, strict=True):
        name = ALL_PRIMITIVES[x.gold[0]]
        hits[name].append((y_hat[0] == x.gold[0], tuple(y_hat) == tuple(x.gold)))
    out: dict[str, float] = {}
    for name, h in hits.items():
        out[f"{name}/prim"] = 100.0 * sum(p for p, _ in h) / len(h)
        out[f"{name}/arg"] = 100.0 * sum(a for _, a in h) / len(h)
    seven = [v for name in PRIMITIVES for v in hits.get(name, [])]
    if seven:
        out["average/prim"] = 100.0 * sum(p for p, _ in seven) / len(seven)
        out["average/arg"] = 100.0 * sum(a for _, a in seven) / len(seven)
    return dict(sorted(out.items()))


def confusion(contexts: list[StepContext], predictions: list[Y]) -> np.ndarray:
    """Counts of (demonstrated primitive, predicted primitive), over all primitives and done."""
    out = np.zeros((len(ALL_PRIMITIVES), len(ALL_PRIMITIVES)), dtype=int)
    for x, y_hat in zip(contexts, predictions, strict=True):
        out[x.gold[0], y_hat[0]] += 1
    return out


def summarize(results: list, contexts: list[StepContext], predicts_args: dict[str, bool]) -> dict[str, dict]:
    """Per method: pooled teacher-forced step metrics and closed-loop sequence metrics, in percent."""
    out: dict[str, dict] = {}
    for name in dict.fromkeys(r.method for r in results):
        rs = [r for r in results if r.method == name]
        index = [i for r in rs for i in r.step_index]
        preds = [y for r in rs for y in r.step_predictions]
        steps = step_accuracy([contexts[i] for i in index], preds)
        if not predicts_args[name]:
            steps = {k: (None if k.endswith("/arg") else v) for k, v in steps.items()}
        entry: dict = {"steps": steps, "n_steps": len(index)}
        if all(r.sequences is not None for r in rs):
            seqs = [s for r in rs for s in r.sequences]
            entry["sequence/prim"] = 100.0 * np.mean([s.prim_correct for s in seqs])
            entry["sequence/arg"] = 100.0 * np.mean([s.arg_correct for s in seqs])
            entry["success"] = 100.0 * np.mean([s.success for s in seqs])
            entry["goal_reached"] = 100.0 * np.mean([s.goal_reached for s in seqs])
            entry["n_scenarios"] = len(seqs)
            entry["programs"] = failure_counts([s.failure for s in seqs])
            per_task = defaultdict(list)
            for s in seqs:
                per_task[s.task].append(s)
            entry["per_task"] = {
                t: {"sequence/arg": 100.0 * np.mean([s.arg_correct for s in v]),
                    "success": 100.0 * np.mean([s.success for s in v]), "n": len(v),
                    "programs": failure_counts([s.failure for s in v])}
                for t, v in sorted(per_task.items())
            }
        out[name] = entry
    return out


def headline_metrics(summary: dict[str, dict]) -> dict[str, dict[str, float]]:
    """Per method, the figures DVC tracks: average step accuracy and the sequence rates it has."""
    out = {}
    for name, entry in summary.items():
        m = {"average_prim": entry["steps"].get("average/prim"), "average_arg": entry["steps"].get("average/arg")}
        for key in ("sequence/prim", "sequence/arg", "success", "goal_reached"):
            if key in entry:
                m[key.replace("/", "_")] = entry[key]
        out[name] = {k: v for k, v in m.items() if v is not None}
    return out
