"""The domain MRF: its scores are w . joint feature, its inference the brute-force best, and the SSVM learns it."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from taskseq.learn.ssvm import CuttingPlaneSSVM
from taskseq.veil.mrf import FEATURE_SETS, DomainMRF, StepInput, best_first

ARITIES = (0, 1, 1, 2, 2)


def random_step(rng: np.random.Generator, n: int, n_row: int = 6, n_pair: int = 3, n_tasks: int = 3) -> StepInput:
    pairs = np.array([(a, b) for a in range(n) for b in range(n) if a != b and rng.random() < 0.2], dtype=int)
    pairs = pairs.reshape(-1, 2)
    return StepInput(rows=(rng.random((n, n_row)) < 0.4).astype(float),
                     history=(rng.random((n, 4)) < 0.2).astype(float),
                     pair_index=pairs, pair_rows=(rng.random((len(pairs), n_pair)) < 0.5).astype(float),
                     task=int(rng.integers(n_tasks)), prev=(int(rng.integers(6)), int(rng.integers(6))),
                     holding=bool(rng.random() < 0.5))


def candidates(x: StepInput) -> list[tuple[int, int, int]]:
    out = []
    for v, arity in enumerate(ARITIES):
        if arity == 0:
            out.append((v, -1, -1))
        elif arity == 1:
            out += [(v, a, -1) for a in range(x.n)]
        else:
            out += [(v, a, b) for a in range(x.n) for b in range(x.n) if a != b]
    return out


@pytest.mark.parametrize("features", sorted(FEATURE_SETS))
def test_scores_are_the_weights_times_the_joint_feature_and_inference_is_the_best(features: str) -> None:
    rng = np.random.default_rng(0)
    model = DomainMRF(ARITIES, n_tasks=3, n_row=6, n_pair=3, features=features)
    X = [random_step(rng, n) for n in (3, 5, 4, 5)]
    w = rng.normal(size=model.size_joint_feature)
    for x in X:
        labels, values = model.scores(x, w)
        brute = {c: float(w @ model.joint_feature(x, c)) for c in candidates(x)}
        assert len(labels) == len(brute)
        for label, value in zip(labels, values, strict=True):
            assert value == pytest.approx(brute[tuple(int(t) for t in label)], abs=1e-9)
        assert model.inference(x, w) == max(brute, key=brute.get)
        gold = candidates(x)[int(rng.integers(len(brute)))]
        augmented = {c: s + model.loss(gold, c) for c, s in brute.items()}
        assert model.loss_augmented_inference(x, gold, w) == max(augmented, key=augmented.get)
    batch = model.batch_inference(X, w)
    assert [tuple(r) for r in batch] == [model.inference(x, w) for x in X]


def test_labels_name_the_candidates_in_the_order_of_their_scores() -> None:
    """`labels` decodes an index of `candidate_scores` into the candidate the brute-force list has there."""
    model = DomainMRF(ARITIES, n_tasks=3, n_row=6, n_pair=3)
    for n in (1, 2, 3, 7):
        x = random_step(np.random.default_rng(n), n)
        assert [tuple(int(t) for t in row) for row in model.labels(np.arange(len(candidates(x))), n)] == candidates(x)


@pytest.mark.parametrize("seed", range(6))
def test_best_first_is_the_stable_descending_order_however_far_it_is_read(seed: int) -> None:
    """The lazily sorted ranking equals the whole stable sort, ties (many here) in index order, for every prefix
    length and every read length, the prefix's edge falling inside a run of ties included."""
    rng = np.random.default_rng(seed)
    values = rng.integers(0, 1 + 4 * seed, size=int(rng.integers(1, 900))).astype(float)
    whole = np.argsort(-values, kind="stable").tolist()
    for first in (1, 2, 5, 16, 1000):
        assert np.concatenate(list(best_first(values, first))).tolist() == whole
        read = itertools.chain.from_iterable(best_first(values, first))
        length = int(rng.integers(0, len(values) + 1))
        assert [next(read) for _ in range(length)] == whole[:length]


def test_the_ssvm_learns_a_rule_that_depends_on_an_attribute_and_the_task() -> None:
    """The gold step is the verb of the task applied to the object with attribute 0 set: learnable, and learned."""
    rng = np.random.default_rng(1)
    X, Y = [], []
    for _ in range(60):
        x = random_step(rng, 5)
        rows = x.rows.copy()
        rows[:, 0] = 0.0
        target = int(rng.integers(5))
        rows[target, 0] = 1.0
        x = StepInput(rows, x.history, x.pair_index, x.pair_rows, x.task, x.prev, x.holding)
        X.append(x)
        Y.append((1 + x.task % 2, target, -1))
    model = DomainMRF(ARITIES, n_tasks=3, n_row=6, n_pair=3)
    learner = CuttingPlaneSSVM(model, C=10.0, tol=1e-4, n_slacks=0).fit(X[:40], Y[:40])
    assert learner.converged_
    predicted = [tuple(int(t) for t in r) for r in learner.predict(X[40:])]
    assert predicted == Y[40:]


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="features"):
        DomainMRF(ARITIES, 3, 6, 3, features="nope")
    with pytest.raises(ValueError, match="arity"):
        DomainMRF((0, 3), 3, 6, 3)
