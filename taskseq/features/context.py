"""What the model sees of one step: per-object rows, task relations, collisions, history.

A `StepContext` holds everything the six feature families need, laid out as
arrays over the step's objects, so that a score for every candidate
`primitive(a1, a2)` comes from a few broadcast operations (see
`taskseq.learn.mrf`). Object names and categories never enter it.

Continuous values are scaled to about [0, 1] by fixed transforms, so a model
needs no fitted scaler and a step's features do not depend on the training
set: lengths on a log scale from 1 cm to 10 m, volume on a log scale from
1 cm^3 to 100 m^3, distance in units of 10 m.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..sim.objects import BINARY_ATTRIBUTES, CONTINUOUS_ATTRIBUTES, ObjectSpec
from ..sim.primitives import ALL_PRIMITIVES, ARITY, Action
from ..sim.state import EPS, INSIDE, ON, WorldState, within_reach
from ..sim.tasks import TASKS, Task

N_PRIM = len(ALL_PRIMITIVES)  # the seven primitives and done
NO_PRIM = N_PRIM  # history index when there is no previous step
PRIM_INDEX = {p: i for i, p in enumerate(ALL_PRIMITIVES)}
ARITIES = np.array([ARITY[p] for p in ALL_PRIMITIVES])
TASK_INDEX = {t: i for i, t in enumerate(TASKS)}

STATE_COLUMNS = ("held", "distance", "reachable", "has_load", "over_shelf", "holds_liquid")
ATTRIBUTE_COLUMNS = CONTINUOUS_ATTRIBUTES + BINARY_ATTRIBUTES
OBJECT_COLUMNS = STATE_COLUMNS + ATTRIBUTE_COLUMNS
TASK_REL_COLUMNS = ("is_task_arg1", "is_task_arg2", "overlaps_task_arg1", "overlaps_task_arg2")
HISTORY_ARG_COLUMNS = ("a1_prev1", "a2_prev1", "a1_prev2", "a2_prev2")
# Relations of every object to three reference objects of the step: the task's first argument, the
# container that holds it, and the object in the gripper. Geometry and state only: never names or categories.
RELATION_REFERENCES = ("object", "container", "held")
VOLUME_RATIOS = (1.0, 1.25, 1.5, 1.75, 2.0, 2.5, 3.0, 4.0)  # volume at least this many times the reference's
LENGTH_MARGINS = (0.0, 0.02, 0.04, 0.06, 0.1)  # longest side at least this much (m) over the reference's height
RELATION_KINDS = ("is", *(f"volume_ge_{r:g}x" for r in VOLUME_RATIOS), "log_volume_ratio",
                  *(f"length_over_height_ge_{m:g}m" for m in LENGTH_MARGINS), "near")
RELATION_COLUMNS = tuple(f"{k}_{r}" for r in RELATION_REFERENCES for k in RELATION_KINDS)

_LENGTHS = {"height", "max_wl", "min_wl"}

_SQRT_HALF = math.sqrt(0.5)  # a square root is correctly rounded everywhere
_LOG10_2 = 0.3010299956639812  # log10 2 and log10 e, correctly rounded
_LOG10_E = 0.4342944819032518
_ATANH_SERIES = tuple(1.0 / k for k in range(25, 0, -2))  # 1/25, 1/23, ..., 1/1: Horner's order


def log10(x: np.ndarray | float) -> np.ndarray:
    """log10 of positive finite `x`, from IEEE-754 multiplies, adds and divides only.

    Why not `np.log10` or `math.log10`: neither gives the same bits on every
    x86-64 processor. NumPy computes `np.log10` with SVML where it finds
    AVX-512 and with the C library elsewhere, and glibc picks its `log` (which
    `log10` calls) by whether the processor has FMA. The relation features
    written with `np.log10` changed their last bits under
    `NPY_DISABLE_CPU_FEATURES`, and the learned weights with them;
    `math.log10` changes under `GLIBC_TUNABLES` that hide FMA. Basic
    operations are correctly rounded everywhere. x = m 2^e with m in [sqrt(1/2), sqrt(2)),
    ln m = 2 atanh(s) with s = (m - 1) / (m + 1), |s| < 0.172, whose series
    to s^25 is within a few ulp of the exact logarithm (exact at powers of ten).
    """
    m, e = np.frexp(np.asarray(x, dtype=np.float64))
    low = m < _SQRT_HALF
    m, e = np.where(low, 2.0 * m, m), e - low
    s = (m - 1.0) / (m + 1.0)
    s2 = s * s
    series = np.zeros_like(s)
    for c in _ATANH_SERIES:
        series = series * s2 + c
    return e * _LOG10_2 + 2.0 * s * series * _LOG10_E


def scale_attribute(name: str, value: float) -> float:
    if name in _LENGTHS:
        return float(log10(max(value, 1e-3) / 0.01)) / 3.0
    if name == "volume":
        return float(log10(max(value, 1e-9) / 1e-6)) / 8.0
    return float(value)  # ratios and flags are already in [0, 1]


@dataclass
class StepContext:
    """One decision point: the world before a step, the task and the last two steps."""

    object_ids: list[str]
    objects: np.ndarray  # (n, len(OBJECT_COLUMNS)) float
    task_rel: np.ndarray  # (n, 4) float
    collide: np.ndarray  # (n, n) bool, diagonal False
    task: int
    prev_prims: tuple[int, int]  # primitive index at t-1 and t-2 (NO_PRIM if none)
    prev_args: tuple[int, int, int, int]  # object index of a1,a2 at t-1 and a1,a2 at t-2 (-1 if none)
    gold: tuple[int, int, int] | None = None  # (primitive, a1, a2), -1 for an absent argument
    relations: np.ndarray | None = None  # (n, len(RELATION_COLUMNS)) float; only the `relations` model reads it

    @property
    def n(self) -> int:
        return len(self.object_ids)

    @property
    def holding(self) -> bool:
        """Whether the gripper holds an object."""
        return bool((self.objects[:, 0] > 0.5).any())

    def history_equal(self) -> np.ndarray:
        """(n, 4) bits: object i is a1/a2 of step t-1, a1/a2 of step t-2."""
        out = np.zeros((self.n, 4))
        for k, a in enumerate(self.prev_args):
            if a >= 0:
                out[a, k] = 1.0
        return out

    def action(self, y: tuple[int, int, int]) -> Action:
        p, a1, a2 = y
        args = tuple(self.object_ids[a] for a in (a1, a2) if a >= 0)
        return Action(ALL_PRIMITIVES[p], args)

    def history(self) -> list[Action]:
        """The steps this context remembers (the last two at most), oldest first: `step_context` given them
        and the same world and task makes the same context again."""
        out = []
        for k in (1, 0):
            if self.prev_prims[k] != NO_PRIM:
                args = tuple(self.object_ids[a] for a in self.prev_args[2 * k: 2 * k + 2] if a >= 0)
                out.append(Action(ALL_PRIMITIVES[self.prev_prims[k]], args))
        return out

    def encode(self, action: Action) -> tuple[int, int, int]:
        index = {o: i for i, o in enumerate(self.object_ids)}
        try:
            args = [index[a] for a in action.args]
        except KeyError as err:
            raise ValueError(f"{action}: object {err.args[0]} is not in this step's environment") from None
        args += [-1] * (2 - len(args))
        return PRIM_INDEX[action.primitive], args[0], args[1]


def _log_ratio(a: np.ndarray, b: np.ndarray | float) -> np.ndarray:
    """log10(a / b) over two decades, clipped to [-1, 1] (entry by entry: `a` and `b` broadcast)."""
    return np.clip(log10(np.maximum(a, 1e-9) / np.maximum(b, 1e-9)) / 2.0, -1.0, 1.0)


def relations(state: WorldState, task: Task, ids: list[str],
              attrs: list[dict[str, float]] | None = None) -> np.ndarray:
    """(n, len(RELATION_COLUMNS)): how each object compares with the step's reference objects.

    Volume against the reference's volume, as a log ratio and as steps (does it
    hold as much, a quarter more, ... four times as much), longest side against
    the reference's height as steps of margin (does it reach out of it), and
    nearness (horizontal distance under 1 m, scaled). Steps let a linear score
    prefer "just big enough" over "bigger". A missing reference (no container,
    an empty gripper) leaves its columns at zero; no object is compared with itself.
    `attrs` are the objects' attributes in `ids` order, when the caller has them already.
    """
    attrs = attrs if attrs is not None else [state.specs[o].attributes() for o in ids]
    volume = np.array([a["volume"] for a in attrs])
    length = np.array([a["max_wl"] for a in attrs])
    xy = np.array([state.poses[o][:2] for o in ids])
    first = task.args[0] if task.args else None
    refs = (first, state.container_of(first) if first in state.specs else None, state.held)
    present = [(r, ids.index(ref)) for r, ref in enumerate(refs) if ref is not None and ref in state.specs]
    n, k = len(ids), len(RELATION_KINDS)
    out = np.zeros((n, len(RELATION_COLUMNS)))
    if not present:
        return out
    at = np.array([j for _, j in present])
    # every reference's log volume ratio in one call: the same operations on each entry as one call per reference
    log_ratios = _log_ratio(volume[None, :], volume[at][:, None])
    for (r, j), log_ratio in zip(present, log_ratios, strict=True):
        cols = out[:, r * k : (r + 1) * k]
        ratio = volume / volume[j]
        margin = length - attrs[j]["height"]
        d = np.hypot(*(xy - xy[j]).T)
        cols[:, 0] = np.arange(n) == j
        cols[:, 1 : 1 + len(VOLUME_RATIOS)] = ratio[:, None] >= np.array(VOLUME_RATIOS)
        c = 1 + len(VOLUME_RATIOS)
        cols[:, c] = log_ratio
        cols[:, c + 1 : c + 1 + len(LENGTH_MARGINS)] = margin[:, None] >= np.array(LENGTH_MARGINS)
        cols[:, -1] = np.clip(1.0 - d, 0.0, 1.0)
        cols[j, 1:] = 0.0
    return out


@lru_cache(maxsize=4096)
def _spec_row(spec: ObjectSpec) -> tuple[dict[str, float], np.ndarray]:
    """An object's attributes and their scaled row: they never change, and every step of a run needs them."""
    attrs = spec.attributes()
    row = np.array([scale_attribute(a, attrs[a]) for a in ATTRIBUTE_COLUMNS])
    row.flags.writeable = False
    return attrs, row


def step_context(
    state: WorldState,
    task: Task,
    history: list[Action],
    gold: Action | None = None,
) -> StepContext:
    """Features of `state` for the next step of `task` after the steps in `history`."""
    ids = sorted(state.specs)
    index = {o: i for i, o in enumerate(ids)}
    n = len(ids)
    objects = np.zeros((n, len(OBJECT_COLUMNS)))
    rows = [_spec_row(state.specs[o]) for o in ids]
    all_attrs = [attrs for attrs, _ in rows]
    # one pass over what rests on what, not one per object
    loaded = {p for p, r in state.support.values() if r == ON}
    wet = {p for c, (p, r) in state.support.items() if r == INSIDE and state.specs[c].has("liquid")}
    shelved, robot = state.shelved(), state.robot
    box_of = [state.box(o) for o in ids]
    objects[:, : len(STATE_COLUMNS)] = [
        (float(state.held == o), min(state.distance(o), 10.0) / 10.0,
         float(within_reach(box, robot)),  # `WorldState.reachable`, its box made once
         float(o in loaded), float(o in shelved), float(o in wet))
        for o, box in zip(ids, box_of, strict=True)]
    objects[:, len(STATE_COLUMNS) :] = [row for _, row in rows]
    boxes = np.array(box_of)
    task_rel = np.zeros((n, 4))
    for k, g in enumerate(task.args[:2]):
        if g in index:
            j = index[g]
            task_rel[j, k] = 1.0
            # footprints share area seen from above (`WorldState.overlap_top`), every object at once
            over = np.all((boxes[:, :2] < boxes[j, 3:5] - EPS) & (boxes[j, :2] < boxes[:, 3:5] - EPS), axis=1)
            over[j] = False
            task_rel[over, 2 + k] = 1.0
    eps = 1e-6
    lo, hi = boxes[:, :3], boxes[:, 3:]
    collide = np.all((lo[:, None, :] <= hi[None, :, :] + eps) & (lo[None, :, :] <= hi[:, None, :] + eps), axis=2)
    np.fill_diagonal(collide, False)
    prev = list(reversed(history[-2:]))
    prev_prims = tuple(PRIM_INDEX[a.primitive] for a in prev) + (NO_PRIM,) * (2 - len(prev))
    prev_args: list[int] = []
    for k in range(2):
        args = list(prev[k].args) if k < len(prev) else []
        prev_args += [index.get(a, -1) for a in args] + [-1] * (2 - len(args))
    ctx = StepContext(ids, objects, task_rel, collide, TASK_INDEX[task.name], prev_prims, tuple(prev_args),
                      relations=relations(state, task, ids, all_attrs))
    if gold is not None:
        ctx.gold = ctx.encode(gold)
    return ctx


def is_candidate(label: Sequence[int], n: int) -> bool:
    """Whether `label` (p, a1, a2) is among `candidate_index(n)`, decided from the arities alone (a fit checks every
    label, and scanning each step's candidates cost more than the check is worth)."""
    p, a1, a2 = label
    if p not in range(len(ARITIES)):
        return False
    arity, objects = ARITIES[int(p)], range(n)
    if arity == 0:
        return a1 == -1 and a2 == -1
    if arity == 1:
        return a1 in objects and a2 == -1
    return a1 in objects and a2 in objects and a1 != a2


@lru_cache(maxsize=64)
def candidate_index(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every (p, a1, a2) that respects arity over n objects; -1 marks an absent argument.

    Ordered by primitive, then a1, then a2: ties in score go to the first.
    """
    ps, a1s, a2s = [], [], []
    objs = np.arange(n)
    for p, arity in enumerate(ARITIES):
        if arity == 0:
            ps.append([p])
            a1s.append([-1])
            a2s.append([-1])
        elif arity == 1:
            ps.append(np.full(n, p))
            a1s.append(objs)
            a2s.append(np.full(n, -1))
        else:
            i, j = np.meshgrid(objs, objs, indexing="ij")
            keep = i != j
            ps.append(np.full(int(keep.sum()), p))
            a1s.append(i[keep])
            a2s.append(j[keep])
    arrays = tuple(np.concatenate(a).astype(np.int64) for a in (ps, a1s, a2s))
    for a in arrays:
        a.setflags(write=False)
    return arrays  # type: ignore[return-value]
