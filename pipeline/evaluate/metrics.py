"""Step metrics, teacher-forced: the true state and history, predict the step."""

from __future__ import annotations

from collections import defaultdict

from ..features.context import StepContext
from ..sim.primitives import ALL_PRIMITIVES, PRIMITIVES

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
