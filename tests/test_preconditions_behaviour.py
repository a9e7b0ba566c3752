"""Every precondition of every primitive, refused and allowed: the same step from two states that differ only in
what the check looks at."""

from __future__ import annotations

import ast
import inspect

import pytest

from taskseq.sim import primitives
from taskseq.sim.primitives import Action, PreconditionError, execute
from tests.conftest import world

TABLE, TRASH = "obj02", "obj10"
CUP, BOTTLE, WATER, SPOON = "obj14", "obj20", "obj27", "obj34"

HOLD_CUP = (f"move_close({CUP})", f"grasp({CUP})")
HOLD_SPOON = (f"move_close({SPOON})", f"grasp({SPOON})")
HOLD_BOTTLE = (f"move_close({BOTTLE})", f"grasp({BOTTLE})")
POURED = (*HOLD_BOTTLE, f"hold_above({BOTTLE},{CUP})", f"follow_traj_pour({BOTTLE},{CUP})",
          f"place_above({BOTTLE},{TABLE})", f"release({BOTTLE})", f"grasp({SPOON})")

# (primitive, check): (history refused, history allowed, the step); `step` runs after each history
CASES = {
    ("any", "object exists"): ((), (), "move_close({})", ("obj99", CUP)),
    ("move_close", "not held"): (HOLD_CUP, (f"move_close({CUP})",), f"move_close({CUP})", None),
    ("move_close", "free to move"): ((*HOLD_CUP, f"place_above({CUP},{TABLE})"),
                                     (*HOLD_CUP, f"place_above({CUP},{TABLE})", f"release({CUP})"),
                                     f"move_close({TRASH})", None),
    ("grasp", "gripper empty"): (HOLD_CUP, (f"move_close({CUP})",), f"grasp({SPOON})", None),
    ("grasp", "movable"): ((f"move_close({CUP})",), (f"move_close({CUP})",), "grasp({})", (TABLE, CUP)),
    ("grasp", "within reach"): ((), (f"move_close({CUP})",), f"grasp({CUP})", None),
    ("release", "held"): ((), (*HOLD_CUP, f"place_above({CUP},{TABLE})"), f"release({CUP})", None),
    ("release", "placed or held above"): (HOLD_CUP, (*HOLD_CUP, f"hold_above({CUP},{TABLE})"), f"release({CUP})",
                                          None),
    ("release", "room below"): ((*HOLD_CUP, f"hold_above({CUP},{SPOON})"),
                                (*HOLD_CUP, f"hold_above({CUP},{TABLE})"), f"release({CUP})", None),
    ("place_above", "held"): ((f"move_close({CUP})",), HOLD_CUP, f"place_above({CUP},{TABLE})", None),
    ("place_above", "separate objects"): (HOLD_BOTTLE, HOLD_BOTTLE, "place_above({},{})",
                                          ((BOTTLE, WATER), (BOTTLE, TABLE))),
    ("place_above", "within reach"): (HOLD_CUP, (*HOLD_CUP, f"move_close({TRASH})"), f"place_above({CUP},{TRASH})",
                                      None),
    ("place_above", "free space"): (HOLD_CUP, HOLD_CUP, "place_above({},{})", ((CUP, SPOON), (CUP, TABLE))),
    ("hold_above", "held"): ((f"move_close({CUP})",), HOLD_CUP, f"hold_above({CUP},{TABLE})", None),
    ("hold_above", "separate objects"): (HOLD_BOTTLE, HOLD_BOTTLE, "hold_above({},{})",
                                         ((BOTTLE, WATER), (BOTTLE, CUP))),
    ("hold_above", "within reach"): (HOLD_CUP, (*HOLD_CUP, f"move_close({TRASH})"), f"hold_above({CUP},{TRASH})",
                                     None),
    ("follow_traj_circle", "held"): (POURED[:-1], (*POURED, f"hold_above({SPOON},{CUP})"),
                                     f"follow_traj_circle({SPOON})", None),
    ("follow_traj_circle", "held above"): (POURED, (*POURED, f"hold_above({SPOON},{CUP})"),
                                           f"follow_traj_circle({SPOON})", None),
    ("follow_traj_circle", "liquid below"): ((*POURED, f"hold_above({SPOON},{TABLE})"),
                                             (*POURED, f"hold_above({SPOON},{CUP})"), f"follow_traj_circle({SPOON})",
                                             None),
    ("follow_traj_circle", "long enough"): ((*HOLD_SPOON, f"hold_above({SPOON},{BOTTLE})"),
                                            (*POURED, f"hold_above({SPOON},{CUP})"), f"follow_traj_circle({SPOON})",
                                            None),
    ("follow_traj_pour", "held"): ((f"move_close({BOTTLE})",), (*HOLD_BOTTLE, f"hold_above({BOTTLE},{CUP})"),
                                   f"follow_traj_pour({BOTTLE},{CUP})", None),
    ("follow_traj_pour", "held above"): (HOLD_BOTTLE, (*HOLD_BOTTLE, f"hold_above({BOTTLE},{CUP})"),
                                         f"follow_traj_pour({BOTTLE},{CUP})", None),
    ("follow_traj_pour", "liquid inside"): ((*HOLD_CUP, f"hold_above({CUP},{BOTTLE})"),
                                            (*HOLD_BOTTLE, f"hold_above({BOTTLE},{CUP})"), "follow_traj_pour({},{})",
                                            ((CUP, BOTTLE), (BOTTLE, CUP))),
    ("follow_traj_pour", "container"): ((*HOLD_BOTTLE, f"hold_above({BOTTLE},{SPOON})"),
                                        (*HOLD_BOTTLE, f"hold_above({BOTTLE},{CUP})"), "follow_traj_pour({},{})",
                                        ((BOTTLE, SPOON), (BOTTLE, CUP))),
}

# what the error says, naming the objects and the numbers that decided it
REASONS = {
    ("any", "object exists"): "obj99 is not in this environment",
    ("move_close", "not held"): "obj14 is in the gripper",
    ("move_close", "free to move"): "obj14 rests on obj02 and is still gripped; release it first",
    ("grasp", "gripper empty"): "the gripper holds obj14",
    ("grasp", "movable"): "obj02 (kitchen_table) cannot be moved",
    ("grasp", "within reach"): "obj14 is 1.62 m from the robot",
    ("release", "held"): "obj14 is not in the gripper (holding None)",
    ("release", "placed or held above"): "obj14 is neither placed on nor held above anything; it would fall",
    ("release", "room below"): "obj14 does not fit on or in obj34",
    ("place_above", "held"): "obj14 is not in the gripper (holding None)",
    ("place_above", "separate objects"): "obj27 rests on or in obj20",
    ("place_above", "within reach"): "obj10 is 1.44 m from the robot",
    ("place_above", "free space"): "no room for obj14 on or in obj34",
    ("hold_above", "held"): "obj14 is not in the gripper (holding None)",
    ("hold_above", "separate objects"): "obj27 rests on or in obj20",
    ("hold_above", "within reach"): "obj10 is 1.44 m from the robot",
    ("follow_traj_circle", "held"): "obj34 is not in the gripper (holding None)",
    ("follow_traj_circle", "held above"): "obj34 is not held above anything",
    ("follow_traj_circle", "liquid below"): "obj02 holds no liquid to stir",
    ("follow_traj_circle", "long enough"): "obj34 (0.14 m) does not reach into obj20 (0.25 m deep)",
    ("follow_traj_pour", "held"): "obj20 is not in the gripper (holding None)",
    ("follow_traj_pour", "held above"): "obj20 is not held above obj14",
    ("follow_traj_pour", "liquid inside"): "obj14 holds no liquid to pour",
    ("follow_traj_pour", "container"): "obj34 (teaspoon) holds nothing",
}


@pytest.fixture
def kitchen():
    # table at x=0 with a bottle of water, a cup and a spoon; a shelf at x=2.2 and a trash can at x=-1.2
    return world({2: 0.0, 8: 2.2, 10: -1.2}, [(20, 2, 0, -0.3), (27, 20), (14, 2, 0, 0.4), (34, 2, 0, 0.0)])


def run(state, actions):
    for text in actions:
        state = execute(state, Action.parse(text))
    return state


def _steps(step: str, args) -> tuple[str, str]:
    """The refused and the allowed step: the same text, or a template filled with two argument sets."""
    if args is None:
        return step, step
    fill = [a if isinstance(a, tuple) else (a,) for a in args]
    return step.format(*fill[0]), step.format(*fill[1])


def _checks_in_source() -> set[tuple[str, str]]:
    """Every (primitive, check) `_require`d by the primitives' effects, read from the module's source."""
    tree = ast.parse(inspect.getsource(primitives))
    funcs = {f.name: f for f in tree.body if isinstance(f, ast.FunctionDef)}

    def checks(fn: ast.FunctionDef) -> set[str]:
        out = set()
        for node in ast.walk(fn):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
                if node.func.id in ("_require", "PreconditionError"):
                    out.add(node.args[2 if node.func.id == "_require" else 1].value)
                elif node.func.id in funcs and node.func.id != fn.name:
                    out |= checks(funcs[node.func.id])
        return out

    pairs = {(name, c) for name in primitives.ARITY for c in checks(funcs[f"_{name}"])}
    return pairs | {("any", c) for c in checks(funcs["execute"])}


def test_every_precondition_in_the_code_has_a_case():
    assert set(CASES) == set(REASONS) == _checks_in_source()


@pytest.mark.parametrize("case", list(CASES), ids=lambda c: f"{c[0]}-{c[1]}")
def test_a_precondition_refuses_and_allows(kitchen, case):
    refused_history, allowed_history, step, args = CASES[case]
    refused, allowed = _steps(step, args)
    primitive, check = case
    with pytest.raises(PreconditionError) as err:
        run(kitchen, (*refused_history, refused))
    assert err.value.check == check and err.value.reason == REASONS[case]
    assert str(err.value) == f"{refused}: precondition '{check}' failed: {REASONS[case]}"
    assert primitive in ("any", err.value.action.primitive)
    before = run(kitchen, allowed_history)
    after = execute(before, Action.parse(allowed))  # the step runs and changes the world, or the held object
    assert after is not before


def test_a_bottle_cannot_be_held_above_its_own_contents(kitchen):
    holding = run(kitchen, HOLD_BOTTLE)
    with pytest.raises(PreconditionError, match=f"{WATER} rests on or in {BOTTLE}"):
        execute(holding, Action.parse(f"hold_above({BOTTLE},{WATER})"))
    above = execute(holding, Action.parse(f"hold_above({BOTTLE},{CUP})"))
    assert above.held_above == CUP and above.support[WATER][0] == BOTTLE  # the water travels in the bottle


@pytest.fixture
def room():
    """An empty kitchen table (1.6 x 0.9 m, centre (0, 0.45), top 0.75) with a bowl at x = 0.4, a shelf with four
    levels (0.5, 0.8, 1.1, 1.4 m) at x = 2.2, a trash can at x = -1.2; a cup and a wastebasket on the table."""
    return world({2: 0.0, 8: 2.2, 10: -1.2}, [(16, 2, 0, 0.4), (14, 2, 0, -0.5), (12, 2, 0, -0.2)])


@pytest.mark.parametrize("robot, spot", [
    ((0.12, -0.35), (0.1, 0.05)),  # the lattice point nearest the robot, in the front row (y = 0.45 - 8 * 0.05)
    ((0.93, -0.35), (0.75, 0.05)),  # beyond the table: the last of 15 columns of 0.05 m from the centre
    ((-0.93, 1.5), (-0.75, 0.85)),  # behind the table: the back row
    ((0.4, -0.35), (0.25, 0.05)),  # the bowl blocks 0.30 to 0.50; 0.25 and 0.55 are as near: lattice order
])
def test_a_cup_goes_to_the_free_spot_nearest_the_robot(room, robot, spot):
    from taskseq.sim.primitives import free_spot
    from taskseq.sim.state import ON

    room.robot = robot
    assert free_spot(room, CUP, TABLE) == ((*spot, 0.75), ON)


@pytest.mark.xfail(strict=True, reason="free_spot floors 0.35 // 0.05 to 6.0; counting the flush spot would move the "
                   "large mug of env03 on the counter (1.15 m of play, 23 steps) and so change the paper rooms' logs")
def test_an_object_that_spans_a_whole_number_of_grid_steps_can_stand_flush_with_the_edge():
    """(1.0 - 0.3) / 2 = 0.35 m of play is 7 steps of 0.05 m, though 0.35 // 0.05 is 6.0 in floating point.

    A known deviation kept for the paper rooms' bytes (docs/world.md, the primitives): strict, so a fix shows here.
    """
    from taskseq.sim.primitives import free_spot
    from taskseq.sim.state import ON

    room = world({4: 0.0}, [(12, 4, 0, -0.3)], robot_x=3.0)  # a wastebasket on the coffee table; the robot far right
    assert free_spot(room, "obj12", "obj04") == ((0.35, 0.15, 0.45), ON)  # the wastebasket flush with the right edge


def test_a_shelf_takes_an_object_on_the_lowest_level_it_fits_under(room):
    from taskseq.sim.primitives import free_spot
    from taskseq.sim.state import ON

    assert free_spot(room, CUP, "obj08") == ((1.65, 0.05, 0.5), ON)  # 9 cm cup: the lowest level
    # the 35 cm wastebasket fits under no level but the top one (0.3 m between levels, 2 cm to spare)
    assert free_spot(room, "obj12", "obj08") == ((1.8, 0.15, 1.4), ON)


def test_a_container_takes_what_fits_inside_at_its_centre(room):
    from taskseq.sim.primitives import free_spot
    from taskseq.sim.state import INSIDE

    assert free_spot(room, CUP, TRASH) == ((-1.2, 0.2, 0.005), INSIDE)
    assert free_spot(room, CUP, "obj16") == ((0.4, 0.16, 0.755), INSIDE)  # a cup into the bowl
    assert free_spot(room, "obj12", CUP) is None  # a wastebasket into a cup
    assert free_spot(room, "obj16", CUP) is None  # nor a bowl


def test_carried_and_contained_objects_move_with_what_holds_them(kitchen):
    held = run(kitchen, HOLD_CUP)
    held.robot = (held.robot[0], held.robot[1] - 0.45)  # the robot stands further back
    moved = execute(held, Action.parse(f"move_close({TRASH})"))
    offset = [a - b for a, b in zip(held.poses[CUP], (*held.robot, 0.0), strict=True)]
    assert [a - b for a, b in zip(moved.poses[CUP], (*moved.robot, 0.0), strict=True)] == pytest.approx(offset)
    bottle = run(kitchen, HOLD_BOTTLE)
    above = execute(bottle, Action.parse(f"hold_above({BOTTLE},{CUP})"))
    before = [w - b for w, b in zip(bottle.poses[WATER], bottle.poses[BOTTLE], strict=True)]
    assert [w - b for w, b in zip(above.poses[WATER], above.poses[BOTTLE], strict=True)] == pytest.approx(before)
    poured = execute(above, Action.parse(f"follow_traj_pour({BOTTLE},{CUP})"))
    assert poured.poses[WATER] == (poured.poses[CUP][0], poured.poses[CUP][1], round(poured.poses[CUP][2] + 0.005, 6))


def test_holding_above_lifts_a_placed_object_off_its_support(kitchen):
    placed = run(kitchen, (*HOLD_CUP, f"place_above({CUP},{TABLE})"))
    assert placed.support[CUP] == (TABLE, "on")
    lifted = run(placed, [f"hold_above({CUP},{BOTTLE})"])
    assert CUP not in lifted.support and lifted.held_above == BOTTLE
    replaced = run(lifted, [f"place_above({CUP},{TABLE})"])
    assert replaced.held_above is None
    with pytest.raises(PreconditionError, match="'held above' failed"):
        run(replaced, [f"follow_traj_circle({CUP})"])


def test_a_long_object_fits_a_container_only_if_both_sides_do():
    from taskseq.sim.primitives import free_spot

    state = world({2: 0.0}, [(13, 2, 0, 0.0), (38, 2, 0, 0.4), (15, 2, 0, -0.4), (27, 15)])
    assert free_spot(state, "obj38", "obj13") is None  # an 8 cm wide, 30 cm long spatula into a 8.5 x 12 cm mug


def test_a_spoon_exactly_as_long_as_the_glass_is_deep_stirs():
    state = world({2: 0.0}, [(15, 2, 0, 0.0), (27, 15), (34, 2, 0, 0.3)])  # teaspoon 0.14 m, glass 0.14 m deep
    s = run(state, ["move_close(obj34)", "grasp(obj34)", "hold_above(obj34,obj15)", "follow_traj_circle(obj34)"])
    assert WATER in s.stirred


def test_try_execute_gives_the_next_state_or_none(kitchen):
    from taskseq.sim.primitives import try_execute

    assert try_execute(kitchen, Action.parse(f"grasp({CUP})")) is None  # out of reach
    near = try_execute(kitchen, Action.parse(f"move_close({CUP})"))
    assert near.robot == (0.4, -0.35) and kitchen.robot == (0.0, -1.5)


def test_what_a_target_receives_inside_and_on_top(kitchen):
    from taskseq.sim.primitives import receives_inside

    assert receives_inside(kitchen, TRASH) and receives_inside(kitchen, CUP)
    assert not receives_inside(kitchen, TABLE) and not receives_inside(kitchen, SPOON)
    shelf = world({8: 0.0}, [])
    assert not receives_inside(shelf, "obj08")


def test_actions_print_and_refuse_as_documented():
    assert str(Action.parse("place_above(obj02, obj26)")) == "place_above(obj02,obj26)"
    with pytest.raises(ValueError, match=r"^unknown primitive 'fly'; known: move_close, grasp, release, "):
        Action("fly", ())
    with pytest.raises(ValueError, match=r"^cannot parse action 'grasp\(obj02'; expected e.g. grasp\(obj02\)$"):
        Action.parse("grasp(obj02")


def _resized(state, obj: str, **change):
    """The state with one object's spec changed (a hand-made object the catalog does not have)."""
    from dataclasses import replace

    state.specs = {**state.specs, obj: replace(state.specs[obj], **change)}
    return state


def test_an_object_fits_inside_up_to_the_containers_own_footprint(kitchen):
    from taskseq.sim.primitives import free_spot

    bin_w, bin_l, _ = kitchen.specs[TRASH].size
    exact = _resized(kitchen.copy(), CUP, size=(bin_w, bin_l, 0.09))
    assert free_spot(exact, CUP, TRASH) is not None  # as wide and as long as the bin: fits
    for size in ((bin_w + 1e-3, 0.05, 0.09), (0.05, bin_l + 1e-3, 0.09)):  # a millimetre too wide or too long
        assert free_spot(_resized(kitchen.copy(), CUP, size=size), CUP, TRASH) is None


def test_a_container_with_a_large_flat_top_takes_things_on_top(kitchen):
    from taskseq.sim.primitives import receives_inside

    flags = kitchen.specs[TRASH].flags | {"large_surface"}
    assert not receives_inside(_resized(kitchen.copy(), TRASH, flags=flags), TRASH)


def test_every_object_on_the_level_blocks_its_footprint(room):
    from taskseq.sim.primitives import free_spot

    # a second bowl at x = 0.15 also blocks 0.05 to 0.25 of the front row: the nearest free spot is 0.55
    two = world({2: 0.0, 8: 2.2, 10: -1.2}, [(16, 2, 0, 0.4), (18, 2, 0, -0.2), (14, 2, 0, -0.6)])
    two = _resized(two, "obj18", size=two.specs["obj16"].size)  # the pot, resized to a second bowl
    two.poses["obj18"] = (0.15, 0.16, 0.75)
    two.robot = (0.4, -0.35)
    assert free_spot(two, CUP, TABLE)[0] == (0.55, 0.05, 0.75)


@pytest.mark.parametrize("robot_x, spot_x", [(0.28, 0.3), (0.52, 0.5), (0.36, 0.3)])
def test_touching_an_object_is_not_overlapping_it(room, robot_x, spot_x):
    from taskseq.sim.primitives import free_spot

    # a 4 x 10 cm cup beside the 16 cm bowl at x = 0.4 (both reach into y 0.08 to 0.1): at 0.3 and 0.5 their
    # edges meet exactly, at 0.35 they overlap
    small = _resized(room, CUP, size=(0.04, 0.1, 0.09))
    small.robot = (robot_x, -0.35)
    assert free_spot(small, CUP, TABLE)[0] == (spot_x, 0.05, 0.75)


def test_objects_on_other_levels_do_not_block_a_shelf_level():
    from taskseq.sim.primitives import free_spot

    shelf = world({8: 2.2}, [(13, 8, 1, 0.0), (14, 8, 0, -0.4)])  # a mug on the second level, right above x = 2.2
    shelf.robot = (2.2, -0.35)
    assert free_spot(shelf, CUP, "obj08") == ((2.2, 0.05, 0.5), "on")


def test_an_object_as_large_as_the_surface_fits_at_its_centre_and_a_too_tall_one_goes_up(room):
    from taskseq.sim.primitives import free_spot

    table_w, table_l, _ = room.specs[TABLE].size
    board = _resized(room.copy(), CUP, size=(table_w, table_l, 0.02))
    board.poses["obj16"] = board.poses["obj12"] = (5.0, 5.0, 0.0)  # clear the table (off it, in the room)
    board.support = {k: v for k, v in board.support.items() if v[0] != TABLE or k == CUP}
    assert free_spot(board, CUP, TABLE) == ((0.0, 0.45, 0.75), "on")
    tall = _resized(room.copy(), CUP, size=(0.075, 0.075, 0.30))  # 30 cm: fits under no level (28 cm each)
    assert free_spot(tall, CUP, "obj08")[0][2] == 1.4  # but on the top one
