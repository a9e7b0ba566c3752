"""The choice cues on a hand-made kitchen whose answers are known, and the method that uses them."""

from __future__ import annotations

import numpy as np

from taskseq.features.context import RELATION_COLUMNS, step_context
from taskseq.features.cues import CUE_COLUMNS, CUE_VOLUME_RATIOS, choice_cues
from taskseq.methods import Lineup, method_labels, specs
from taskseq.selection import Selection
from taskseq.settings import Methods
from taskseq.sim.demonstrator import choose_stirrer, choose_vessel
from taskseq.sim.objects import ObjectSpec
from taskseq.sim.state import INSIDE, ON, WorldState
from taskseq.sim.tasks import Task

CUP = frozenset({"container", "cylinder", "movable"})
LIQUID = frozenset({"liquid", "cylinder", "movable"})


def kitchen() -> WorldState:
    """A table; a bottle with milk (0.05 x 0.05 x 0.1 m, 0.25 l of box); four cups, 1.2, 2.2 and 3.2 times the milk's
    volume and one of 1.6 times holding tea, 0.1 m deep; three stirrers 1, 5 and 12 cm longer than that depth, and a
    long box (a ruler). The robot stands 1 m in front of the table's middle."""
    objects = {  # id: (category, size, flags, x)
        "obj01": ("table", (2.0, 0.8, 0.75), frozenset({"large_surface", "box"}), 0.0),
        "obj02": ("bottle", (0.08, 0.08, 0.25), CUP, -0.8),
        "obj03": ("liquid", (0.05, 0.05, 0.1), LIQUID, -0.8),
        "obj04": ("cup", (0.05, 0.06, 0.1), CUP, -0.6),  # 1.2 times the milk
        "obj05": ("cup", (0.1, 0.055, 0.1), CUP, 0.4),  # 2.2 times
        "obj06": ("cup", (0.08, 0.1, 0.1), CUP, 0.2),  # 3.2 times, nearer the robot than the other cups
        "obj07": ("cup", (0.08, 0.05, 0.1), CUP, 0.6),  # 1.6 times, holding tea
        "obj08": ("liquid", (0.04, 0.04, 0.05), LIQUID, 0.6),
        "obj09": ("stirrer", (0.11, 0.01, 0.01), frozenset({"movable"}), -0.3),
        "obj10": ("stirrer", (0.01, 0.15, 0.01), frozenset({"movable"}), -0.2),
        "obj11": ("stirrer", (0.22, 0.01, 0.01), frozenset({"movable", "cylinder"}), -0.1),
        "obj12": ("item", (0.3, 0.03, 0.005), frozenset({"movable", "box"}), 0.8),
    }
    specs = {o: ObjectSpec(o, o, cat, size, flags) for o, (cat, size, flags, _) in objects.items()}
    poses = {o: (x, 0.0, 0.0 if o == "obj01" else 0.75) for o, (_, _, _, x) in objects.items()}
    support = {o: ("obj01", ON) for o in objects if o not in ("obj01", "obj03", "obj08")}
    support |= {"obj03": ("obj02", INSIDE), "obj08": ("obj07", INSIDE)}
    return WorldState(specs, poses, support, robot=(0.0, -1.0))


def cues_of(state: WorldState, task: str) -> dict[str, list[str]]:
    """Each cue column: the objects it marks."""
    ctx = step_context(state, Task.parse(task), [])
    cues = choice_cues(ctx.objects, ctx.relations)
    assert cues.shape == (ctx.n, len(CUE_COLUMNS)) and set(np.unique(cues)) <= {0.0, 1.0}
    return {c: [ctx.object_ids[i] for i in np.flatnonzero(cues[:, k])] for k, c in enumerate(CUE_COLUMNS)}


def test_the_smallest_empty_container_that_holds_enough_is_the_vessel_the_demonstrator_pours_into():
    state = kitchen()
    cues = cues_of(state, "pour(obj03)")
    # obj07 (1.6x) holds tea and the bottle holds the milk: neither counts; obj04 holds too little beyond 1.2x
    # (exactly 1.2x counts as at least 1.2x)
    ratios = ("1", "1.1", "1.2", "1.3", "1.4", "1.5", "1.6", "1.7", "1.8", "1.9", "2", "2.5", "3", "4")
    assert [cues[f"smallest_empty_ge_{r}x_object"] for r in ratios] == [
        ["obj04"], ["obj04"], ["obj04"], *[["obj05"]] * 8, ["obj06"], ["obj06"], []]
    assert choose_vessel(state, "obj03") == "obj05"  # the demonstrator's rule: capacity 0.6 of the box


def test_the_task_object_is_never_its_own_smallest_container():
    """A cup to move or throw away is compared with the other cups, not with itself (its own ratio is 1)."""
    cues = cues_of(kitchen(), "pick_and_place(obj04,obj01)")
    assert cues["smallest_empty_ge_1x_object"] == ["obj05"]  # 1.8 times obj04; obj06 is 2.7 times
    assert cues_of(kitchen(), "throw_away(obj06)")["smallest_empty_ge_1x_object"] == []  # none as large as obj06
    # without the task's object among the rows there is nothing to compare with
    ctx = step_context(kitchen(), Task.parse("pour(obj03)"), [])
    relations = ctx.relations.copy()
    relations[:, [c.endswith("_object") for c in RELATION_COLUMNS]] = 0.0
    assert not choice_cues(ctx.objects, relations)[:, :len(CUE_VOLUME_RATIOS)].any()


def test_the_shortest_thin_object_reaching_out_of_the_container_is_the_demonstrators_stirrer():
    state = kitchen()
    cues = cues_of(state, "stir(obj08)")  # the tea's cup obj07 is 0.1 m deep
    assert [cues[f"shortest_over_container_by_{m}m"] for m in ("0", "0.02", "0.04", "0.06", "0.1")] == [
        ["obj09"], ["obj10"], ["obj10"], ["obj11"], ["obj11"]]
    assert choose_stirrer(state, "obj07") == "obj10"
    # the container of pour's liquid is the 0.25 m bottle: only the ruler reaches out of it
    assert cues_of(state, "pour(obj03)")["shortest_over_container_by_0.04m"] == ["obj12"]
    assert not cues_of(state, "pour(obj03)")["shortest_over_container_by_0.06m"]


def test_a_flat_object_is_no_stirrer_however_long():
    """A book lying flat (its middle side more than half its longest) reaches out of the cup as far as a spoon would,
    and is shorter than the long stirrer; the cue passes over it."""
    state = kitchen()
    book = ObjectSpec("obj13", "obj13", "item", (0.16, 0.12, 0.02), frozenset({"movable", "box"}))
    state = WorldState({**state.specs, "obj13": book}, {**state.poses, "obj13": (-0.45, 0.2, 0.75)},
                       {**state.support, "obj13": ("obj01", ON)}, robot=state.robot)
    cues = cues_of(state, "stir(obj08)")  # 0.1 m deep: obj10 reaches 5 cm out, the book 6, obj11 12
    assert cues["shortest_over_container_by_0.06m"] == ["obj11"]
    assert cues["shortest_over_container_by_0.04m"] == ["obj10"]
    assert choose_stirrer(state, "obj07") == "obj10"
    # a middle side of exactly half the longest still counts as elongated
    stick = ObjectSpec("obj14", "obj14", "item", (0.2, 0.1, 0.01), frozenset({"movable", "box"}))
    state = WorldState({**kitchen().specs, "obj14": stick}, {**kitchen().poses, "obj14": (-0.45, 0.2, 0.75)},
                       {**kitchen().support, "obj14": ("obj01", ON)}, robot=kitchen().robot)
    assert cues_of(state, "stir(obj08)")["shortest_over_container_by_0.06m"] == ["obj14"]


def test_the_nearest_of_each_kind_is_marked():
    nearest = cues_of(kitchen(), "pour(obj03)")["nearest_of_kind"]
    # cups and the bottle share their flags: obj06 is the nearest of them; the two liquids are one kind (the tea
    # obj08 the nearer), the stirrers without the cylinder flag another (obj10); the rest are alone of their kind
    assert nearest == ["obj01", "obj06", "obj08", "obj10", "obj11", "obj12"]


def test_a_padded_batch_has_each_steps_own_cues():
    """The cues of a batch (`StepBatch.of`) are each step's alone: the padding and the other steps' objects
    never take part in a step's comparisons, and the padding has none."""
    from taskseq.learn.mrf import StepBatch

    state = kitchen()
    steps = [step_context(state, Task.parse(task), []) for task in ("pour(obj03)", "stir(obj08)")]
    small = WorldState({o: s for o, s in state.specs.items() if o not in ("obj05", "obj06", "obj10")},
                       {o: p for o, p in state.poses.items() if o not in ("obj05", "obj06", "obj10")},
                       {o: s for o, s in state.support.items() if o not in ("obj05", "obj06", "obj10")},
                       robot=state.robot)
    steps.append(step_context(small, Task.parse("pour(obj03)"), []))
    batch = StepBatch.of(steps, relations=True, cues=True)
    for s, x in enumerate(steps):
        assert batch.cues_rows[s, : x.n].tobytes() == choice_cues(x.objects, x.relations).tobytes()
        assert not batch.cues_rows[s, x.n :].any()


def test_the_choice_cue_method_is_a_labelled_row_of_table1():
    methods = Lineup(Methods(), Selection({**dict.fromkeys(specs(), 2.0), "choice": 0.5}, source="s")).factories()
    choice = methods["choice"]()
    assert (choice.features, choice.C, choice.dagger_rounds, choice.policy) == ("choice", 0.5, 0, "greedy")
    assert choice.learner_params() == methods["relations"]().learner_params() | {"C": 0.5}
    assert method_labels()["choice"] == "ours + relations + choice cues"


def test_the_choice_model_is_the_relations_model_plus_the_cue_blocks():
    from taskseq.learn.mrf import CUE_FAMILY, StepMRF

    state = kitchen()
    ctx = step_context(state, Task.parse("stir(obj08)"), [])
    choice, relations = StepMRF("choice"), StepMRF("relations")
    cue = choice.family_of() == CUE_FAMILY
    names = np.array(choice.feature_names())
    at = ctx.object_ids.index
    for y in [(0, at("obj10"), -1), (4, at("obj09"), at("obj07"))]:
        row = choice.joint_feature(ctx, y)
        np.testing.assert_array_equal(row[~cue], relations.joint_feature(ctx, y))
        marked = set(names[cue & (row != 0)])
        slot = "cues1[stir,move_close," if y[0] == 0 else "cues1[stir,hold_above,"
        expected = {"shortest_over_container_by_0.02m", "shortest_over_container_by_0.04m", "nearest_of_kind"}
        if y[0] == 4:
            expected = {"shortest_over_container_by_0m"}  # obj09, and obj07 (cues2) is no cue of a stir step
        assert marked == {f"{slot}{c}]" for c in expected}
