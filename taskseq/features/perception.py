"""Perception that gets binary attributes wrong: at test time (attribute noise) and, on purpose, in training.

A robot's detectors report each binary attribute (container, movable,
liquid, ...) of each object, and sometimes report it wrongly. `flip_masks`
draws which ones a run gets wrong and `noisy_perception` applies them to
every step of the run alike, as one detector's mistake persists while the
scene stays the same. `noisy_copies` makes training steps the same way:
copies of a scenario's demonstrated steps seen with flipped attributes and
labelled with the demonstrated step, so the learned weights do not lean on
any single attribute being right.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from ..sim.objects import BINARY_ATTRIBUTES
from .context import OBJECT_COLUMNS, StepContext
from .dataset import StepMeta

BINARY_COLUMNS = np.array([OBJECT_COLUMNS.index(a) for a in BINARY_ATTRIBUTES])


def flip_masks(object_ids: list[str], rate: float, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """For each object, which binary attributes the robot perceives wrongly in this run."""
    return {o: rng.random(len(BINARY_COLUMNS)) < rate for o in object_ids}


def noisy_perception(masks: dict[str, np.ndarray]) -> Callable[[StepContext], StepContext]:
    """A `perceive` hook that flips the masked binary attributes of every object, every step alike."""

    flips: dict[tuple[str, ...], np.ndarray] = {}  # (n, binary attributes) masks, rows in a step's object order

    def perceive(ctx: StepContext) -> StepContext:
        ids = tuple(ctx.object_ids)
        if ids not in flips:
            flips[ids] = np.array([masks[o] for o in ids], dtype=bool).reshape(len(ids), len(BINARY_COLUMNS))
        objects = ctx.objects.copy()
        binary = objects[:, BINARY_COLUMNS]
        objects[:, BINARY_COLUMNS] = np.where(flips[ids], 1.0 - binary, binary)
        return replace(ctx, objects=objects)

    return perceive


def noisy_copies(contexts: Sequence[StepContext], meta: Sequence[StepMeta], rate: float,
                 copies: int) -> tuple[list[StepContext], list[StepMeta]]:
    """`copies` copies of the steps, each binary attribute of each object flipped with probability `rate`.

    Copy c of a scenario's steps sees one draw of flips, the same at each of
    its steps (as a test-time run does); the draw is seeded by c and the
    scenario's id alone, so a scenario's copies do not depend on which other
    scenarios a fold trains on. Labels (`gold`) and metadata are the steps'.
    """
    if rate < 0.0 or rate > 1.0:
        raise ValueError(f"noisy copies: the flip rate must be within [0, 1], got {rate}")
    if copies < 0:
        raise ValueError(f"noisy copies: the number of copies must be 0 or more, got {copies}")
    out, out_meta = [], []
    # a draw depends on the copy, the scenario and its objects alone: made once for each, not at every step
    runs: dict[tuple[int, str, tuple[str, ...]], Callable[[StepContext], StepContext]] = {}
    for c in range(copies):
        for ctx, m in zip(contexts, meta, strict=True):
            key = (c, m.scenario_id, tuple(sorted(ctx.object_ids)))
            if key not in runs:
                rng = np.random.default_rng([c, zlib.crc32(m.scenario_id.encode())])
                runs[key] = noisy_perception(flip_masks(list(key[2]), rate, rng))
            out.append(runs[key](ctx))
            out_meta.append(m)
    return out, out_meta
