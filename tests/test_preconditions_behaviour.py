"""Every precondition of every primitive, refused and allowed: the same step from two states that differ only in
what the check looks at."""

from __future__ import annotations

import ast
import inspect

import pytest

from pipeline.sim import primitives
from pipeline.sim.primitives import Action, PreconditionError, execute
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
    assert set(CASES) == _checks_in_source()


@pytest.mark.parametrize("case", list(CASES), ids=lambda c: f"{c[0]}-{c[1]}")
def test_a_precondition_refuses_and_allows(kitchen, case):
    refused_history, allowed_history, step, args = CASES[case]
    refused, allowed = _steps(step, args)
    primitive, check = case
    with pytest.raises(PreconditionError) as err:
        run(kitchen, (*refused_history, refused))
    assert err.value.check == check
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
