"""Measure a room prior for teaching on drawn development worlds: does favouring the taught objects pay?

The `teach` stage lets a room's k demonstrations weigh by counting each taught
step `teach.weight` times in a refit. A person teaches their room's ways
(which bin, which cup, which spoon), so another way to let them weigh is a
prior: in a taught room, every candidate step that uses an object in the
position a taught step used it (`grasp` of this mug, `place_above` onto this
table) gets `beta` added to its score for each such use, for every task of the room, with or
without the refit. This script measures that on the teach protocol
(`taskseq.stages.teach`: the rooms `teach.environments` held out, the first
max(`teach.k`) tasks of each taught, every other task judged) for each beta of a grid,
on development draws only (`world.dev_seed` by default; `--dev-seeds` adds
others, never a reported one), and prints the sequence-arg misses and the
successes pooled over the draws, against the planner without the prior.
docs/teach.md shows the table this writes:

    python scripts/teach_room_prior.py --betas 0.25 0.5 1 2 --dev-seeds 100 101 102 103 104 \
        --output reports/teach_room_prior.json

Run it after `dvc repro` has run `select` (the shipped planner and its C are read from reports/selection.json).
"""

from __future__ import annotations

import argparse
import itertools
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "scripts"))  # the teach protocol's options and checks, as teach_weight.py has them

from teach_weight import add_dev_options, dev_setting, room_variants, show_variants  # noqa: E402

from taskseq.experiments.teaching import Taught  # noqa: E402
from taskseq.features.context import StepContext  # noqa: E402
from taskseq.learn.estimator import StepScorer  # noqa: E402
from taskseq.sim.primitives import ALL_PRIMITIVES  # noqa: E402

Use = tuple[str, int, str]  # (primitive, argument position, object id) of a taught step


class RoomPrior:
    """A fitted scorer whose candidates that use an object as a taught step did score `beta` more per such use;
    it ranks as `StepScorer.ranked` does (ties: the earlier candidate first), which is all a policy asks of it."""

    def __init__(self, scorer: StepScorer, uses: set[Use], beta: float) -> None:
        self.scorer, self.uses, self.beta = scorer, uses, beta

    def scores(self, x: StepContext) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], np.ndarray]:
        (cp, ca1, ca2), s = self.scorer.model_.scores(x, self.scorer.w_)
        position = {o: i for i, o in enumerate(x.object_ids)}
        bonus = np.zeros(len(s))
        for primitive, k, obj in self.uses:
            if obj in position:
                bonus += (cp == ALL_PRIMITIVES.index(primitive)) & ((ca1, ca2)[k] == position[obj])
        return (cp, ca1, ca2), s + self.beta * bonus

    def ranked(self, x: StepContext) -> Iterator[tuple[tuple[int, int, int], float]]:
        (cp, ca1, ca2), s = self.scores(x)
        for i in np.argsort(-s, kind="stable"):
            yield (int(cp[i]), int(ca1[i]), int(ca2[i])), float(s[i])

    def top_k(self, x: StepContext, k: int) -> list[tuple[tuple[int, int, int], float]]:
        return list(itertools.islice(self.ranked(x), k))


def taught_uses(room: Taught, k: int) -> set[Use]:
    """Every (primitive, position, object) of the first k tasks a person shows in `room`."""
    return {(a.primitive, i, obj) for _, actions in room.shown[:k] for a in actions for i, obj in enumerate(a.args)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--betas", type=float, nargs="+", default=[0.25, 0.5, 1.0, 2.0],
                        help="score added per taught use, to try (default: 0.25 0.5 1 2); 0, no prior, is always "
                             "run too, as what the others are compared with")
    add_dev_options(parser)
    args = parser.parse_args(argv)
    if any(b < 0 for b in args.betas):
        parser.error("--betas: a prior favours the taught objects, so every beta must be at least 0")
    betas = sorted({0.0, *args.betas})
    dev = dev_setting(parser, args)
    most = max(dev.params.teach.k)
    rows = room_variants(dev, betas, lambda fitted, room, beta: RoomPrior(fitted, taught_uses(room, most), beta),
                         "beta")
    show_variants(dev, rows, "beta", args.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
