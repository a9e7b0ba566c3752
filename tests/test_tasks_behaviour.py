"""The goal test of every task, reached and not reached, on states the primitives produce."""

from __future__ import annotations

import pytest

from taskseq.sim.primitives import Action, execute
from taskseq.sim.tasks import TASKS, Task, goal_reached
from tests.conftest import world

TABLE, SHELF, TRASH = "obj02", "obj08", "obj10"
CUP, BOTTLE, WATER, SPOON = "obj14", "obj20", "obj27", "obj34"


@pytest.fixture
def kitchen():
    return world({2: 0.0, 8: 2.2, 10: -1.2}, [(20, 2, 0, -0.3), (27, 20), (14, 2, 0, 0.4), (34, 2, 0, 0.0)])


def run(state, *actions):
    for text in actions:
        state = execute(state, Action.parse(text))
    return state


POUR = (f"move_close({BOTTLE})", f"grasp({BOTTLE})", f"hold_above({BOTTLE},{CUP})", f"follow_traj_pour({BOTTLE},{CUP})")


def test_pour_is_reached_when_the_liquid_left_its_container_for_a_vessel(kitchen):
    task = Task("pour", (WATER,))
    assert not goal_reached(task, kitchen, kitchen)
    assert not goal_reached(task, kitchen, run(kitchen, *POUR[:3]))  # above the cup, not yet poured
    assert goal_reached(task, kitchen, run(kitchen, *POUR))
    into_bin = run(kitchen, *POUR[:2], f"move_close({TRASH})", f"hold_above({BOTTLE},{TRASH})",
                   f"follow_traj_pour({BOTTLE},{TRASH})")
    assert into_bin.container_of(WATER) == TRASH and not goal_reached(task, kitchen, into_bin)


def test_pour_to_needs_that_very_vessel(kitchen):
    poured = run(kitchen, *POUR)
    assert goal_reached(Task("pour_to", (WATER, CUP)), kitchen, poured)
    assert not goal_reached(Task("pour_to", (WATER, BOTTLE)), kitchen, poured)
    assert not goal_reached(Task("pour_to", (WATER, CUP)), kitchen, kitchen)


def test_stir_is_reached_once_the_liquid_was_stirred(kitchen):
    poured = run(kitchen, *POUR, f"place_above({BOTTLE},{TABLE})", f"release({BOTTLE})", f"grasp({SPOON})",
                 f"hold_above({SPOON},{CUP})")
    task = Task("stir", (WATER,))
    assert not goal_reached(task, kitchen, poured)
    assert goal_reached(task, kitchen, run(poured, f"follow_traj_circle({SPOON})"))


def test_pick_and_place_needs_the_object_released_on_the_target(kitchen):
    task = Task("pick_and_place", (CUP, TRASH))
    held = run(kitchen, f"move_close({CUP})", f"grasp({CUP})", f"move_close({TRASH})", f"hold_above({CUP},{TRASH})")
    assert not goal_reached(task, kitchen, held)
    assert goal_reached(task, kitchen, run(held, f"release({CUP})"))
    placed = run(kitchen, f"move_close({CUP})", f"grasp({CUP})", f"place_above({CUP},{TABLE})")
    assert not goal_reached(Task("pick_and_place", (CUP, TABLE)), kitchen, placed)  # still gripped
    assert goal_reached(Task("pick_and_place", (CUP, TABLE)), kitchen, run(placed, f"release({CUP})"))
    assert goal_reached(Task("pick_and_place", (CUP, TABLE)), kitchen, kitchen)  # where it already is


def test_throw_away_needs_a_bin(kitchen):
    task = Task("throw_away", (CUP,))
    assert not goal_reached(task, kitchen, kitchen)  # on the table
    held = run(kitchen, f"move_close({CUP})", f"grasp({CUP})", f"move_close({TRASH})", f"hold_above({CUP},{TRASH})")
    assert not goal_reached(task, kitchen, held)
    assert goal_reached(task, kitchen, run(held, f"release({CUP})"))
    assert not goal_reached(task, kitchen, run(kitchen, f"move_close({CUP})", f"grasp({CUP})"))  # held, no parent


def test_tasks_parse_and_refuse_what_they_cannot_be():
    assert Task.parse(" pour_to( obj30 , obj15 ) ") == Task("pour_to", ("obj30", "obj15"))
    assert str(Task("pour", ("obj27",))) == "pour(obj27)" and set(TASKS) == {
        "stir", "pick_and_place", "pour", "pour_to", "throw_away"}
    with pytest.raises(ValueError, match="unknown task 'fly'; known: stir, pick_and_place"):
        Task("fly", ("a",))
    with pytest.raises(ValueError, match="task pour takes one argument"):
        Task("pour", ("a", "b"))
    with pytest.raises(ValueError, match="cannot parse task 'pour'"):
        Task.parse("pour")


def test_a_task_names_an_object_missing_from_the_world(kitchen):
    Task("pour", (WATER,)).check_objects(kitchen)
    with pytest.raises(ValueError, match="task pour_to\\(obj27,obj99\\): object obj99 is not in this environment"):
        Task("pour_to", (WATER, "obj99")).check_objects(kitchen)
