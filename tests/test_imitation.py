"""Training data beyond the logs: the demonstrator as an expert, chained starts, DAgger."""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest

import taskseq.imitation.dagger as dagger_module
import taskseq.imitation.starts as starts_module
from taskseq.demonstrations.benchmark import Benchmark
from taskseq.evaluate.methods import ScorerMethod
from taskseq.experiments.crossval import run_fold, scenario_folds
from taskseq.features.context import NO_PRIM, candidate_index, step_context
from taskseq.features.dataset import build_steps
from taskseq.imitation.dagger import fit_imitation, rollout_contexts
from taskseq.imitation.expert import DONE, next_actions
from taskseq.imitation.starts import chained_contexts, chained_scenarios, demonstration_contexts
from taskseq.learn.estimator import StepScorer
from taskseq.sim.primitives import Action, PreconditionError, execute, try_execute
from taskseq.sim.tasks import goal_reached

SSVM = {"C": 3.0, "tol": 1e-2, "max_iter": 300, "n_slacks": 0}
ENVS = ("env01", "env02", "env03")


@pytest.fixture(scope="module")
def small(benchmark_tables):
    records = [i.record for i in benchmark_tables[1] if i.record["env_id"] in ENVS]
    contexts, meta = build_steps(records)
    return contexts, meta, Benchmark.from_records(records).scenarios


def follow_expert(scenario, history, state, cap=25):
    """Take the expert's first answer until it says done; returns (history, state, stopped)."""
    for _ in range(cap):
        answers = next_actions(scenario, history, state)
        if not answers:
            return history, state, False
        if answers[0] == DONE:
            return history, state, True
        state = execute(state, answers[0])
        history = (*history, answers[0])
    return history, state, False


def test_on_a_demonstration_the_expert_answers_with_the_log(small):
    _, _, scenarios = small
    for sc in scenarios.values():
        for demo in sc.demonstrations:
            state = sc.initial
            for k in range(len(demo) + 1):
                want = demo[k] if k < len(demo) else DONE
                assert want in next_actions(sc, demo[:k], state), (sc.id, k)
                if k < len(demo):
                    state = execute(state, demo[k])


def test_the_expert_finishes_the_task_after_a_detour(small):
    """Off every demonstration (a wrong first step), following the expert still reaches the goal."""
    _, _, scenarios = small
    tried = finished = 0
    for sc in scenarios.values():
        ctx = step_context(sc.initial, sc.task, [])
        first = {d[0] for d in sc.demonstrations}
        for y in zip(*candidate_index(ctx.n), strict=True):
            detour = ctx.action(tuple(int(v) for v in y))
            if detour.primitive != "move_close" or detour in first:
                continue
            try:
                state = execute(sc.initial, detour)
            except PreconditionError:
                continue
            tried += 1
            history, final, stopped = follow_expert(sc, (detour,), state)
            finished += stopped and goal_reached(sc.task, sc.initial, final)
            break
    assert tried >= 10
    assert finished == tried


def test_chained_scenarios_start_where_a_given_scenario_ended(small):
    _, _, scenarios = small
    given = list(scenarios.values())
    ends = []
    for sc in given:
        state = sc.initial
        for a in sc.demonstrations[0]:
            state = execute(state, a)
        ends.append(state)
    chained = chained_scenarios(given)
    assert len(chained) >= len(given) // 2
    tasks_by_env = {(sc.env_id, sc.task) for sc in given}
    for sc in chained:
        assert (sc.env_id, sc.task) in tasks_by_env  # a task of the same environment
        assert any(sc.initial == e for e in ends)  # starts where a demonstration ended
        for demo in sc.demonstrations:
            state = sc.initial
            for a in demo:
                state = execute(state, a)
            assert goal_reached(sc.task, sc.initial, state)
    assert any(sc.initial.held is not None for sc in chained)  # some start with something in hand


def test_a_process_chains_and_featurises_a_scenario_once(small, monkeypatch):
    """Folds of one world share training scenarios: what was chained for one comes back for the next, equal."""
    _, _, scenarios = small
    given = sorted(scenarios.values(), key=lambda s: s.id)
    real_chain = starts_module._chain
    calls: list[tuple[int, object]] = []

    def spy_chain(env_id, state, task):
        calls.append((id(state), task))
        return real_chain(env_id, state, task)

    monkeypatch.setattr(starts_module, "_chain", spy_chain)
    monkeypatch.setattr(starts_module, "_CHAINED", {})
    monkeypatch.setattr(starts_module, "_CONTEXTS", {})
    first = chained_scenarios(given)
    asked = len(calls)
    assert asked and first
    again = chained_scenarios(given)
    assert len(calls) == asked and all(a is b for a, b in zip(again, first, strict=True))
    chained_scenarios(given[1:])  # another fold: only pairs never tried are chained
    assert len(calls) > asked and len(set(calls)) == len(calls)
    made = [chained_contexts(sc) for sc in first]
    assert all(chained_contexts(sc) is m for sc, m in zip(first, made, strict=True))

    monkeypatch.setattr(starts_module, "_CHAINED", {})  # from nothing again: the same scenarios and steps
    fresh = chained_scenarios(given)
    assert [(sc.id, sc.initial, sc.demonstrations) for sc in fresh] == [
        (sc.id, sc.initial, sc.demonstrations) for sc in first]
    for sc, mine in zip(fresh, made, strict=True):
        plain = demonstration_contexts(sc)
        assert [x.gold for x in mine] == [x.gold for x in plain]
        for x, y in zip(mine, plain, strict=True):
            for field in ("objects", "relations", "task_rel", "collide"):
                np.testing.assert_array_equal(getattr(x, field), getattr(y, field))
            assert (x.object_ids, x.prev_prims, x.prev_args) == (y.object_ids, y.prev_prims, y.prev_args)


def test_the_chaining_memo_empties_both_halves_together_when_full(small, monkeypatch):
    """A process that goes through many worlds keeps a bounded memo: past the cap, what was chained and what
    was featurised are forgotten together (neither half keeps scenarios the other dropped)."""
    _, _, scenarios = small
    given = sorted(scenarios.values(), key=lambda s: s.id)
    monkeypatch.setattr(starts_module, "_CHAINED", {})
    monkeypatch.setattr(starts_module, "_CONTEXTS", {})
    monkeypatch.setattr(starts_module, "_REMEMBERED", 3)
    chained = chained_scenarios(given[:2])
    assert len(starts_module._CHAINED) == 2 and chained
    for sc in chained:
        chained_contexts(sc)
    assert len(starts_module._CONTEXTS) == len(chained) <= 2
    chained_contexts(given[2])  # the third scenario featurised: still within the cap
    assert len(starts_module._CHAINED) == 2 and len(starts_module._CONTEXTS) == len(chained) + 1
    assert len(starts_module._CONTEXTS) == 3  # full: the next call empties both halves first
    chained_contexts(given[3])
    assert (len(starts_module._CHAINED), len(starts_module._CONTEXTS)) == (0, 1)


def test_demonstration_contexts_equal_the_feature_pipelines(small, benchmark_tables):
    contexts, meta, scenarios = small
    sid = meta[0].scenario_id
    mine = demonstration_contexts(scenarios[sid])
    logged = [x for x, m in zip(contexts, meta, strict=True) if m.scenario_id == sid]
    assert [x.gold for x in mine] == [x.gold for x in logged]
    for a, b in zip(mine, logged, strict=True):
        np.testing.assert_array_equal(a.objects, b.objects)
        np.testing.assert_array_equal(a.relations, b.relations)


def test_rollouts_label_only_states_off_the_demonstrations(small):
    contexts, _, scenarios = small
    fit = StepScorer("full", **SSVM).fit(contexts)
    sc = next(iter(scenarios.values()))
    detour = next(a for a in (Action("move_close", (o,)) for o in sorted(sc.initial.specs))
                  if a not in {d[0] for d in sc.demonstrations} and try_execute(sc.initial, a) is not None)

    def rank(ctx, state):  # a planner that first goes somewhere no demonstration goes, then follows the model
        if ctx.prev_prims[0] == NO_PRIM:
            return [(ctx.encode(detour), 0.0)]
        return fit.top_k(ctx, 1)

    asked = []

    def spy(scenario, history, state):
        asked.append(tuple(history))
        assert not any(d[: len(history)] == tuple(history) for d in scenario.demonstrations)
        return next_actions(scenario, history, state)

    seen: set = set()
    out = rollout_contexts(rank, sc, seen, spy)
    assert asked and asked[0] == (detour,) and out
    assert {x.prev_args[0] for x in out[:1]} == {out[0].object_ids.index(detour.args[0])}
    assert rollout_contexts(rank, sc, seen, spy) == []  # a history labelled once is not labelled again


def test_no_augmentation_is_the_plain_fit(small):
    contexts, _, scenarios = small
    plain = StepScorer("full", **SSVM).fit(contexts)
    same = fit_imitation(StepScorer("full", **SSVM), contexts, list(scenarios.values()), rounds=0, chained=False)
    assert plain.w_.tobytes() == same.w_.tobytes()


def test_augmented_fits_are_deterministic_and_grow_the_data(small, monkeypatch):
    contexts, _, scenarios = small
    fits = []
    for _ in range(2):  # each as in a fresh process: nothing chained or featurised before it
        monkeypatch.setattr(starts_module, "_CHAINED", {})
        monkeypatch.setattr(starts_module, "_CONTEXTS", {})
        fits.append(fit_imitation(StepScorer("full", **SSVM), contexts, list(scenarios.values()), rounds=1,
                                  chained=True))
    a, b = fits
    assert a.w_.tobytes() == b.w_.tobytes()
    assert a.n_steps_ > len(contexts)


def test_the_expert_never_sees_a_test_scenario(small, monkeypatch):
    """DAgger's rollouts and chained starts consult the demonstrator on training scenarios only."""
    contexts, meta, scenarios = small
    asked: list[str] = []
    real_expert, real_chain = dagger_module.next_actions, starts_module._chain

    def spy_expert(scenario, history, state):
        asked.append(scenario.id)
        return real_expert(scenario, history, state)

    def spy_chain(env_id, state, task):
        asked.append(f"{env_id}/{task}")
        return real_chain(env_id, state, task)

    monkeypatch.setattr(dagger_module, "next_actions", spy_expert)
    monkeypatch.setattr(starts_module, "_chain", spy_chain)
    monkeypatch.setattr(starts_module, "_CHAINED", {})  # nothing chained by an earlier test
    test = scenario_folds(scenarios, 3, 0, "scenario")[0]
    make = partial(ScorerMethod, "full", **SSVM, chained_starts=True, dagger_rounds=1, name="all")
    result = run_fold(make, 0, contexts, meta, scenarios, test, max_steps=20)
    assert result.sequences is not None and asked
    assert not set(asked) & test
    assert set(asked) <= set(scenarios) - test


def test_augmented_methods_need_the_scenarios(small):
    contexts, meta, _ = small
    with pytest.raises(ValueError, match="training scenarios"):
        ScorerMethod("full", **SSVM, dagger_rounds=1).fit(contexts, meta)


def test_dagger_from_a_given_base_equals_dagger_from_scratch(small):
    contexts, _, scenarios = small
    base = StepScorer("full", **SSVM).fit(contexts)
    given = fit_imitation(StepScorer("full", **SSVM), contexts, list(scenarios.values()), rounds=1, chained=False,
                          base=base)
    scratch = fit_imitation(StepScorer("full", **SSVM), contexts, list(scenarios.values()), rounds=1, chained=False)
    assert given.w_.tobytes() == scratch.w_.tobytes()


def test_each_dagger_refit_starts_where_the_fit_before_it_ended(small, monkeypatch):
    """Warm starts: the first fit (demonstrations and chained starts) from `warm`, a fit on the demonstrations
    alone; every round's refit from the fit before it, whose steps its own begin with."""
    contexts, _, scenarios = small
    warm = StepScorer("full", **SSVM).fit(contexts)
    fits: list[tuple[int, StepScorer | None]] = []
    real = StepScorer.fit

    def spy(self, X, y=None, progress=False, warm_start=None):
        fitted = real(self, X, y, progress, warm_start)
        fits.append((len(X), warm_start))
        return fitted

    monkeypatch.setattr(StepScorer, "fit", spy)
    last = fit_imitation(StepScorer("full", **SSVM), contexts, list(scenarios.values()), rounds=2, chained=True,
                         warm=warm)
    assert fits[0][1] is warm and fits[0][0] > len(contexts)  # chained starts added after the demonstrations
    assert len(fits) >= 2  # at least one round found states off the demonstrations
    for (n_before, _), (n, start) in zip(fits[:-1], fits[1:], strict=True):
        assert start is not None and start.n_steps_ == n_before < n
    assert last.n_steps_ == fits[-1][0]


# --- the last round's rollouts kept in the cache ---------------------------------------------------------------------

@pytest.fixture
def steps_cache(tmp_path, monkeypatch):
    from taskseq.runtime import cache

    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path / "cache"))
    return tmp_path / "cache" / "steps"


def _dagger(contexts, scenarios, C=3.0, rounds=1, expert=None):
    return fit_imitation(StepScorer("full", **{**SSVM, "C": C}), contexts, list(scenarios.values()), rounds=rounds,
                         chained=False, expert=expert)


def test_with_the_cache_on_the_rollouts_are_kept_and_read_back_to_the_same_fit(small, steps_cache, monkeypatch):
    contexts, _, scenarios = small
    monkeypatch.delenv("TASKSEQ_CACHE")
    uncached = _dagger(contexts, scenarios)
    monkeypatch.setenv("TASKSEQ_CACHE", str(steps_cache.parent))
    first = _dagger(contexts, scenarios)
    (entry,) = steps_cache.glob("??/*.steps")
    monkeypatch.setattr(dagger_module, "rollout_contexts", lambda *a: pytest.fail("rolled out, not read back"))
    again = _dagger(contexts, scenarios)
    assert uncached.w_.tobytes() == first.w_.tobytes() == again.w_.tobytes()
    assert uncached.n_steps_ == first.n_steps_ == again.n_steps_ > len(contexts)


def test_another_policy_rolls_out_anew_and_only_the_last_round_is_kept(small, steps_cache):
    contexts, _, scenarios = small
    _dagger(contexts, scenarios)
    _dagger(contexts, scenarios, C=0.3)  # another policy: other rollouts
    assert len(list(steps_cache.glob("??/*.steps"))) == 2
    _dagger(contexts, scenarios, rounds=2)  # its first round rolls out (not the last), its second is kept
    assert len(list(steps_cache.glob("??/*.steps"))) == 3
    _dagger(contexts, scenarios, C=1.0, expert=next_actions)  # an expert given by the caller: nothing kept
    assert len(list(steps_cache.glob("??/*.steps"))) == 3


def test_an_unreadable_kept_rollout_is_rolled_out_again(small, steps_cache):
    contexts, _, scenarios = small
    first = _dagger(contexts, scenarios)
    (entry,) = steps_cache.glob("??/*.steps")
    (entry / "objects.npz").write_bytes(b"not an archive")
    with pytest.warns(UserWarning, match="rolled out again"):
        again = _dagger(contexts, scenarios)
    assert again.w_.tobytes() == first.w_.tobytes()


def test_a_rollouts_key_holds_the_policys_weights_beyond_its_settings_and_data(small):
    """Two fits of the same settings and steps can differ (a warm start ends elsewhere within the gap): the
    weights themselves are hashed."""
    import copy

    contexts, _, scenarios = small
    fitted, listed = StepScorer("full", **SSVM).fit(contexts), list(scenarios.values())
    other = copy.copy(fitted)
    other.w_ = fitted.w_.copy()
    other.w_[0] += 1e-9
    assert repr(other) == repr(fitted)
    none = [set() for _ in listed]
    assert dagger_module._key(other, listed, none, contexts) != dagger_module._key(fitted, listed, none, contexts)


def test_a_rollouts_key_holds_the_histories_earlier_rounds_labelled(small):
    contexts, _, scenarios = small
    fitted, listed = StepScorer("full", **SSVM).fit(contexts), list(scenarios.values())
    none = [set() for _ in listed]
    some = [{(Action("move_close", ("obj01",)),)}] + none[1:]
    assert dagger_module._key(fitted, listed, none, contexts) == dagger_module._key(fitted, listed, none, contexts)
    assert dagger_module._key(fitted, listed, some, contexts) != dagger_module._key(fitted, listed, none, contexts)
