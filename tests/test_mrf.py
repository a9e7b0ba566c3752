"""The MRF model: vectorised scores against a plain reference, families, names, features files."""

import dataclasses

import numpy as np
import pytest

from taskseq.features.dataset import read_features, write_features
from taskseq.learn.mrf import CLIQUE_FAMILIES, EDGE_FAMILIES, FEATURE_SETS, N_PRIM, StepMRF, candidate_index
from taskseq.learn.products import matmul
from taskseq.sim.primitives import ALL_PRIMITIVES, ARITY


@pytest.fixture(scope="module")
def some_steps(benchmark_steps):
    contexts, _ = benchmark_steps
    rng = np.random.default_rng(1)
    return [contexts[i] for i in rng.choice(len(contexts), size=25, replace=False)]


def test_candidates_respect_arity():
    n = 6
    p, a1, a2 = candidate_index(n)
    for prim, arity in ARITY.items():
        k = ALL_PRIMITIVES.index(prim)
        sel = p == k
        assert sel.sum() == {0: 1, 1: n, 2: n * (n - 1)}[arity]
        assert np.all((a1[sel] >= 0) == (arity >= 1)) and np.all((a2[sel] >= 0) == (arity == 2))
    assert not np.any((a1 == a2) & (a1 >= 0))


@pytest.mark.parametrize("features", ["full", "edge", "clique", "relations"])
def test_vectorised_scores_equal_the_per_candidate_reference(some_steps, features):
    model = StepMRF(features)
    rng = np.random.default_rng(2)
    for x in some_steps[:8]:
        w = rng.normal(size=model.size_joint_feature)
        (cp, ca1, ca2), scores = model.scores(x, w)
        slow = np.array([w @ model.joint_feature(x, (p, a, b)) for p, a, b in zip(cp, ca1, ca2, strict=True)])
        np.testing.assert_allclose(scores, slow, rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("features", ["full", "relations"])
def test_weights_arranged_once_score_as_a_fresh_model_and_follow_a_change_in_place(some_steps, features):
    """A model keeps the weights it arranged last (a planner scores step after step with one model's): its
    scores are a fresh model's bits, for the same weights, for weights changed in place and for new ones."""
    model = StepMRF(features)
    w = np.random.default_rng(4).normal(size=model.size_joint_feature)
    for x in some_steps[:6]:
        assert np.array_equal(model.scores(x, w)[1], StepMRF(features).scores(x, w)[1])
    x = some_steps[0]
    w *= 2.0  # the same array, other values
    assert np.array_equal(model.scores(x, w)[1], StepMRF(features).scores(x, w.copy())[1])
    other = w[::-1].copy()
    assert np.array_equal(model.scores(x, other)[1], StepMRF(features).scores(x, other)[1])
    model.release()  # a fitted scorer handed back by a worker carries neither the batch nor the weights
    assert model._arranged is None


@pytest.mark.parametrize("features", ["full", "relations"])
def test_batched_inference_and_joint_features_equal_the_per_step_ones(some_steps, features):
    model = StepMRF(features)
    w = np.random.default_rng(3).normal(size=model.size_joint_feature)
    gold = [x.gold for x in some_steps]
    assert model.batch_inference(some_steps, w) == [model.inference(x, w) for x in some_steps]
    y_hat = model.batch_loss_augmented_inference(some_steps, gold, w)
    assert y_hat.tolist() == [list(model.loss_augmented_inference(x, y, w)) for x, y in zip(some_steps, gold,
                                                                                            strict=True)]
    assert model.batch_loss(gold, y_hat).tolist() == [model.loss(y, tuple(r)) for y, r in zip(gold, y_hat,
                                                                                               strict=True)]
    # one sparse row per step, for the demonstrated labels and for the oracle's (arguments absent included)
    for labels in (gold, [tuple(r) for r in y_hat]):
        rows = model.batch_joint_feature_rows(some_steps, labels)
        assert rows.shape == (len(some_steps), model.size_joint_feature)
        dense = np.array([model.joint_feature(x, y) for x, y in zip(some_steps, labels, strict=True)])
        np.testing.assert_array_equal(rows.toarray(), dense)
        assert rows.nnz == np.count_nonzero(dense)


def test_loss_augmented_inference_maximises_score_plus_hamming(some_steps):
    model = StepMRF("full")
    w = np.random.default_rng(4).normal(size=model.size_joint_feature)
    for x in some_steps[:5]:
        (cp, ca1, ca2), scores = model.scores(x, w)
        total = scores + [model.loss(x.gold, y) for y in zip(cp, ca1, ca2, strict=True)]
        y_hat = model.loss_augmented_inference(x, x.gold, w)
        k = int(np.argmax(total))
        assert y_hat == (cp[k], ca1[k], ca2[k])


def test_score_tables_refuse_factors_the_oracle_would_read_past(some_steps):
    """The compiled oracle indexes the tables without bounds checks, so tables whose shapes disagree are refused
    when made: a low-rank left factor wider than the right one (as a model without relations would make with a
    width of 1 instead of 0) would otherwise be read past its end."""
    for features in ("full", "relations"):
        model = StepMRF(features)
        tables = model.batch_tables(model._batch(some_steps[:4]), np.ones(model.size_joint_feature))
        S, N = tables.collide.shape[:2]
        assert tables.left.shape[:3] == (tables.P.shape[1], S, N)
        assert tables.left.shape[-1] == tables.right.shape[-1]
        assert (tables.right.shape[-1] > 0) == (features == "relations")  # the pairwise relation term's rank
        wider = np.zeros(tables.left.shape[:3] + (tables.right.shape[-1] + 1,))
        with pytest.raises(ValueError, match=r"Tables\.left has shape .* expected"):
            dataclasses.replace(tables, left=wider)
        with pytest.raises(ValueError, match=r"Tables\.U2 has shape"):
            dataclasses.replace(tables, U2=tables.U2[:-1])


def test_edge_and_clique_use_exactly_their_families(some_steps):
    full, edge, clique = StepMRF("full"), StepMRF("edge"), StepMRF("clique")
    assert set(edge.family_of()) == set(EDGE_FAMILIES)
    assert set(clique.family_of()) == set(CLIQUE_FAMILIES)
    assert sorted(edge.feature_names() + clique.feature_names()) == sorted(full.feature_names())
    index = {n: i for i, n in enumerate(full.feature_names())}
    for x in some_steps[:5]:
        phi = full.joint_feature(x, x.gold)
        for sub in (edge, clique):
            cols = [index[n] for n in sub.feature_names()]
            np.testing.assert_array_equal(sub.joint_feature(x, x.gold), phi[cols])


def test_every_weight_has_a_readable_name():
    names = StepMRF("full").feature_names()
    assert len(names) == len(set(names)) == StepMRF("full").size_joint_feature
    for name in ("primitive_previous_task1[pour,hold_above->follow_traj_pour]",
                 "primitive_argument_environment1[grasp,has_load]", "primitive_task[stir,follow_traj_circle]",
                 "argument_environment_task_relation1[pick_and_place,is_task_arg1]",
                 "argument_environment_pair[collide]", "primitive_argument_previous_argument2[hold_above,a1_prev1]"):
        assert name in names


def test_unknown_feature_set_is_refused():
    with pytest.raises(ValueError, match="features must be one of"):
        StepMRF("nodes")


def test_feature_files_round_trip(benchmark_steps, tmp_path):
    contexts, meta = benchmark_steps
    write_features(contexts[:60], meta[:60], tmp_path / "features")
    back, back_meta = read_features(tmp_path / "features")
    assert back_meta == meta[:60]
    for a, b in zip(contexts[:60], back, strict=True):
        assert a.object_ids == b.object_ids and a.gold == b.gold and a.task == b.task
        assert a.prev_prims == b.prev_prims and a.prev_args == b.prev_args
        np.testing.assert_array_equal(a.objects, b.objects)
        np.testing.assert_array_equal(a.task_rel, b.task_rel)
        np.testing.assert_array_equal(a.collide, b.collide)
        np.testing.assert_array_equal(a.relations, b.relations)


def test_the_paper_models_ignore_relations_and_the_relations_model_needs_them(some_steps):
    from dataclasses import replace

    w_full = np.random.default_rng(5).normal(size=StepMRF("full").size_joint_feature)
    stripped = [replace(x, relations=None) for x in some_steps]
    assert StepMRF("full").batch_inference(stripped, w_full) == StepMRF("full").batch_inference(some_steps, w_full)
    model = StepMRF("relations")
    with pytest.raises(ValueError, match="needs steps with relations"):
        model.batch_inference(stripped, np.zeros(model.size_joint_feature))


def test_steps_include_a_final_done(benchmark_steps):
    contexts, meta = benchmark_steps
    done = ALL_PRIMITIVES.index("done")
    last = {}
    for x, m in zip(contexts, meta, strict=True):
        last[m.sequence_id] = x
    assert all(x.gold == (done, -1, -1) for x in last.values())
    assert sum(x.gold[0] == done for x in contexts) == len(last) == 127


@pytest.mark.parametrize("features", ["full", "relations"])
def test_the_lazy_ranking_is_top_k_of_every_candidate(some_steps, features):
    """A policy walking down `ranked` reads what `top_k` of all candidates gives, ties to the earlier candidate."""
    model = StepMRF(features)
    w = np.random.default_rng(5).normal(size=model.size_joint_feature)
    w[::3] = 0.0
    for x in some_steps[:4]:
        n_cand = len(candidate_index(x.n)[0])
        assert list(model.ranked(x, w)) == model.top_k(x, w, n_cand)
        head = model.ranked(x, w)
        assert [next(head) for _ in range(3)] == model.top_k(x, w, 3)
    x = max(some_steps, key=lambda c: c.n)
    ties = list(model.ranked(x, np.zeros(model.size_joint_feature)))  # every score 0: candidate order
    assert [y for y, _ in ties] == list(zip(*(a.tolist() for a in candidate_index(x.n)), strict=True))
    few = np.zeros(model.size_joint_feature)  # a few small whole weights: many candidates tie at each score
    few[np.random.default_rng(6).choice(len(few), size=12, replace=False)] = [1.0, 2.0, -1.0] * 4
    (cp, ca1, ca2), s = model.scores(x, few)
    order = np.lexsort((np.arange(len(s)), -s))
    assert [y for y, _ in model.ranked(x, few)] == [(int(cp[i]), int(ca1[i]), int(ca2[i])) for i in order]
    assert len(np.unique(s)) < len(s) // 10  # the ties are there to break


def _numpy_argument_tables(model: StepMRF, b, w: np.ndarray) -> list[np.ndarray]:
    """U1 and U2 as the broadcast NumPy sums of `products.matmul` made them: the bits the kernel must give."""
    S, N = b.valid.shape
    holding = (b.objects[:, :, 0] > 0.5).any(axis=1)
    U = []
    for s in (1, 2):
        unary = np.zeros((S, N))
        if (wt := model._w(w, f"argument_environment{s}")) is not None:
            unary += matmul(b.objects[:, :, [0, 1]], wt)
        if (wt := model._w(w, f"argument_environment_task_relation{s}")) is not None:
            unary += matmul(b.task_rel, wt[b.task][:, :, None])[:, :, 0]
        if (wt := model._w(w, f"argument_environment_task_object{s}")) is not None:
            unary += matmul(b.objects, wt[b.task, np.where(holding, 0, 1)][:, :, None])[:, :, 0]
        table = np.repeat(unary[:, :, None], N_PRIM, axis=2)
        for family, rows in (("primitive_argument_environment", b.objects),
                             ("primitive_argument_previous_argument", b.hist)):
            if (wt := model._w(w, f"{family}{s}")) is not None:
                table += matmul(rows, wt.T)
        for family, rows in (("relations", b.relations_rows), ("cues", b.cues_rows)):
            if (wt := model._w(w, f"{family}{s}")) is not None:
                table += matmul(rows, wt[b.task].transpose(0, 2, 1))
        U.append(table.transpose(0, 2, 1))
    return U


@pytest.mark.parametrize("features", sorted(FEATURE_SETS))
def test_the_compiled_tables_and_oracle_give_the_bits_of_the_numpy_sums(some_steps, features):
    """The kernels sum each table entry and each pair's score in the order the broadcast NumPy sums did, and
    the oracle breaks ties as `argmax` over the per-candidate scores does."""
    model = StepMRF(features)
    b = model._batch(some_steps)
    rng = np.random.default_rng(7)
    gold = np.array([x.gold for x in some_steps])
    for w in (rng.normal(size=model.size_joint_feature) * 10.0 ** rng.integers(-3, 4, model.size_joint_feature),
              np.round(rng.normal(size=model.size_joint_feature), 1), np.zeros(model.size_joint_feature)):
        f = model.batch_tables(b, w)
        for table, expected in zip((f.U1, f.U2), _numpy_argument_tables(model, b, w), strict=True):
            assert table.tobytes() == np.ascontiguousarray(expected).tobytes()
        for x, y in zip(some_steps, model.batch_loss_augmented_inference(some_steps, gold, w), strict=True):
            assert tuple(y) == model.loss_augmented_inference(x, x.gold, w)
