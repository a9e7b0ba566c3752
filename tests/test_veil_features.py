"""What the MRF sees of a VEIL state, how an objective's goal is derived, and how C is chosen."""

from __future__ import annotations

import pickle
from pathlib import Path
from types import SimpleNamespace

import pytest

from taskseq.veil import experiment
from taskseq.veil.evaluate import derive_goals
from taskseq.veil.features import PAIR_COLUMNS, ROBOT_COLUMNS, Vocabulary
from taskseq.veil.release import read_release
from taskseq.veil.replay import replay_release
from taskseq.veil.state import State

FIXTURE = Path(__file__).parent / "fixtures" / "veil" / "release"


@pytest.fixture(scope="module")
def release():
    rel = read_release(FIXTURE)
    return rel, replay_release(rel)


def test_an_objects_row_says_near_grasped_on_and_holds_and_never_its_name(release) -> None:
    rel, reps = release
    world = next(r for r in reps if r.kept).initial.world
    a, b = list(world.objects)[:2]
    state = State(world, frozenset({("Near", "Robot", a), ("Grasping", "Robot", b), ("On", a, b),
                                    ("state", a, "Tea")}))
    vocabulary = Vocabulary.of(rel.catalog, ["x"], categories=False)
    rows, pairs, pair_rows = vocabulary.rows(state)
    col = {c: i for i, c in enumerate(vocabulary.columns)}
    names = list(world.objects)
    assert rows[names.index(a), col["near"]] == 1 and rows[names.index(a), col["grasped"]] == 0
    assert rows[names.index(b), col["grasped"]] == 1 and rows[names.index(b), col["near"]] == 0
    assert rows[names.index(a), col["on_something"]] == 1 and rows[names.index(b), col["holds_on"]] == 1
    assert rows[names.index(a), col["state_Tea"]] == 1 and rows[names.index(b), col["state_Tea"]] == 0
    assert not any(c.startswith("is_") for c in vocabulary.columns)  # attributes only, as the paper's model
    at = {tuple(p): r for p, r in zip(pairs.tolist(), pair_rows, strict=True)}
    i, j = names.index(a), names.index(b)
    assert at[(i, j)][PAIR_COLUMNS.index("a1_on_a2")] == 1 and at[(j, i)][PAIR_COLUMNS.index("a2_on_a1")] == 1
    assert ROBOT_COLUMNS[:2] == ("near", "grasped")


def _replay(objective: str, initial: State, final: State):
    return SimpleNamespace(kept=("a step",), point=SimpleNamespace(objective=objective), initial=initial, final=final)


def test_a_fact_is_in_the_goal_when_at_least_half_of_the_objectives_sequences_make_it_true(release) -> None:
    world = next(r for r in release[1] if r.kept).initial.world
    a, b = list(world.objects)[:2]
    start, done = State(world, frozenset()), State(world, frozenset({("On", a, b)}))
    lifted = ("On", world.objects[a].category, world.objects[b].category)
    assert derive_goals([_replay("x", start, done), _replay("x", start, start)])["x"] == {lifted}  # one of two
    assert derive_goals([_replay("x", start, done)] + [_replay("x", start, start)] * 2)["x"] == frozenset()
    assert derive_goals([_replay("x", done, done)])["x"] == frozenset()  # true from the start: asked for nothing


def test_c_is_the_grid_value_with_the_best_inner_figure_ties_to_the_smallest(release, monkeypatch) -> None:
    rel, reps = release
    settings = experiment.Settings(folds=2, C_grid=(1.0, 10.0, 100.0))
    for figures, chosen in (({1.0: 0.2, 10.0: 0.5, 100.0: 0.4}, 10.0), ({1.0: 0.3, 10.0: 0.3, 100.0: 0.1}, 1.0)):
        monkeypatch.setattr(experiment, "both_accuracy", lambda method, test, f=figures: f[method.C])
        objectives = sorted({r.point.objective for r in reps})
        assert experiment.choose_C("mrf_attributes", rel, objectives, reps, settings) == chosen


def test_rows_of_one_world_share_its_fixed_part_and_never_a_states(release) -> None:
    """The affordance, category and same-category part is made once per world; what a state holds is its own:
    asked in turn, two states of one world, and two worlds, get the rows made afresh for each."""
    rel, reps = release
    worlds = list({r.initial.world.env_id: r.initial.world for r in reps if r.kept}.values())[:2]
    first = list(worlds[0].objects)[0]
    states = [State(worlds[0], frozenset({("Grasping", "Robot", first), ("state", first, "Tea")})),
              State(worlds[0], frozenset()), State(worlds[1], frozenset())]
    shared = Vocabulary.of(rel.catalog, ["x"], categories=True)
    for state in states + states[::-1]:
        fresh = Vocabulary.of(rel.catalog, ["x"], categories=True).rows(state)
        for kept, made in zip(shared.rows(state), fresh, strict=True):
            assert kept.shape == made.shape and (kept == made).all()
    grasped = shared.rows(states[0])[0][0, shared.columns.index("grasped")]
    assert (grasped, shared.rows(states[1])[0][0, shared.columns.index("grasped")]) == (1, 0)
    copy = pickle.loads(pickle.dumps(shared))  # the rows kept per world stay in their process
    assert copy == shared and copy._worlds == {} and (copy.rows(states[0])[0] == shared.rows(states[0])[0]).all()
