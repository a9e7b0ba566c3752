"""The objects a symbolic goal needs but an under-specified task leaves open.

`stir(L)` needs a stirrer, `pour(L)` a vessel, `throw_away(A)` a bin. They come
from the demonstration (symb-plan-manual) or from a ranking SVM per role that
scores objects by their state bits and attributes (symb-plan-svm).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ...sim.primitives import Action
from ...sim.tasks import Task

ROLE_OF_TASK = {"stir": "stirrer", "pour": "vessel", "throw_away": "bin"}


def demonstrated_roles(task: Task, actions: Sequence[Action]) -> dict[str, str]:
    """The stirrer, vessel or bin the demonstration used."""
    role = ROLE_OF_TASK.get(task.name)
    if role == "stirrer":
        return {role: next(a.args[0] for a in actions if a.primitive == "follow_traj_circle")}
    if role == "vessel":
        return {role: next(a.args[1] for a in actions if a.primitive == "follow_traj_pour")}
    if role == "bin":
        return {role: [a for a in actions if a.primitive in ("hold_above", "place_above")][-1].args[1]}
    return {}


class RoleRanker:
    """A pairwise ranking SVM (Joachims 2002): the chosen object should outscore every other one."""

    def __init__(self, C: float = 1.0) -> None:
        self.C = C

    def fit(self, groups: list[tuple[np.ndarray, int]]) -> RoleRanker:
        """`groups`: (features of the candidate objects, index of the chosen one) per scenario."""
        from sklearn.svm import LinearSVC  # imported here: writing PDDL files needs the roles, not the ranker

        diffs = []
        for X, chosen in groups:
            for j in range(len(X)):
                if j != chosen:
                    diffs.append(X[chosen] - X[j])
        if not diffs:
            raise ValueError("a ranking needs at least one scenario with two candidates")
        D = np.array(diffs)
        X = np.vstack([D, -D])
        y = np.r_[np.ones(len(D)), -np.ones(len(D))]
        self.svm_ = LinearSVC(C=self.C, fit_intercept=False, max_iter=100000, random_state=0).fit(X, y)
        self.w_ = self.svm_.coef_.ravel()
        return self

    def best(self, X: np.ndarray) -> int:
        return int(np.argmax(X @ self.w_))
