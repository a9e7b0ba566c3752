"""The baselines of the people's-demonstrations evaluation (`taskseq.veil.baselines`) on the invented fixture."""

from __future__ import annotations

from itertools import islice
from pathlib import Path

import pytest

from taskseq.veil.baselines import Chance, MostFrequent, MulticlassSVM, NearestDemonstration, candidates
from taskseq.veil.features import DONE, SIGNATURES
from taskseq.veil.grounding import ActionIndex, Step
from taskseq.veil.methods import training_steps
from taskseq.veil.release import Environment, EnvObject, Point, RawAction, read_release
from taskseq.veil.replay import Replay, replay_point, replay_release
from taskseq.veil.state import State, apply, initial_state

RELEASE = Path(__file__).parent / "fixtures" / "veil" / "release"
KITCHEN1 = "kitchen_scenario_environment_number_1"
KITCHEN2 = "kitchen_scenario_environment_number_2"
LIVING = "living_room_scenario_environment_number9"
BASELINES = (lambda: Chance(seed=7), MostFrequent, NearestDemonstration, MulticlassSVM)


@pytest.fixture(scope="module")
def release():
    return read_release(RELEASE)


@pytest.fixture(scope="module")
def replays(release):
    return replay_release(release)


def demo(release, env: Environment | str, objective: str, lines: list[str], seq_id: str) -> Replay:
    """A person's sequence made up for a test, replayed; every line must be kept."""
    env = release.environments[env] if isinstance(env, str) else env
    point = Point(seq_id, "made up", env.env_id, objective,
                  tuple(RawAction(t, 0, i) for i, t in enumerate(lines)), 1, 0)
    r = replay_point(point, env, release.catalog, ActionIndex(release.domain))
    assert len(r.kept) == len(lines), r.records
    return r


def after(release, env: Environment | str, lines: list[str]) -> tuple[State, list[Step]]:
    """The state of `env` after `lines`, and their steps (the history)."""
    env = release.environments[env] if isinstance(env, str) else env
    index = ActionIndex(release.domain)
    state, history = initial_state(env, release.catalog), []
    for line in lines:
        g = index.ground(line, env.names)
        state = apply(state, g.action, g.args)
        history.append(g.step)
    return state, history


def other_kitchen() -> Environment:
    """A kitchen of the fixture's categories under other names (no name of kitchen 1 but the tub's)."""
    names = ["Honey_4", "Teapot_7", "Beaker_5", "Tub", "Beaker_3"]
    objects = tuple(EnvObject(n, (float(i), 0.0, 0.0), (0.0, 0.0, 0.0), (), i) for i, n in enumerate(names))
    return Environment("kitchen_scenario_environment_number_5", "kitchen", 5, "(test)", objects)


def first(method, state: State, history: list[Step], objective: str, n: int = 1) -> list[Step]:
    return list(islice(method.ranked(state, history, objective), n))


def objects_of(step: Step) -> list[str]:
    return [a for a in (step.a1, step.a2) if a is not None]


# every baseline -------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("make", BASELINES)
def test_each_baseline_fits_and_ranks_only_existing_objects_without_repeats(make, release, replays):
    method = make().fit(replays)
    signatures = {(v, k) for v, k in SIGNATURES}
    n = 0
    for state, history, objective, _ in training_steps(replays):
        top = first(method, state, history, objective, 60)
        assert top, method.name
        assert len(set(top)) == len(top)
        for s in top:
            assert all(o in state.world.objects for o in objects_of(s)), (method.name, s)
            assert (s.verb, len(objects_of(s))) in signatures
            assert len(set(objects_of(s))) == len(objects_of(s))
        n += 1
    assert n == sum(len(r.kept) + 1 for r in replays if r.kept)
    # a state of an environment never trained on, with an objective never seen
    state, history = after(release, other_kitchen(), ["moveto Teapot_7"])
    top = first(method, state, history, "Unseen Objective", 20)
    assert top and all(o in state.world.objects for s in top for o in objects_of(s))


@pytest.mark.parametrize("make", BASELINES)
def test_each_baseline_is_deterministic_and_independent_of_the_calls_before(make, release, replays):
    a, b = make().fit(replays), make().fit(replays)
    steps = list(training_steps(replays))
    forward = [first(a, s, h, o, 30) for s, h, o, _ in steps]
    backward = [first(b, s, h, o, 30) for s, h, o, _ in reversed(steps)][::-1]
    assert forward == backward


def test_chance_ranks_every_candidate_once_in_an_order_the_seed_sets(release, replays):
    state, history = after(release, KITCHEN2, ["moveto Beaker_1"])
    ranked = list(Chance(seed=1).ranked(state, history, "Tidy Up"))
    everything = list(candidates(state))
    n = len(state.world.objects)
    assert len(everything) == sum(1 if k == 0 else n if k == 1 else n * (n - 1) for _, k in SIGNATURES)
    assert sorted(ranked, key=str) == sorted(everything, key=str) and len(set(ranked)) == len(ranked)
    assert ranked != everything  # shuffled
    assert ranked == list(Chance(seed=1).fit(replays).ranked(state, history, "Tidy Up"))
    assert ranked != list(Chance(seed=2).ranked(state, history, "Tidy Up"))
    assert ranked != list(Chance(seed=1).ranked(state, history, "Hot Tea"))
    assert ranked != list(Chance(seed=1).ranked(state, history + [Step("wait")], "Tidy Up"))


# MostFrequent ---------------------------------------------------------------------------------------------------
def test_most_frequent_learns_the_next_verb_and_the_argument_categories_of_an_objective(release):
    sweeten = ["moveto Honey_1", "grasp Honey_1", "release Honey_1"]
    fetch = ["moveto Beaker_2", "grasp Beaker_2", "moveto Tub", "wait", "keep Beaker_2 On Tub"]
    train = [demo(release, KITCHEN2, "Sweeten", sweeten, f"s{i}") for i in range(3)]
    train += [demo(release, KITCHEN2, "Fetch", fetch, f"f{i}") for i in range(2)]
    method = MostFrequent().fit(train)
    # kitchen 1 lists Beaker_1 before Beaker_2: a category maps to its first object in world order
    state, history = after(release, KITCHEN1, [])
    assert first(method, state, history, "Sweeten") == [Step("moveto", "Honey_1")]
    assert first(method, state, history, "Fetch") == [Step("moveto", "Beaker_1")]
    state, history = after(release, KITCHEN1, ["moveto Honey_1", "grasp Honey_1"])
    assert first(method, state, history, "Sweeten") == [Step("release", "Honey_1")]
    # after wait comes keep, of a beaker on a tub: the first beaker, whichever the robot holds
    state, history = after(release, KITCHEN1, ["moveto Beaker_2", "grasp Beaker_2", "moveto Tub", "wait"])
    assert first(method, state, history, "Fetch") == [Step("keep_on", "Beaker_1", "Tub")]
    state, history = after(release, KITCHEN1, sweeten)
    assert first(method, state, history, "Sweeten") == [Step(DONE)]
    # an unseen objective falls back to the overall counts: moveto is the most frequent signature (7 of 24 steps),
    # honey its most frequent argument category over all objectives (3, beaker 2, tub 2)
    state, history = after(release, KITCHEN1, [])
    assert first(method, state, history, "Unseen") == [Step("moveto", "Honey_1")]


def test_most_frequent_is_a_whole_ranking_and_skips_categories_the_state_lacks(release):
    train = [demo(release, KITCHEN1, "Sweet", ["moveto Cocoa_1", "moveto Honey_1"], "c1")]
    method = MostFrequent().fit(train)
    state, history = after(release, KITCHEN2, [])  # kitchen 2 has honey but no cocoa
    ranked = list(method.ranked(state, history, "Sweet"))
    assert ranked[0] == Step("moveto", "Honey_1")
    assert sorted(ranked, key=str) == sorted(candidates(state), key=str) and len(set(ranked)) == len(ranked)
    assert ranked.index(Step("done")) < ranked.index(Step("grasp", "Honey_1"))  # seen signatures come first


# NearestDemonstration -------------------------------------------------------------------------------------------
def test_nearest_demonstration_maps_objects_by_name_else_by_category_into_another_environment(release, replays):
    method = NearestDemonstration().fit(replays)
    state, history = after(release, other_kitchen(), [])
    # Hot Tea has one demonstration (p001, kitchen 1): Teapot_1 -> Teapot_7 (the only teapot), Tub by name
    assert first(method, state, history, "Hot Tea", 4) == [Step("moveto", "Teapot_7"), Step("grasp", "Teapot_7"),
                                                            Step("moveto", "Tub"), Step("keep_on", "Teapot_7", "Tub")]
    # step index = len(history); steps whose objects have no match (the knob, the hot plate) are skipped
    state, history = after(release, other_kitchen(), ["moveto Teapot_7", "grasp Teapot_7", "moveto Tub",
                                                      "keep Teapot_7 On Tub"])
    assert first(method, state, history, "Hot Tea", 3) == [Step("moveto", "Teapot_7"), Step("grasp", "Teapot_7"),
                                                            Step("wait")]
    # Sweet Drink (p006): pour Beaker_2 Teapot_1 -> the first beaker, Beaker_5, and the teapot; two beakers of one
    # step go to two objects of the category
    state, history = after(release, other_kitchen(), [])
    ranked = list(method.ranked(state, history, "Sweet Drink"))
    assert ranked[0] == Step("moveto", "Honey_4")  # Dipper_1 and Sorbet_1 have no match: skipped
    assert Step("pour", "Beaker_5", "Teapot_7") in ranked and Step("moveto", "Beaker_5") in ranked
    assert all(o in state.world.objects for s in ranked for o in objects_of(s))
    # past its end, the demonstration says done
    state, history = after(release, KITCHEN1, [])
    assert first(method, state, history + [Step("wait")] * 30, "Hot Tea") == [Step(DONE)]


def test_nearest_demonstration_prefers_the_room_then_the_overlap_then_the_sequence_id(release):
    kitchen2 = demo(release, KITCHEN2, "Go", ["moveto Tub"], "b")
    kitchen1 = demo(release, KITCHEN1, "Go", ["moveto Teapot_1"], "c")
    kitchen1_again = demo(release, KITCHEN1, "Go", ["moveto Icebox"], "a")
    living = demo(release, LIVING, "Go", ["moveto bench_1"], "z")
    method = NearestDemonstration().fit([living, kitchen2, kitchen1])
    # kitchen 1 shares more categories with kitchen 1 than kitchen 2 does
    state, _ = after(release, KITCHEN1, [])
    assert first(method, state, [], "Go") == [Step("moveto", "Teapot_1")]
    # the other kitchen (honey, teapot, 2 beakers, tub) overlaps kitchen 1 in 5 categories and kitchen 2 in 5: a tie,
    # broken by the sequence id
    state, _ = after(release, other_kitchen(), [])
    assert first(method, state, [], "Go") == [Step("moveto", "Tub")]  # "b" < "c"
    method = NearestDemonstration().fit([living, kitchen2, kitchen1, kitchen1_again])
    state, _ = after(release, KITCHEN1, [])
    assert first(method, state, [], "Go") == [Step("moveto", "Icebox")]  # "a" < "c", the same environment
    # a living room holding kitchen things: the living room's sequence wins though it shares fewer categories
    names = ["Teapot_1", "Tub", "Beaker_1", "bench_1"]
    objects = tuple(EnvObject(n, (float(i), 0.0, 0.0), (0.0, 0.0, 0.0), (), i) for i, n in enumerate(names))
    odd = Environment("living_room_scenario_environment_number3", "livingRoom", 7, "(test)", objects)
    state, _ = after(release, odd, [])
    assert first(method, state, [], "Go") == [Step("moveto", "bench_1")]


# MulticlassSVM --------------------------------------------------------------------------------------------------
def test_the_svm_predicts_a_signature_from_what_the_robot_grasps(release):
    """After moveto and grasp, a person releases honey but takes the teapot to the tub: the previous signatures
    are the same, only the grasped (and near) category tells them apart, which MostFrequent cannot see."""
    honey = ["moveto Honey_1", "grasp Honey_1", "release Honey_1"]
    teapot = ["moveto Teapot_1", "grasp Teapot_1", "moveto Tub", "keep Teapot_1 On Tub"]
    train = [demo(release, KITCHEN2, "Tidy", honey, f"h{i}") for i in range(3)]
    train += [demo(release, KITCHEN2, "Tidy", teapot, f"t{i}") for i in range(3)]
    svm = MulticlassSVM(C=1.0).fit(train)
    baseline = MostFrequent().fit(train)
    predicted, frequent = {}, {}
    for name, lines in (("honey", honey[:2]), ("teapot", teapot[:2])):
        state, history = after(release, KITCHEN1, lines)
        predicted[name] = first(svm, state, history, "Tidy")[0]
        frequent[name] = first(baseline, state, history, "Tidy")[0].verb
    # moveto's argument is its most frequent category for the objective (honey, teapot and tub tie: honey first)
    assert predicted == {"honey": Step("release", "Honey_1"), "teapot": Step("moveto", "Honey_1")}
    assert frequent["honey"] == frequent["teapot"]
    # done is learned after the release and after the keep
    state, history = after(release, KITCHEN1, honey)
    assert first(svm, state, history, "Tidy") == [Step(DONE)]


def test_the_svm_ranks_every_signature_and_fits_with_two_classes_or_none(release):
    svm = MulticlassSVM().fit([demo(release, KITCHEN2, "Wait", ["wait", "wait"], "w")])  # two classes: wait, done
    state, history = after(release, KITCHEN1, [])
    ranked = list(svm.ranked(state, history, "Wait"))
    assert ranked[:2] == [Step("wait"), Step(DONE)]
    assert sorted(ranked, key=str) == sorted(candidates(state), key=str) and len(set(ranked)) == len(ranked)
    nothing = MulticlassSVM().fit([demo(release, KITCHEN2, "Wait", [], "n")])  # no kept step: no sample
    assert sorted(nothing.ranked(state, [], "Wait"), key=str) == sorted(candidates(state), key=str)
