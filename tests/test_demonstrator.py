"""Each rule of the demonstrator, on small hand-built environments."""

import pytest

from taskseq.sim.demonstrator import NoDemonstration, demonstrate
from taskseq.sim.primitives import execute
from taskseq.sim.safety import violations
from taskseq.sim.tasks import Task, goal_reached
from tests.conftest import world


def play(state, actions):
    """Execute a sequence, asserting it is safe; return the final state."""
    for action in actions:
        assert violations(state, action) == [], action
        state = execute(state, action)
    return state


def only(state, task):
    seqs = demonstrate(state, task)
    assert len(seqs) == 1
    final = play(state, seqs[0])
    assert goal_reached(task, state, final)
    return [str(a) for a in seqs[0]], final


def test_liquid_is_poured_through_its_container_into_the_smallest_empty_vessel_that_holds_it():
    # bottle of water; a cup already holding soda; an empty teacup and bowl
    s = world({2: 0.0}, [(20, 2, 0, -0.3), (27, 20), (14, 2, 0, 0.0), (30, 14), (17, 2, 0, 0.2), (16, 2, 0, 0.45)])
    seq, final = only(s, Task("pour", ("obj27",)))
    assert "grasp(obj27)" not in seq and "grasp(obj20)" in seq
    assert seq[-1] == "follow_traj_pour(obj20,obj17)"  # the teacup: the cup is full, the bowl is bigger
    assert final.container_of("obj27") == "obj17"


def test_vessel_on_a_shelf_goes_to_the_table_before_pouring():
    s = world({8: 0.0, 2: 2.0}, [(14, 8, 1, 0.4), (20, 2, 0, -0.6), (27, 20)])
    seq, final = only(s, Task("pour_to", ("obj27", "obj14")))
    assert seq.index("place_above(obj14,obj02)") < seq.index("follow_traj_pour(obj20,obj14)")
    assert not final.over_shelf("obj14")
    assert seq == [
        "move_close(obj14)", "grasp(obj14)", "move_close(obj20)", "place_above(obj14,obj02)", "release(obj14)",
        "grasp(obj20)", "hold_above(obj20,obj14)", "follow_traj_pour(obj20,obj14)",
    ]


def test_stirring_happens_on_a_table_with_the_shortest_stirrer_that_reaches():
    # tea in a glass (0.14 m deep) on a shelf; teaspoon 0.14 m, tablespoon 0.19 m, long spoon 0.28 m
    s = world({8: 0.0, 2: 1.5}, [(15, 8, 1, 0.4), (27, 15), (34, 2, 0, -0.6), (35, 2, 0, -0.4), (36, 2, 0, -0.2)])
    seq, final = only(s, Task("stir", ("obj27",)))
    assert seq[-1] == "follow_traj_circle(obj35)"
    assert seq.index("place_above(obj15,obj02)") < seq.index("hold_above(obj35,obj15)")
    assert "obj27" in final.stirred and not final.over_shelf("obj15")


def test_a_shallow_vessel_takes_the_teaspoon():
    s = world({2: 0.0}, [(13, 2, 0, 0.3), (31, 13), (34, 2, 0, -0.2), (35, 2, 0, 0.0)])
    seq, _ = only(s, Task("stir", ("obj31",)))
    assert seq[-1] == "follow_traj_circle(obj34)"


def test_what_rests_on_an_object_is_cleared_before_it_is_grasped():
    s = world({2: 0.0, 4: 2.0}, [(40, 2, 0, 0.0), (43, 40)])
    seq, final = only(s, Task("pick_and_place", ("obj40", "obj04")))
    assert seq[:5] == [
        "move_close(obj40)", "grasp(obj43)", "place_above(obj43,obj02)", "release(obj43)", "grasp(obj40)",
    ]
    assert final.support["obj40"][0] == "obj04"


def test_two_loads_give_two_sequences_that_differ_only_in_order():
    s = world({2: 0.0}, [(40, 2, 0, 0.0), (43, 40, 0, -0.05), (37, 40, 0, 0.06)])
    task = Task("pick_and_place", ("obj40", "obj01"))
    first, second = demonstrate(s, task)
    assert first != second and sorted(map(str, first)) == sorted(map(str, second))
    for seq in (first, second):
        assert goal_reached(task, s, play(s, seq))


def test_things_go_to_the_nearest_bin():
    s = world({10: -1.5, 2: 0.0, 11: 1.5}, [(43, 2, 0, 0.6)])
    seq, final = only(s, Task("throw_away", ("obj43",)))
    assert seq[-2] == "hold_above(obj43,obj11)"
    assert final.support["obj43"] == ("obj11", "inside")


def test_a_low_bin_may_be_dropped_into_or_set_down_in():
    s = world({2: 0.0, 12: 1.2}, [(43, 2, 0, 0.6)])
    seqs = demonstrate(s, Task("throw_away", ("obj43",)))
    assert {str(q[-2]) for q in seqs} == {"hold_above(obj43,obj12)", "place_above(obj43,obj12)"}


def test_impossible_tasks_say_why():
    s = world({2: 0.0}, [(20, 2, 0, 0.0), (27, 20)])
    with pytest.raises(NoDemonstration, match="no empty vessel"):
        demonstrate(s, Task("pour", ("obj27",)))
    with pytest.raises(NoDemonstration, match="no bin"):
        demonstrate(s, Task("throw_away", ("obj20",)))
