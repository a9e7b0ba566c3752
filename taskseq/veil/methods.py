"""Methods on people's sequences: each fits on replayed sequences and ranks the next step of a state.

Every method, learned or not, speaks one interface, `VeilMethod`: `fit` on the
replays of the training environments, then `ranked(state, history, objective)`
yields steps best first. The evaluation (`taskseq.veil.evaluate`) reads the
first as its next-step prediction; in closed loop a policy takes the first
(`plain`) or the first the domain lets run (`feasible`). A method never sees a
held-out environment's sequences: `fit` is all it is given of the data.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from ..learn.ssvm import CuttingPlaneSSVM
from .features import ARITIES, DONE, PAIR_COLUMNS, Vocabulary, label_of, step_of
from .grounding import Step
from .mrf import DomainMRF, StepInput, best_first
from .replay import Replay
from .state import State


class VeilMethod(Protocol):
    """A method of the evaluation. One that predicts no next step of a person (a planner that searches from
    where it stands) says so with a class attribute `predicts_next_step = False`; the evaluation then gives it
    closed-loop figures only."""

    name: str

    def fit(self, train: Sequence[Replay]) -> VeilMethod: ...

    def ranked(self, state: State, history: Sequence[Step], objective: str) -> Iterator[Step]: ...


def training_steps(replays: Sequence[Replay]) -> Iterator[tuple[State, list[Step], str, Step]]:
    """(state, history, objective, person's step) for every kept step of `replays`, and `done` after the last."""
    for r in replays:
        if not r.kept:
            continue
        steps = list(r.kept) + [Step(DONE)]
        states = list(r.states) + [r.final]
        for i, (state, s) in enumerate(zip(states, steps, strict=True)):
            yield state, steps[:i], r.point.objective, s


@dataclass
class DomainScorer:
    """The unrolled MRF's weights from the structural SVM (`DomainMRF`, `CuttingPlaneSSVM`).

    The vocabulary fixes what an object's row holds (`features.Vocabulary`; with categories or, as the paper's
    model, attributes only) and which objectives the model knows."""

    name: str
    vocabulary: Vocabulary
    features: str = "full"
    C: float = 1.0
    tol: float = 1e-3
    max_iter: int = 500
    model_: DomainMRF = field(init=False, repr=False)
    w_: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.model_ = DomainMRF(ARITIES, len(self.vocabulary.objectives), len(self.vocabulary.columns),
                                len(PAIR_COLUMNS), self.features)

    def inputs(self, replays: Sequence[Replay]) -> tuple[list[StepInput], list[tuple[int, int, int]]]:
        X, Y = [], []
        for state, history, objective, s in training_steps(replays):
            X.append(self.vocabulary.step_input(state, history, objective))
            Y.append(label_of(s, state))
        return X, Y

    def fit(self, train: Sequence[Replay]) -> DomainScorer:
        X, Y = self.inputs(train)
        learner = CuttingPlaneSSVM(self.model_, C=self.C, tol=self.tol, max_iter=self.max_iter, n_slacks=0)
        self.w_ = learner.fit(X, Y).w_
        return self

    def ranked(self, state: State, history: Sequence[Step], objective: str) -> Iterator[Step]:
        x = self.vocabulary.step_input(state, history, objective)
        values = self.model_.candidate_scores(x, self.w_)
        names = list(state.world.objects)  # once per ranking, not per candidate
        for chunk in best_first(values):  # sorted only as far as the caller reads
            for label in self.model_.labels(chunk, x.n).tolist():
                yield step_of(label, names)
