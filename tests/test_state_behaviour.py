"""sim/state.py on a hand-built world: a floor, a table with a cup of water and a spoon in the cup, a two-level shelf
with a book and a sheet of paper on the book, a lamp standing on nothing; every relation and every measure
against its value worked out by hand."""

from __future__ import annotations

import math

import pytest

from taskseq.sim import state as state_module
from taskseq.sim.objects import ObjectSpec
from taskseq.sim.state import EPS, INSIDE, ON, REACH, STANDOFF, WorldState, footprint_distance, within_reach


def spec(oid, category, size, *flags, levels=()):
    return ObjectSpec(oid, f"{oid}-name", category, size, frozenset(flags), levels)


SPECS = {s.id: s for s in [
    spec("floor", "floor", (10.0, 10.0, 0.01), "large_surface"),
    spec("table", "table", (1.0, 0.6, 0.8), "large_surface"),
    spec("cup", "cup", (0.1, 0.1, 0.12), "container", "movable", "cylinder"),
    spec("water", "liquid", (0.08, 0.08, 0.06), "liquid"),
    spec("spoon", "stirrer", (0.02, 0.15, 0.01), "movable"),
    spec("shelf", "shelf", (0.8, 0.4, 1.5), "multi_surface", levels=(0.5, 1.0)),
    spec("book", "item", (0.2, 0.3, 0.04), "movable", "box"),
    spec("paper", "item", (0.2, 0.3, 0.001), "movable"),
    spec("lamp", "item", (0.2, 0.2, 0.4), "movable"),
]}


def world() -> WorldState:
    return WorldState(
        specs=SPECS,
        poses={"floor": (0.0, 0.0, 0.0), "table": (0.0, 1.0, 0.01), "cup": (0.1, 1.0, 0.81),
               "water": (0.1, 1.0, 0.82), "spoon": (0.12, 1.0, 0.82), "shelf": (2.0, 1.0, 0.01),
               "book": (2.0, 1.0, 0.51), "paper": (2.0, 1.0, 0.55), "lamp": (-3.0, 4.0, 0.0)},
        support={"table": ("floor", ON), "cup": ("table", ON), "water": ("cup", INSIDE), "spoon": ("cup", INSIDE),
                 "shelf": ("floor", ON), "book": ("shelf", ON), "paper": ("book", ON)},
        robot=(0.0, 0.0),
    )


def test_the_constants_are_the_documented_ones():
    assert (ON, INSIDE, REACH, STANDOFF, EPS) == ("on", "inside", 0.8, 0.35, 1e-6)


# --- footprints and reach ------------------------------------------------------------------------------------------

BOX = (0.0, 0.0, 5.0, 1.0, 2.0, 9.0)  # x 0..1, y 0..2


@pytest.mark.parametrize("point, distance", [
    ((0.5, 1.0), 0.0), ((0.0, 0.0), 0.0), ((1.0, 2.0), 0.0),  # inside and on the corners
    ((-3.0, 1.0), 3.0), ((4.0, 1.0), 3.0), ((0.5, -2.0), 2.0), ((0.5, 6.0), 4.0),  # off one side each
    ((-3.0, -4.0), 5.0), ((4.0, 6.0), 5.0), ((2.0, 5.0), math.sqrt(10.0)),  # off a corner
])
def test_the_footprint_distance_is_to_the_nearest_point_of_the_footprint(point, distance):
    assert footprint_distance(BOX, point) == pytest.approx(distance, abs=1e-12)


def test_reach_is_the_footprint_distance_up_to_the_reach_and_its_tolerance():
    assert within_reach(BOX, (-0.8, 1.0)) and within_reach(BOX, (1.8, 1.0))
    assert within_reach(BOX, (0.5, -0.8 - 0.5e-6))  # within the tolerance
    assert not within_reach(BOX, (0.5, -0.8 - 2e-6)) and not within_reach(BOX, (-0.81, 1.0))
    assert not within_reach(BOX, (1.0 + 0.6, 2.0 + 0.6))  # 0.85 m off the corner, though 0.6 off in x and in y
    assert within_reach(BOX, (-(REACH + EPS), 1.0))  # exactly at the reach and its tolerance: within


# --- copies and keys -----------------------------------------------------------------------------------------------

def test_a_copy_shares_the_specs_and_nothing_it_changes():
    a = world()
    a.held, a.held_above, a.stirred = "spoon", "cup", {"water"}
    b = a.copy()
    assert b.specs is a.specs
    assert (b.poses, b.support, b.robot, b.held, b.held_above, b.stirred) == (
        a.poses, a.support, a.robot, "spoon", "cup", {"water"})
    assert b.poses is not a.poses and b.support is not a.support and b.stirred is not a.stirred
    b.poses["cup"] = (9.0, 9.0, 9.0)
    b.support.pop("cup")
    b.stirred.add("cup")
    assert a.poses["cup"] == (0.1, 1.0, 0.81) and a.support["cup"] == ("table", ON) and a.stirred == {"water"}


def test_the_key_tells_worlds_apart_by_everything_a_primitive_changes():
    a = world()
    assert a.key() == a.copy().key() and hash(a.key()) == hash(a.copy().key())
    assert a.key() == (tuple(a.poses.items()), tuple(a.support.items()), (0.0, 0.0), None, None, frozenset())
    changes = [lambda s: s.poses.update(cup=(0.2, 1.0, 0.81)), lambda s: s.support.update(cup=("floor", ON)),
               lambda s: setattr(s, "robot", (0.0, 0.1)), lambda s: setattr(s, "held", "cup"),
               lambda s: setattr(s, "held_above", "cup"), lambda s: s.stirred.add("water")]
    keys = {a.key()}
    for change in changes:
        b = a.copy()
        change(b)
        keys.add(b.key())
    assert len(keys) == len(changes) + 1
    reordered = a.copy()
    reordered.poses = dict(reversed(list(a.poses.items())))
    assert reordered.key() != a.key()  # dict order counts


# --- relations -----------------------------------------------------------------------------------------------------

def test_children_are_sorted_and_filtered_by_relation():
    s = world()
    assert s.children("cup") == ["spoon", "water"] and s.children("cup", INSIDE) == ["spoon", "water"]
    assert s.children("cup", ON) == []
    assert s.children("floor") == ["shelf", "table"] and s.children("floor", ON) == ["shelf", "table"]
    assert s.children("paper") == [] and s.children("lamp") == []
    s.support["lamp"] = ("cup", ON)
    assert s.children("cup") == ["lamp", "spoon", "water"] and s.children("cup", ON) == ["lamp"]
    assert s.loads("cup") == ["lamp"] and s.loads("table") == ["cup"] and s.loads("water") == []


def test_the_liquids_in_a_container_are_its_liquid_contents_only():
    s = world()
    assert s.liquids_in("cup") == ["water"]
    s.support["water"] = ("table", ON)
    assert s.liquids_in("cup") == [] and s.liquids_in("table") == []


def test_the_container_of_an_object_is_what_holds_it_inside():
    s = world()
    assert s.container_of("water") == "cup" and s.container_of("spoon") == "cup"
    assert s.container_of("cup") is None and s.container_of("lamp") is None and s.container_of("floor") is None


def test_ancestors_run_from_the_support_down_to_what_rests_on_nothing():
    s = world()
    assert s.ancestors("water") == ["cup", "table", "floor"]
    assert s.ancestors("paper") == ["book", "shelf", "floor"]
    assert s.ancestors("floor") == [] and s.ancestors("lamp") == []


def test_descendants_are_everything_resting_on_or_in_an_object_directly_or_through_others():
    s = world()
    below_floor = s.descendants("floor")
    assert sorted(below_floor) == ["book", "cup", "paper", "shelf", "spoon", "table", "water"]
    assert len(below_floor) == len(set(below_floor))
    assert sorted(s.descendants("table")) == ["cup", "spoon", "water"]
    assert sorted(s.descendants("cup")) == ["spoon", "water"]
    assert s.descendants("book") == ["paper"] and s.descendants("paper") == [] and s.descendants("lamp") == []


def test_the_furniture_under_an_object_is_the_first_table_shelf_or_floor_below_it():
    s = world()
    assert s.furniture_under("water") == "table" and s.furniture_under("cup") == "table"
    assert s.furniture_under("paper") == "shelf" and s.furniture_under("table") == "table"
    assert s.furniture_under("floor") == "floor" and s.furniture_under("lamp") is None
    s.support["lamp"] = ("floor", ON)
    assert s.furniture_under("lamp") == "floor"


def test_over_shelf_is_resting_directly_or_through_others_on_a_multi_surface_object():
    s = world()
    assert s.over_shelf("book") and s.over_shelf("paper")
    assert not s.over_shelf("shelf") and not s.over_shelf("cup") and not s.over_shelf("water")
    assert not s.over_shelf("lamp")


def test_shelved_is_every_object_over_a_shelf_in_one_walk():
    s = world()
    assert s.shelved() == {"book", "paper"}
    assert s.shelved() == {o for o in s.specs if s.over_shelf(o)}
    s.support["cup"] = ("paper", ON)  # the cup with its water and spoon, moved onto the paper
    assert s.shelved() == {"book", "paper", "cup", "water", "spoon"}
    assert s.shelved() == {o for o in s.specs if s.over_shelf(o)}
    empty = world()
    del empty.support["book"], empty.support["paper"]
    assert empty.shelved() == set()


def test_shelved_follows_every_shelf_and_every_branch():
    s = world()
    specs = dict(SPECS, shelf2=spec("shelf2", "shelf", (0.5, 0.3, 1.0), "multi_surface", levels=(0.4,)),
                 box2=spec("box2", "item", (0.1, 0.1, 0.1), "movable"))
    s.specs = specs
    s.poses.update(shelf2=(4.0, 1.0, 0.01), box2=(4.0, 1.0, 0.41))
    s.support.update(shelf2=("floor", ON), box2=("shelf2", ON), lamp=("book", ON))
    assert s.shelved() == {"book", "paper", "lamp", "box2"}
    assert s.shelved() == {o for o in s.specs if s.over_shelf(o)}


def test_a_support_loop_through_a_shelf_is_walked_once():
    """The shelf resting on the paper that rests on the book on the shelf (a broken file's world): the walk
    visits each object once and ends."""
    s = world()
    s.support["shelf"] = ("paper", ON)
    s.support["lamp"] = ("paper", ON)
    assert s.shelved() == {"book", "paper", "shelf", "lamp"}


# --- geometry ------------------------------------------------------------------------------------------------------

def test_a_box_is_centred_on_its_pose_in_x_and_y_and_rises_from_it():
    s = world()
    assert s.box("table") == pytest.approx((-0.5, 0.7, 0.01, 0.5, 1.3, 0.81))
    assert s.box("spoon") == pytest.approx((0.11, 0.925, 0.82, 0.13, 1.075, 0.83))


@pytest.mark.parametrize("pose, overlap", [
    ((2.0, 1.0, 0.0), True),  # the same footprint
    ((2.15, 1.2, 0.0), True),  # overlapping in x and y
    ((2.2, 1.0, 0.0), False), ((1.8, 1.0, 0.0), False),  # touching edge to edge in x, either side
    ((2.0, 1.3, 0.0), False), ((2.0, 0.7, 0.0), False),  # touching in y
    ((2.2 - 2e-6, 1.0, 0.0), True), ((2.2 - 0.5e-6, 1.0, 0.0), False),  # sharing more / less than EPS
    ((2.0, 1.3 - 2e-6, 0.0), True), ((2.0, 1.3 - 0.5e-6, 0.0), False),
    ((2.1, 2.0, 0.0), False), ((3.0, 1.1, 0.0), False),  # overlapping in x only, in y only
    # sharing exactly EPS, to the last bit (2.199999 - 0.1 == 2.1 - 1e-6 in floating point): no overlap
    ((2.199999, 1.0, 0.0), False), ((2.0, 1.299999, 0.0), False),
])
def test_footprints_overlap_only_when_they_share_area_seen_from_above(pose, overlap):
    s = world()
    s.poses["paper"] = pose  # 0.2 x 0.3, like the book at (2.0, 1.0)
    assert s.overlap_top("book", "paper") is overlap and s.overlap_top("paper", "book") is overlap


def test_distances_from_the_robot_to_the_centre_and_to_the_footprint():
    s = world()
    s.robot = (3.0, 5.0)
    assert s.distance("lamp") == pytest.approx(math.hypot(6.0, 1.0))
    assert s.distance("table") == pytest.approx(5.0)  # (0, 1) from (3, 5)
    assert s.reach_distance("table") == pytest.approx(math.hypot(2.5, 3.7))
    s.robot = (0.0, 0.0)
    assert s.reach_distance("table") == pytest.approx(0.7) and s.reachable("table")
    s.robot = (0.0, -0.1 + 1e-3)
    assert s.reach_distance("table") == pytest.approx(0.799) and s.reachable("table")
    s.robot = (0.0, -0.1 - 1e-3)
    assert not s.reachable("table")


def test_the_reach_threshold_is_the_modules_one(monkeypatch):
    s = world()
    s.robot = (0.0, -0.2)  # 0.9 m from the table's footprint
    assert not s.reachable("table")
    monkeypatch.setattr(state_module, "REACH", 1.0)
    assert s.reachable("table") and within_reach(s.box("table"), s.robot)


def test_the_robot_parks_in_front_of_the_furniture_level_with_the_object():
    s = world()
    assert s.approach_point("cup") == (0.1, round(0.7 - STANDOFF, 6))  # the table's front edge, less the standoff
    assert s.approach_point("water") == (0.1, round(0.7 - STANDOFF, 6))
    assert s.approach_point("paper") == (2.0, round(0.8 - STANDOFF, 6))  # the shelf's
    assert s.approach_point("table") == (0.0, round(0.7 - STANDOFF, 6))
    assert s.approach_point("lamp") == (-3.0, round(3.9 - STANDOFF, 6))  # on nothing: in front of itself
    s.support["lamp"] = ("floor", ON)
    assert s.approach_point("lamp") == (-3.0, round(3.9 - STANDOFF, 6))  # on the floor: in front of itself too
    s.poses["cup"] = (0.123456789, 1.0, 0.81)
    assert s.approach_point("cup") == (0.123457, 0.35)
    s.poses["table"] = (0.0, 1.0000004, 0.01)  # its front edge 0.3500004 m in front of the robot's line
    assert s.approach_point("cup") == (0.123457, 0.35)  # rounded to the micrometre
