"""The scene a person reads: what stands where, shelf levels, what the robot holds, every shape on the page."""

from __future__ import annotations

import numpy as np

from taskseq.serve.environments import world_environment
from taskseq.serve.scene import LABEL_GAP, LABEL_LIFT, support_tree, top_view
from taskseq.settings import Procedural
from taskseq.sim.catalog import build_environment
from taskseq.sim.primitives import Action, execute
from taskseq.sim.procedural import Redraw, draw_room


def nodes_by_id(nodes, out=None):
    out = {} if out is None else out
    for n in nodes:
        out[n.id] = n
        nodes_by_id(n.children, out)
    return out


def test_the_tree_nests_what_rests_on_and_in_what_with_shelf_levels():
    state = world_environment(0, "env01").state
    tree = support_tree(state)
    assert [n.name for n in tree] == ["trash_can", "kitchen_table", "kitchen_shelf"]  # left to right
    nodes = nodes_by_id(tree)
    assert [c.name for c in nodes["obj40"].children] == ["chopstick", "crumpled_paper"]  # on the magazine
    assert [(c.name, c.relation) for c in nodes["obj20"].children] == [("water", "inside")]
    assert nodes["obj17"].level == 3 and nodes["obj02"].level is None


def test_the_top_view_draws_every_object_once_and_what_the_robot_holds_beside_it():
    state = world_environment(0, "env01").state
    view = top_view(state)
    drawn = {s.id for s in view.shapes}
    liquids = {o for o in state.specs if state.specs[o].has("liquid")}
    assert drawn == set(state.specs) - liquids - {"obj01"}  # liquids show in their container's label
    assert next(s for s in view.shapes if s.id == "obj20").label == "water_bottle (water)"
    assert all(0 <= s.x <= view.width and 0 <= s.y <= view.height for s in view.shapes)
    held = execute(execute(state, Action("move_close", ("obj20",))), Action("grasp", ("obj20",)))
    view = top_view(held)
    assert "obj20" not in {s.id for s in view.shapes} and view.held == "water_bottle (water)"
    # above the teacup on the shelf, at the room's right end: the picture is wide enough for the whole label
    above = execute(execute(held, Action("move_close", ("obj17",))), Action("hold_above", ("obj20", "obj17")))
    view = top_view(above)
    assert view.robot_label == "robot, holding water_bottle (water), above teacup"
    assert view.width >= view.robot_label_x + 8 * len(view.robot_label)
    assert "obj20" not in nodes_by_id(support_tree(held))


def drawn_rooms(n: int, seed: int = 7):
    """`n` rooms as the procedural family draws them (a draw it refuses is drawn again)."""
    rng, rooms = np.random.default_rng(seed), []
    while len(rooms) < n:
        try:
            env, objects = draw_room(f"proc{len(rooms) + 1:03d}", Procedural(), rng)
        except Redraw:
            continue
        rooms.append(build_environment(env, objects=objects))
    return rooms


def test_no_two_slanted_labels_write_over_each_other_in_drawn_rooms():
    """An item's label rises at 45 degrees from its top edge, on the line x + y = anchor + top: labels of items at
    different depths of a deep shelf share a line unless the layout keeps the lines apart, not only the starts."""
    rooms = drawn_rooms(40) + [world_environment(0, f"env{i:02d}").state for i in range(1, 14)]
    crowded = 0
    for state in rooms:
        slanted = [s for s in top_view(state).shapes if s.kind in ("vessel", "item")]
        lines = np.sort([s.anchor + s.y for s in slanted])
        assert np.all(np.diff(lines) >= LABEL_GAP - 0.2)  # (anchors and rows are rounded to a tenth of a pixel)
        assert all(s.anchor >= s.x + s.w / 2 - 0.1 for s in slanted)  # from its centre, or right of it
        centres = np.sort([s.x + s.w / 2 + s.y for s in slanted])
        crowded += bool(np.any(np.diff(centres) < LABEL_GAP))
    assert crowded >= 10  # rooms where labels started at their centres would have met: the rule was needed


def test_a_name_moved_off_its_shapes_middle_is_led_back_to_its_own_shape():
    """A name pushed right can start over a neighbour (env01: the teacup's over the tablespoon) and read as that
    one's: every moved name has a line from where it starts to its own shape, and no other name has one."""
    rooms = drawn_rooms(40) + [world_environment(0, f"env{i:02d}").state for i in range(1, 14)]
    led = 0
    for state in rooms:
        shapes = top_view(state).shapes
        for s in shapes:
            moved = s.kind in ("vessel", "item") and s.anchor - (s.x + s.w / 2) > 0.1  # beyond rounding
            if not moved:
                assert s.leader is None, s
                continue
            x1, y1, x2, y2 = s.leader
            assert (x1, y1) == (s.anchor, round(s.y - LABEL_LIFT, 1))  # from where the name starts
            assert s.x <= x2 <= s.x + s.w and s.y <= y2 <= s.y + s.h  # to its own shape
            assert abs(x2 - (s.x + s.w / 2)) <= 0.1  # at its middle, where an unmoved name starts
            led += 1
    assert led >= 100  # (133 in these rooms)
    shapes = {s.name: s for s in top_view(world_environment(0, "env01").state).shapes}
    teacup, spoon = shapes["teacup"], shapes["tablespoon"]
    assert spoon.x <= teacup.anchor <= spoon.x + spoon.w  # the name starts over the tablespoon...
    assert teacup.x <= teacup.leader[2] <= teacup.x + teacup.w  # ...and its line leads to the teacup
