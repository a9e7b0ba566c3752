"""Measure a room correction for teaching on drawn development worlds: weights shared by every task of the room.

The shipped planner keeps most of what says which object a step takes per task
kind: an argument's relations to the step's reference objects and its choice
cues are weighted per task, so a pour-to lesson in a room (set the cup down on
the table under the jug) reaches a pour's or a stir's choices only through the
few families every task shares. A room correction is a second weight vector d,
one for the whole room and shared by every task: it adds to the planner's
weights w0 the same amount in every task's copy of those families, and to the
argument's attributes by primitive (already shared). It is fitted to the
room's taught steps alone by the project's structural SVM, with w0's scores as
a fixed offset:

    min_d  0.5 ||d||^2 + C sum_i max_y [loss(y_i, y) - (w0 + T d) . (psi(x_i, y_i) - psi(x_i, y))]

(T copies d into every task): d is pulled by every taught step that w0 does
not already rank above each other candidate by that candidate's loss (margin
rescaling), right or wrong, and held towards 0 by the norm; no refit. This
script runs the teach protocol (`taskseq.stages.teach`: the rooms
`teach.environments` held out, the first max(`teach.k`) tasks of each taught,
every other task judged) on development draws only (`world.dev_seed` by
default; `--dev-seeds` adds others, never a reported one), for each C of a grid,
on the planner without the taught steps and on the one refitted with them as
`teach` does, and prints the sequence-arg misses and the successes pooled over
the draws. docs/teach.md shows the table this writes:

    python scripts/teach_adapt.py --Cs 0.1 0.3 1 --dev-seeds 100 101 102 103 104 \
        --output reports/teach_adapt.json

Run it after `dvc repro` has run `select` (the shipped planner and its C are read from reports/selection.json).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import scipy.sparse as sp

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "scripts"))  # the teach protocol's options and checks, as teach_weight.py has them

from teach_weight import add_dev_options, dev_setting, room_variants, show_variants  # noqa: E402

from taskseq.experiments.teaching import Taught  # noqa: E402
from taskseq.features.context import StepContext  # noqa: E402
from taskseq.features.dataset import build_steps  # noqa: E402
from taskseq.learn.estimator import StepScorer  # noqa: E402
from taskseq.learn.mrf import StepMRF  # noqa: E402
from taskseq.learn.ssvm import CuttingPlaneSSVM  # noqa: E402
from taskseq.serve.environments import Environment  # noqa: E402
from taskseq.serve.writer import person_record  # noqa: E402
from taskseq.stages.teach import SCRIPTED, written_and_read_back  # noqa: E402

# The blocks a room correction moves (slots 1 and 2 of each): those kept per task get one copy of d for every task
SHARED = ("primitive_argument_environment",)
PER_TASK = ("relations", "cues")


def sharing(mrf: StepMRF) -> sp.csr_matrix:
    """(size of w, size of d): T, which copies each weight of d into its place in every task's block."""
    rows, cols, n, start = [], [], 0, 0
    for block in mrf.blocks:  # in weight order
        start += block.size
        family = block.name[:-1] if block.name[-1] in "12" else block.name
        if family not in SHARED + PER_TASK:
            continue
        where = np.arange(start - block.size, start).reshape(block.shape)
        copies = where if family in PER_TASK else where[None]  # (tasks or 1, ...) positions of each copy
        width = copies[0].size
        for copy in copies:
            rows.append(copy.ravel())
            cols.append(n + np.arange(width))
        n += width
    r, c = np.concatenate(rows), np.concatenate(cols)
    return sp.csr_matrix((np.ones(len(r)), (r, c)), shape=(mrf.size_joint_feature, n))


class RoomCorrection:
    """The structured model of a room correction, in the learner's protocol: an example is the index of a taught
    step, a label the row (index, primitive, a1, a2), and a cut's loss is the Hamming loss less what w0 already
    gives the demonstrated step over the other (so the learner's margin is that of w0 + T d)."""

    def __init__(self, mrf: StepMRF, w0: np.ndarray, steps: list[StepContext]) -> None:
        self.mrf, self.w0, self.steps = mrf, w0, steps
        self.T = sharing(mrf)
        self.size_joint_feature = self.T.shape[1]
        # w0's score of each demonstrated step: the learner's labels are always these, so it is reckoned once
        self._gold_scores = mrf.batch_joint_feature_rows(steps, [x.gold for x in steps]) @ w0

    def weights(self, d: np.ndarray) -> np.ndarray:
        return self.w0 + self.T @ d

    def _split(self, Y: np.ndarray) -> tuple[list[StepContext], np.ndarray, np.ndarray]:
        Y = np.asarray(Y, dtype=np.int64)
        # the learner asks for every step in order: the same list each time, so the model's batch is built once
        everyone = np.array_equal(Y[:, 0], np.arange(len(self.steps)))
        return (self.steps if everyone else [self.steps[i] for i in Y[:, 0]]), Y[:, 0], Y[:, 1:]

    def batch_loss_augmented_inference(self, X: list[int], Y: np.ndarray, d: np.ndarray) -> np.ndarray:
        steps, index, labels = self._split(Y)
        return np.column_stack([index, self.mrf.batch_loss_augmented_inference(steps, labels, self.weights(d))])

    def batch_loss(self, Y: np.ndarray, Y_hat: np.ndarray) -> np.ndarray:
        steps, index, labels = self._split(Y)
        hats = np.asarray(Y_hat, dtype=np.int64)[:, 1:]
        given = self._gold_scores[index] - self.mrf.batch_joint_feature_rows(steps, hats) @ self.w0
        return self.mrf.batch_loss(labels, hats) - given

    def batch_joint_feature_rows(self, X: list[int], Y: np.ndarray) -> sp.csr_matrix:
        steps, _, labels = self._split(Y)
        return sp.csr_matrix(self.mrf.batch_joint_feature_rows(steps, labels) @ self.T)


def fit_correction(scorer: StepScorer, steps: list[StepContext], C: float) -> tuple[RoomCorrection, CuttingPlaneSSVM]:
    """The correction of `scorer` fitted at C to `steps` (the room's taught steps): its model and fitted learner."""
    model = RoomCorrection(StepMRF(scorer.features), scorer.w_, steps)
    labels = np.array([(i, *x.gold) for i, x in enumerate(steps)], dtype=np.int64)
    ssvm = CuttingPlaneSSVM(model, C=C, tol=scorer.tol, max_iter=scorer.max_iter, n_slacks=0)
    ssvm.fit(list(range(len(steps))), labels)
    model.mrf.release()
    if not ssvm.converged_:
        raise RuntimeError(f"a room correction at C = {C:g} did not reach the gap {scorer.tol:g} in "
                           f"{scorer.max_iter} iterations")
    return model, ssvm


def corrected(scorer: StepScorer, steps: list[StepContext], C: float) -> StepScorer:
    """`scorer` with a room correction fitted at C to `steps`."""
    model, ssvm = fit_correction(scorer, steps, C)
    return StepScorer.from_weights(scorer.features, model.weights(ssvm.w_), C=scorer.C, tol=scorer.tol,
                                   max_iter=scorer.max_iter, n_slacks=scorer.n_slacks)


def taught_steps(room: Taught, k: int) -> list[StepContext]:
    """The steps of the first k tasks shown in `room`, as a person's records are written and read back."""
    records = written_and_read_back([person_record(Environment(room.env_id, room.env_id, room.state), task,
                                                   list(actions), SCRIPTED) for task, actions in room.shown[:k]])
    return build_steps(records)[0]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--Cs", type=float, nargs="+", default=[0.1, 0.3, 1.0],
                        help="the correction's C, to try (default: 0.1 0.3 1); no correction is always run too, "
                             "as what the others are compared with")
    add_dev_options(parser)
    args = parser.parse_args(argv)
    if any(not c > 0 for c in args.Cs):
        parser.error("--Cs: every C must be positive")
    dev = dev_setting(parser, args)
    most = max(dev.params.teach.k)
    lessons: dict[int, tuple[Taught, list[StepContext]]] = {}  # each room's taught steps, read back once

    def lesson(room: Taught) -> list[StepContext]:
        if id(room) not in lessons:
            lessons[id(room)] = (room, taught_steps(room, most))  # the room kept: its id is not reused meanwhile
        return lessons[id(room)][1]

    rows = room_variants(dev, [0.0, *sorted(set(args.Cs))],
                         lambda fitted, room, C: corrected(fitted, lesson(room), C) if C else fitted, "C")
    show_variants(dev, rows, "C", args.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
