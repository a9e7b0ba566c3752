from taskseq.sim.primitives import Action, execute
from taskseq.sim.safety import RULES, violations
from tests.conftest import world


def run(state, *actions):
    for text in actions:
        state = execute(state, Action.parse(text))
    return state


def test_every_rule_is_documented():
    assert set(RULES) == {"liquid_grasped", "over_shelf", "grasp_with_load"}


def test_grasping_a_liquid_is_unsafe():
    s = world({2: 0.0}, [(20, 2, 0, 0.0), (27, 20)])
    s = run(s, "move_close(obj20)")
    assert violations(s, Action.parse("grasp(obj27)")) == ["liquid_grasped"]
    assert violations(s, Action.parse("grasp(obj20)")) == []


def test_grasping_under_a_load_is_unsafe():
    s = world({2: 0.0}, [(40, 2, 0, 0.0), (43, 40)])
    s = run(s, "move_close(obj40)")
    assert violations(s, Action.parse("grasp(obj40)")) == ["grasp_with_load"]
    assert violations(s, Action.parse("grasp(obj43)")) == []


def test_pouring_and_stirring_over_a_shelf_are_unsafe():
    # a cup on the shelf, a bottle of water and a spoon on the table beside it
    s = world({8: 0.0, 2: 1.5}, [(14, 8, 1, 0.5), (20, 2, 0, -0.6), (27, 20), (34, 2, 0, -0.4)])
    s = run(s, "move_close(obj20)", "grasp(obj20)", "hold_above(obj20,obj14)")
    assert violations(s, Action.parse("follow_traj_pour(obj20,obj14)")) == ["over_shelf"]
    s = run(s, "follow_traj_pour(obj20,obj14)", "place_above(obj20,obj02)", "release(obj20)")
    s = run(s, "grasp(obj34)", "hold_above(obj34,obj14)")
    assert violations(s, Action.parse("follow_traj_circle(obj34)")) == ["over_shelf"]


def test_pouring_over_a_table_is_safe():
    s = world({2: 0.0}, [(14, 2, 0, 0.3), (20, 2, 0, -0.3), (27, 20)])
    s = run(s, "move_close(obj20)", "grasp(obj20)", "hold_above(obj20,obj14)")
    assert violations(s, Action.parse("follow_traj_pour(obj20,obj14)")) == []
