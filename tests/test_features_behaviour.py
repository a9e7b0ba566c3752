"""What the model sees of a step and how it scores it, on hand-built worlds and hand-made steps: every column
against the world's own queries or a formula, every score against the dot product with the joint feature."""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np
import pytest

from taskseq.features.context import (
    ATTRIBUTE_COLUMNS,
    LENGTH_MARGINS,
    NO_PRIM,
    OBJECT_COLUMNS,
    RELATION_COLUMNS,
    RELATION_KINDS,
    STATE_COLUMNS,
    VOLUME_RATIOS,
    StepContext,
    _log_ratio,
    _spec_row,
    candidate_index,
    is_candidate,
    relations,
    scale_attribute,
    step_context,
)
from taskseq.features.cues import CUE_COLUMNS
from taskseq.learn.mrf import FEATURE_SETS, StepBatch, StepMRF, relations_row
from taskseq.sim.primitives import ALL_PRIMITIVES, ARITY, Action, execute
from taskseq.sim.state import INSIDE, ON, WorldState
from taskseq.sim.tasks import Task
from tests.conftest import world

# --- the step's context --------------------------------------------------------------------------------------


def test_lengths_and_volumes_are_scaled_on_fixed_log_scales():
    for name in ("height", "max_wl", "min_wl"):
        assert scale_attribute(name, 0.01) == 0.0 and scale_attribute(name, 10.0) == pytest.approx(1.0)
        assert scale_attribute(name, 0.1) == pytest.approx(1 / 3)
        assert scale_attribute(name, 0.0) == pytest.approx(-1 / 3)  # clipped at 1 mm
        assert scale_attribute(name, 0.001) == pytest.approx(-1 / 3)
    assert scale_attribute("volume", 1e-6) == 0.0 and scale_attribute("volume", 100.0) == pytest.approx(1.0)
    assert scale_attribute("volume", 1e-3) == pytest.approx(3 / 8)
    assert scale_attribute("volume", 0.0) == pytest.approx(-3 / 8)  # clipped at 1 mm^3
    assert scale_attribute("volume", 1e-9) == pytest.approx(-3 / 8)
    assert scale_attribute("min_over_max", 0.25) == 0.25 and scale_attribute("cylinder", True) == 1.0
    assert type(scale_attribute("cylinder", True)) is float


def test_log_ratio_spans_two_decades_each_way():
    a = np.array([1.0, 10.0, 100.0, 1000.0, 0.1, 0.01, 0.0001, 0.0])
    np.testing.assert_allclose(_log_ratio(a, 1.0), [0, 0.5, 1, 1, -0.5, -1, -1, -1])
    np.testing.assert_allclose(_log_ratio(np.array([1e-9, 1e-8]), 0.0), [0.0, 0.5])  # both floored at 1e-9
    np.testing.assert_allclose(_log_ratio(np.array([0.0]), 1e-7), [-1.0])


def test_spec_rows_are_scaled_attributes_and_shared():
    state = pour_world()
    spec = state.specs["obj14"]
    attrs, row = _spec_row(spec)
    assert attrs == spec.attributes()
    np.testing.assert_array_equal(row, [scale_attribute(a, attrs[a]) for a in ATTRIBUTE_COLUMNS])
    assert not row.flags.writeable and _spec_row(spec)[1] is row


def pour_world() -> WorldState:
    # table obj02 with a bottle (obj20) holding a liquid (obj27), two cups (obj14, obj15) and a stirrer (obj35)
    return world({2: 0.0}, [(14, 2, 0, 0.3), (15, 2, 0, -0.3), (20, 2, 0, 0.0), (27, 20), (35, 2, 0, 0.5)])


def stacked_world() -> WorldState:
    """A shelf (obj08) and a table (obj02), a cup on a plate on the table, a bottle with a liquid on the shelf."""
    return world({2: 0.0, 8: 1.6}, [(14, 2, 0, 0.3), (20, 8, 1, 0.0), (27, 20), (35, 2, 0, -0.4)], robot_x=0.5)


def reference_objects(state: WorldState, ids: list[str]) -> np.ndarray:
    """The object rows from the world's own queries, one object at a time."""
    rows = []
    for o in ids:
        attrs = state.specs[o].attributes()
        rows.append([float(state.held == o), min(state.distance(o), 10.0) / 10.0, float(state.reachable(o)),
                     float(bool(state.loads(o))), float(state.over_shelf(o)), float(bool(state.liquids_in(o))),
                     *(scale_attribute(a, attrs[a]) for a in ATTRIBUTE_COLUMNS)])
    return np.array(rows)


def reference_relations(state: WorldState, task: Task, ids: list[str]) -> np.ndarray:
    """Every relation column written out, object by object."""
    out = np.zeros((len(ids), len(RELATION_COLUMNS)))
    first = task.args[0]
    refs = {"object": first, "container": state.container_of(first), "held": state.held}
    for o_i, o in enumerate(ids):
        a = state.specs[o].attributes()
        for ref_name, ref in refs.items():
            if ref is None:
                continue
            r = state.specs[ref].attributes()
            col = {k: RELATION_COLUMNS.index(f"{k}_{ref_name}") for k in RELATION_KINDS}
            if o == ref:
                out[o_i, col["is"]] = 1.0
                continue
            for t in VOLUME_RATIOS:
                out[o_i, col[f"volume_ge_{t:g}x"]] = float(a["volume"] / r["volume"] >= t)
            out[o_i, col["log_volume_ratio"]] = max(-1.0, min(1.0, math.log10(a["volume"] / r["volume"]) / 2))
            for m in LENGTH_MARGINS:
                out[o_i, col[f"length_over_height_ge_{m:g}m"]] = float(a["max_wl"] - r["height"] >= m)
            (x, y, _), (rx, ry, _) = state.poses[o], state.poses[ref]
            out[o_i, col["near"]] = max(0.0, 1.0 - math.hypot(x - rx, y - ry))
    return out


def test_relations_are_the_formulas_written_out():
    state = pour_world()
    ids = sorted(state.specs)
    task = Task("pour", ("obj27",))
    got = relations(state, task, ids)
    np.testing.assert_allclose(got, reference_relations(state, task, ids), atol=1e-12)
    attrs = [state.specs[o].attributes() for o in ids]
    np.testing.assert_array_equal(relations(state, task, ids, attrs), got)
    # holding the left cup: its columns are filled too
    held = execute(execute(state, Action("move_close", ("obj14",))), Action("grasp", ("obj14",)))
    assert held.held == "obj14"
    np.testing.assert_allclose(relations(held, task, ids), reference_relations(held, task, ids), atol=1e-12)
    # a task object in no container, an empty gripper: only the object's columns
    cup = Task("pick_and_place", ("obj14", "obj02"))
    only = relations(state, cup, ids)
    np.testing.assert_allclose(only, reference_relations(state, cup, ids), atol=1e-12)
    assert not only[:, len(RELATION_KINDS):].any() and only[ids.index("obj14"), 0] == 1.0
    # no container, but a held object: the held object's columns are filled all the same
    stir = Task("stir", ("obj35",))
    both = relations(held, stir, ids)
    np.testing.assert_allclose(both, reference_relations(held, stir, ids), atol=1e-12)
    assert both[ids.index("obj14"), 2 * len(RELATION_KINDS)] == 1.0


def test_a_task_object_not_in_the_world_has_no_relations():
    state = pour_world()
    ids = sorted(state.specs)
    assert not relations(state, Task("pour", ("obj99",)), ids).any()


def test_on_a_shelf_and_far_away():
    # the bottle on the shelf's upper level, a glass on a second table 12 m away
    state = world({2: 0.0, 8: 1.6, 3: 12.0}, [(14, 2, 0, 0.3), (20, 8, 1, 0.0), (27, 20), (15, 3, 0, 0.0)])
    task = Task("pour_to", ("obj27", "obj14"))
    ctx = step_context(state, task, [])
    ids = ctx.object_ids
    np.testing.assert_allclose(ctx.objects, reference_objects(state, ids), atol=1e-12)
    shelf, dist = STATE_COLUMNS.index("over_shelf"), STATE_COLUMNS.index("distance")
    assert {ids[i] for i in np.flatnonzero(ctx.objects[:, shelf])} == {"obj20", "obj27"}
    assert ctx.objects[ids.index("obj15"), dist] == 1.0  # capped at 10 m
    rel = relations(state, task, ids)
    np.testing.assert_allclose(rel, reference_relations(state, task, ids), atol=1e-12)
    near = RELATION_COLUMNS.index("near_object")
    assert rel[ids.index("obj15"), near] == 0.0 and rel[ids.index("obj08"), near] > 0.0
    # nearness is horizontal only: the bottle and the liquid in it share x and y, not z
    assert state.poses["obj20"][2] != state.poses["obj27"][2] and rel[ids.index("obj20"), near] == 1.0


def test_footprints_that_only_touch_do_not_overlap_but_collide():
    # the cup (7.5 cm wide) and the glass (6.5 cm) side by side, edge to edge
    state = world({2: 0.0}, [(14, 2, 0, 0.3), (15, 2, 0, 0.37), (20, 2, 0, -0.3)])
    assert state.box("obj14")[3] == pytest.approx(state.box("obj15")[0], abs=1e-9)
    for task in (Task("pick_and_place", ("obj14", "obj15")), Task("pick_and_place", ("obj15", "obj14"))):
        ctx = step_context(state, task, [])
        ids = ctx.object_ids
        cup, glass = ids.index("obj14"), ids.index("obj15")
        assert ctx.task_rel[glass, 2] == 0.0 and ctx.task_rel[cup, 2] == 0.0 and ctx.task_rel[cup, 3] == 0.0
        assert ctx.task_rel[ids.index("obj02"), 2] == 1.0  # the table under it does overlap
        assert ctx.collide[cup, glass] and ctx.collide[glass, cup]


@pytest.mark.parametrize("make", [pour_world, stacked_world])
def test_every_object_column_is_the_worlds_own_answer(make):
    state = make()
    task = Task("pour", ("obj27",))
    history = [Action("move_close", ("obj20",)), Action("grasp", ("obj20",))]
    for a in history:
        state = execute(state, a)
    ids = sorted(state.specs)
    ctx = step_context(state, task, history, gold=Action("move_close", ("obj14",)))
    assert ctx.object_ids == ids and ctx.n == len(ids) and ctx.holding
    np.testing.assert_allclose(ctx.objects, reference_objects(state, ids), atol=1e-12)
    assert ctx.objects.shape == (len(ids), len(OBJECT_COLUMNS))
    np.testing.assert_array_equal(ctx.relations, relations(state, task, ids))
    assert ctx.task == 2 and ctx.prev_prims == (1, 0)  # grasp at t-1, move_close at t-2
    assert ctx.prev_args == (ids.index("obj20"), -1, ids.index("obj20"), -1)
    assert ctx.gold == (0, ids.index("obj14"), -1)


def test_loads_and_liquids_mark_the_objects_that_carry_them():
    # a cup on a tray (obj41) on the table, a bottle with a liquid in it, a stirrer in the cup
    state = world({2: 0.0}, [(41, 2, 0, 0.3), (14, 41), (20, 2, 0, 0.0), (27, 20), (35, 14)])
    assert state.support["obj14"] == ("obj41", ON) and state.support["obj27"] == ("obj20", INSIDE)
    assert state.support["obj35"] == ("obj14", INSIDE)
    ctx = step_context(state, Task("pour", ("obj27",)), [])
    ids = ctx.object_ids
    load, wet = STATE_COLUMNS.index("has_load"), STATE_COLUMNS.index("holds_liquid")
    assert {ids[i] for i in np.flatnonzero(ctx.objects[:, load])} == {"obj01", "obj02", "obj41"}  # floor too
    assert {ids[i] for i in np.flatnonzero(ctx.objects[:, wet])} == {"obj20"}  # the stirrer is no liquid
    np.testing.assert_allclose(ctx.objects, reference_objects(state, ids), atol=1e-12)


def test_task_relations_mark_the_arguments_and_what_overlaps_them_from_above():
    state = world({2: 0.0}, [(14, 2, 0, 0.3), (20, 2, 0, 0.0), (27, 20), (35, 14, 0, 0.0), (15, 2, 0, -0.3)])
    task = Task("pick_and_place", ("obj14", "obj20"))
    ctx = step_context(state, task, [])
    ids = ctx.object_ids
    expected = np.zeros((len(ids), 4))
    for k, g in enumerate(task.args):
        expected[ids.index(g), k] = 1.0
        for i, o in enumerate(ids):
            if o != g and state.overlap_top(o, g):
                expected[i, 2 + k] = 1.0
    np.testing.assert_array_equal(ctx.task_rel, expected)
    assert expected[:, 2].sum() >= 2 and expected[:, 3].sum() >= 2  # the table and what rests on or in them


def test_collisions_are_touching_boxes_never_an_object_with_itself():
    state = world({2: 0.0}, [(14, 2, 0, 0.3), (15, 2, 0, 0.3 + 0.2), (20, 2, 0, -0.4)])
    ctx = step_context(state, Task("pick_and_place", ("obj14", "obj02")), [])
    ids = ctx.object_ids
    for i, a in enumerate(ids):
        for j, b in enumerate(ids):
            ba, bb = state.box(a), state.box(b)
            touch = all(ba[k] <= bb[k + 3] + 1e-6 and bb[k] <= ba[k + 3] + 1e-6 for k in range(3))
            assert ctx.collide[i, j] == (touch and i != j), (a, b)
    assert ctx.collide.dtype == bool and ctx.collide[ids.index("obj14"), ids.index("obj02")]


def test_history_of_one_step_and_of_none():
    state = pour_world()
    task = Task("stir", ("obj27",))
    assert step_context(state, task, []).prev_prims == (NO_PRIM, NO_PRIM)
    assert step_context(state, task, []).prev_args == (-1, -1, -1, -1)
    one = step_context(state, task, [Action("hold_above", ("obj14", "obj15"))])
    ids = one.object_ids
    assert one.prev_prims == (4, NO_PRIM)
    assert one.prev_args == (ids.index("obj14"), ids.index("obj15"), -1, -1)
    three = step_context(state, task, [Action("done"), Action("release", ("obj99",)), Action("grasp", ("obj35",))])
    assert three.prev_prims == (1, 2) and three.prev_args == (ids.index("obj35"), -1, -1, -1)  # unknown: -1
    assert step_context(state, task, []).gold is None


def test_a_context_gives_back_the_last_two_steps_it_remembers_oldest_first():
    state = pour_world()
    task = Task("stir", ("obj27",))
    assert step_context(state, task, []).history() == []
    one = [Action("hold_above", ("obj14", "obj15"))]
    assert step_context(state, task, one).history() == one
    steps = [Action("done"), Action("grasp", ("obj14",)), Action("place_above", ("obj14", "obj15")),
             Action("release", ("obj14",))]
    assert step_context(state, task, steps).history() == steps[-2:]
    assert step_context(state, task, steps[:3]).history() == steps[1:3]
    first = step_context(state, task, []).object_ids[0]  # index 0 is an object like any other
    assert step_context(state, task, [Action("move_close", (first,))]).history() == [Action("move_close", (first,))]


def hand_step(rng: np.random.Generator, n: int, task: int, prev=(NO_PRIM, NO_PRIM), prev_args=(-1, -1, -1, -1),
              holding: bool = False, relations_: bool = True) -> StepContext:
    objects = rng.uniform(size=(n, len(OBJECT_COLUMNS)))
    objects[:, 0] = 0.0
    if holding:
        objects[n - 1, 0] = 1.0
    return StepContext([f"o{i}" for i in range(n)], objects, (rng.uniform(size=(n, 4)) < 0.4).astype(float),
                       np.triu(rng.uniform(size=(n, n)) < 0.5, 1) | np.triu(rng.uniform(size=(n, n)) < 0.5, 1).T,
                       task, prev, prev_args, None,
                       rng.uniform(size=(n, len(RELATION_COLUMNS))) if relations_ else None)


def test_a_steps_history_bits_holding_and_actions():
    ctx = hand_step(np.random.default_rng(0), 4, 1, (2, 3), (2, -1, 0, 2))
    expected = np.zeros((4, 4))
    expected[2, 0] = expected[0, 2] = expected[2, 3] = 1.0
    np.testing.assert_array_equal(ctx.history_equal(), expected)
    assert not ctx.holding
    ctx.objects[1, 0] = 0.5
    assert not ctx.holding
    ctx.objects[1, 0] = 0.51
    assert ctx.holding
    assert ctx.action((3, 1, 2)) == Action("place_above", ("o1", "o2"))
    assert ctx.action((1, 3, -1)) == Action("grasp", ("o3",)) and ctx.action((7, -1, -1)) == Action("done")
    assert ctx.action((1, 0, -1)) == Action("grasp", ("o0",)) and ctx.action((4, 1, 0)) == Action("hold_above",
                                                                                                ("o1", "o0"))
    for y in [(3, 1, 2), (1, 3, -1), (7, -1, -1), (3, 0, 1)]:
        assert ctx.encode(ctx.action(y)) == y
    with pytest.raises(ValueError, match=r"^grasp\(o9\): object o9 is not in this step's environment$"):
        ctx.encode(Action("grasp", ("o9",)))


@pytest.mark.parametrize("n", [1, 2, 3])
def test_candidates_respect_arity_in_primitive_then_argument_order(n):
    p, a1, a2 = candidate_index(n)
    expected = []
    for k, prim in enumerate(ALL_PRIMITIVES):
        if ARITY[prim] == 0:
            expected.append((k, -1, -1))
        elif ARITY[prim] == 1:
            expected += [(k, i, -1) for i in range(n)]
        else:
            expected += [(k, i, j) for i in range(n) for j in range(n) if i != j]
    assert list(zip(p.tolist(), a1.tolist(), a2.tolist(), strict=True)) == expected
    assert all(a.dtype == np.int64 and not a.flags.writeable for a in (p, a1, a2))
    assert candidate_index(n)[0] is p


@pytest.mark.parametrize("n", [1, 2, 4])
def test_a_label_is_a_candidate_exactly_when_candidate_index_lists_it(n):
    listed = set(zip(*(a.tolist() for a in candidate_index(n)), strict=True))
    values = range(-2, max(n, len(ALL_PRIMITIVES)) + 2)
    for label in itertools.product(values, repeat=3):
        assert is_candidate(label, n) == (label in listed), label
        assert is_candidate(np.array(label, dtype=np.int64), n) == (label in listed), label
    assert not is_candidate((0.5, -1, -1), n) and not is_candidate((len(ALL_PRIMITIVES), -1, -1), n)


# --- the model's score ---------------------------------------------------------------------------------------


@pytest.fixture
def steps() -> list[StepContext]:
    rng = np.random.default_rng(4)
    return [hand_step(rng, 3, 0), hand_step(rng, 4, 2, (1, 0), (1, -1, 1, -1), holding=True),
            hand_step(rng, 2, 4, (7, NO_PRIM), (-1, -1, -1, -1)), hand_step(rng, 5, 3, (3, 4), (0, 4, 2, 1)),
            hand_step(rng, 4, 2, (2, 1), (0, -1, 0, -1)), hand_step(rng, 1, 1)]


def all_candidates(x: StepContext) -> list[tuple[int, int, int]]:
    return list(zip(*(a.tolist() for a in candidate_index(x.n)), strict=True))


@pytest.mark.parametrize("features", sorted(FEATURE_SETS))
def test_every_score_is_the_weights_dot_the_joint_feature(steps, features):
    model = StepMRF(features)
    w = np.random.default_rng(1).normal(size=model.size_joint_feature)
    for x in steps:
        cands = all_candidates(x)
        direct = np.array([w @ model.joint_feature(x, y) for y in cands])
        (cp, ca1, ca2), s = model.scores(x, w)
        assert list(zip(cp.tolist(), ca1.tolist(), ca2.tolist(), strict=True)) == cands
        np.testing.assert_allclose(s, direct, rtol=1e-10, atol=1e-10)
        best = cands[int(np.argmax(direct))]
        assert model.inference(x, w) == best
        for gold in (cands[0], cands[-1], cands[len(cands) // 2]):
            aug = direct + np.array([model.loss(gold, y) for y in cands])
            assert model.loss_augmented_inference(x, gold, w) == cands[int(np.argmax(aug))]
        top = model.top_k(x, w, 4)
        order = np.argsort(-direct, kind="stable")[:4]
        assert [y for y, _ in top] == [cands[i] for i in order]
        np.testing.assert_allclose([s for _, s in top], direct[order], rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("features", sorted(FEATURE_SETS))
def test_the_batch_methods_equal_the_per_step_ones(steps, features):
    model = StepMRF(features)
    w = np.random.default_rng(2).normal(size=model.size_joint_feature)
    golds = [all_candidates(x)[k] for x, k in zip(steps, (0, 5, 3, 40, 20, 1), strict=True)]
    assert model.batch_inference(steps, w) == [model.inference(x, w) for x in steps]
    oracle = model.batch_loss_augmented_inference(steps, golds, w)
    assert oracle.dtype == np.int64 and oracle.shape == (6, 3)
    assert [tuple(r) for r in oracle.tolist()] == [model.loss_augmented_inference(x, g, w)
                                                   for x, g in zip(steps, golds, strict=True)]
    rows = model.batch_joint_feature_rows(steps, golds)
    assert rows.shape == (6, model.size_joint_feature) and rows.has_sorted_indices
    np.testing.assert_allclose(rows.toarray(), [model.joint_feature(x, g) for x, g in zip(steps, golds, strict=True)],
                               atol=1e-15)
    assert not np.any(rows.data == 0.0)
    other = [tuple(r) for r in oracle.tolist()]
    np.testing.assert_array_equal(model.batch_loss(golds, other), [model.loss(g, o) for g, o in zip(golds, other,
                                                                                                   strict=True)])


def test_ties_go_to_the_first_candidate(steps):
    model = StepMRF("full")
    w = np.zeros(model.size_joint_feature)
    x = steps[0]
    assert model.inference(x, w) == (0, 0, -1) and model.batch_inference([x], w) == [(0, 0, -1)]
    # zero weights: the most violated labelling is the first with a loss of 3
    assert model.loss_augmented_inference(x, (1, 0, -1), w) == (3, 1, 0)
    assert model.batch_loss_augmented_inference([x], [(1, 0, -1)], w).tolist() == [[3, 1, 0]]
    assert model.batch_loss_augmented_inference([x], [(7, -1, -1)], w).tolist() == [[3, 0, 1]]
    assert model.top_k(x, w, 3) == [((0, 0, -1), 0.0), ((0, 1, -1), 0.0), ((0, 2, -1), 0.0)]
    assert len(model.top_k(x, w, 1000)) == len(all_candidates(x))


def test_hamming_loss():
    model = StepMRF("edge")
    assert model.loss((1, 2, -1), (1, 2, -1)) == 0.0 and model.loss((1, 2, -1), (3, 2, 0)) == 2.0
    assert model.loss((1, 2, -1), (0, 1, 3)) == 3.0 and type(model.loss((1, 2, -1), (1, 2, -1))) is float
    np.testing.assert_array_equal(model.batch_loss([(1, 2, -1), (0, 0, 0)], [(1, 0, -1), (0, 0, 0)]), [1.0, 0.0])


def test_the_factor_tables_of_one_step(steps):
    model = StepMRF("relations")
    w = np.random.default_rng(3).normal(size=model.size_joint_feature)
    x = steps[3]
    P, U1, U2, pair = model.tables(x, w)
    assert P.shape == (8,) and U1.shape == U2.shape == (8, 5) and pair.shape == (8, 5, 5)
    for p, a1, a2 in all_candidates(x):
        s = P[p] + (U1[p, a1] if a1 >= 0 else 0) + (U2[p, a2] + pair[p, a1, a2] if a2 >= 0 else 0)
        assert s == pytest.approx(w @ model.joint_feature(x, (p, a1, a2)), abs=1e-10)
    P, U1, U2, pair = StepMRF("edge").tables(x, w[: StepMRF("edge").size_joint_feature])
    assert np.array_equal(pair[0], pair[5])  # without the low-rank term the pair table is the same for every p


def test_the_model_sizes_and_names():
    sizes = {f: StepMRF(f).size_joint_feature for f in FEATURE_SETS}
    assert sizes == {"full": 1589, "edge": 45, "clique": 1544, "relations": 7829, "choice": 7829 + 2 * 5 * 8 * 20}
    edge = StepMRF("edge")
    names = edge.feature_names()
    assert names[:5] == ["argument_environment1[held]", "argument_environment1[distance]",
                         "argument_environment2[held]", "argument_environment2[distance]",
                         "argument_environment_pair[collide]"]
    assert names[5] == "primitive_task[stir,move_close]" and names[-1] == "primitive_task[throw_away,done]"
    assert len(names) == 45
    full = StepMRF("full")
    names = full.feature_names()
    assert len(names) == 1589 and len(set(names)) == 1589
    assert "primitive_previous_task1[pour,none->grasp]" in names
    assert "primitive_previous_task2[stir,done->release]" in names
    assert "argument_environment_task_object1[pour_to,empty_hand,volume]" in names
    assert "primitive_argument_previous_argument2[done,a2_prev2]" in names
    families = full.family_of()
    assert len(families) == 1589
    assert families[0] == "argument_environment" and families[-1] == "primitive_argument_previous_argument"
    assert [f for f, n in zip(families, names, strict=True) if n.startswith("primitive_previous_task")] == \
        ["primitive_previous_task"] * (2 * 5 * 9 * 8)
    assert set(StepMRF("relations").family_of()) == {
        "argument_environment", "primitive_task", "argument_environment_task", "primitive_argument_environment",
        "primitive_previous_task", "primitive_argument_previous_argument", "relations"}
    with pytest.raises(ValueError, match=r"^features must be one of \['choice', 'clique', 'edge', 'full', "
                                         r"'relations'\], got 'nope'$"):
        StepMRF("nope")


@pytest.mark.parametrize(("features", "families"), [
    ("edge", {"argument_environment", "primitive_task"}),
    ("clique", {"argument_environment_task", "primitive_argument_environment", "primitive_previous_task",
                "primitive_argument_previous_argument"})])
def test_a_feature_set_writes_only_its_families(steps, features, families):
    full, part = StepMRF("relations"), StepMRF(features)
    mask = np.isin(full.family_of(), list(families))
    for x in steps:
        for y in all_candidates(x)[::7]:
            np.testing.assert_array_equal(part.joint_feature(x, y), full.joint_feature(x, y)[mask])


def test_the_relations_model_needs_relations_and_the_others_ignore_them():
    rng = np.random.default_rng(6)
    bare = hand_step(rng, 3, 1, relations_=False)
    model = StepMRF("relations")
    w = np.ones(model.size_joint_feature)
    message = r"^the relations model needs steps with relations \(build them with step_context\)$"
    for call in (lambda: model.joint_feature(bare, (0, 0, -1)), lambda: model.scores(bare, w),
                 lambda: model.batch_inference([bare], w)):
        with pytest.raises(ValueError, match=message):
            call()
    full = StepMRF("full")
    with_rel = StepContext(bare.object_ids, bare.objects, bare.task_rel, bare.collide, bare.task, bare.prev_prims,
                           bare.prev_args, None, rng.uniform(size=(3, len(RELATION_COLUMNS))))
    wf = rng.normal(size=full.size_joint_feature)
    np.testing.assert_array_equal(full.scores(bare, wf)[1], full.scores(with_rel, wf)[1])
    assert full.batch_inference([bare], wf) == full.batch_inference([with_rel], wf)


def test_a_padded_batch_never_picks_padding(steps):
    batch = StepBatch.of(steps)
    assert batch.valid.shape == (6, 5) and batch.valid.sum() == 3 + 4 + 2 + 5 + 4 + 1
    assert np.isneginf(batch.valid_neg[2, 2:]).all() and not batch.valid_neg[2, :2].any()
    assert batch.counts.tolist() == [3, 4, 2, 5, 4, 1]  # each step's objects first, the padding after them
    np.testing.assert_array_equal(batch.relations_rows[1, :4], relations_row(steps[1].objects, steps[1].task_rel,
                                                                             steps[1].relations))
    assert not batch.relations_rows[1, 4:].any()
    assert StepBatch.of(steps, relations=False).relations_rows.shape == (6, 5, 0)
    # the choice cues only when asked for (and only with the relations they are read from)
    for without in (batch, StepBatch.of(steps, relations=True, cues=False), StepBatch.of(steps, False, True)):
        assert without.cues_rows.shape == (6, 5, 0)
    assert StepBatch.of(steps, relations=True, cues=True).cues_rows.shape == (6, 5, len(CUE_COLUMNS))
    model = StepMRF("relations")
    w = -np.abs(np.random.default_rng(5).normal(size=model.size_joint_feature))  # padding at zero would win
    assert model.batch_inference(steps, w) == [model.inference(x, w) for x in steps]


def test_the_batch_of_the_last_steps_is_kept_until_released(steps):
    model = StepMRF("full")
    w = np.zeros(model.size_joint_feature)
    model.batch_inference(steps, w)
    first = model._batch_cache[1]
    model.batch_inference(steps, w)
    assert model._batch_cache[1] is first  # the same list: the same batch
    model.batch_inference(list(steps), w)
    assert model._batch_cache[1] is not first
    model.release()
    assert model._batch_cache is None


def test_relations_rows_key_the_state_on_the_task_object_and_its_container():
    objects = np.arange(2 * len(OBJECT_COLUMNS), dtype=float).reshape(2, -1)
    task_rel = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0]])
    rel = np.zeros((2, len(RELATION_COLUMNS)))
    rel[0, RELATION_COLUMNS.index("is_object")] = 1.0
    rel[1, RELATION_COLUMNS.index("is_container")] = 1.0
    rows = relations_row(objects, task_rel, rel)
    k = len(STATE_COLUMNS)
    np.testing.assert_array_equal(rows[0], np.concatenate([rel[0], task_rel[0], objects[0, :k], objects[0, :k],
                                                           np.zeros(k)]))
    np.testing.assert_array_equal(rows[1], np.concatenate([rel[1], task_rel[1], objects[1, :k], np.zeros(k),
                                                           objects[1, :k]]))


@pytest.mark.parametrize("features", sorted(FEATURE_SETS))
def test_the_oracle_weighs_the_loss_against_close_scores(steps, features):
    """Small weights: the Hamming loss decides between candidates, including the missing arguments of `done`."""
    model = StepMRF(features)
    rng = np.random.default_rng(7)
    for trial in range(3):
        w = 0.05 * rng.normal(size=model.size_joint_feature)
        for x in steps:
            cands = all_candidates(x)
            direct = np.array([w @ model.joint_feature(x, y) for y in cands])
            for gold in {cands[0], cands[-1], cands[len(cands) // 2], cands[trial % len(cands)], (7, -1, -1)}:
                aug = direct + np.array([model.loss(gold, y) for y in cands])
                expected = cands[int(np.argmax(aug))]
                assert model.loss_augmented_inference(x, gold, w) == expected
                assert model.batch_loss_augmented_inference([x], [gold], w).tolist() == [list(expected)]


def test_the_pair_features_of_colliding_arguments(steps):
    model = StepMRF("relations")
    x = steps[3]
    pairs = [(p, a1, a2) for p, a1, a2 in all_candidates(x) if a2 >= 0 and x.collide[a1, a2]]
    assert any(a1 == 0 for _, a1, _ in pairs) and any(a2 == 0 for _, _, a2 in pairs)
    rows = model.batch_joint_feature_rows([x] * len(pairs), pairs).toarray()
    collide = model.feature_names().index("argument_environment_pair[collide]")
    assert np.all(rows[:, collide] == 1.0)
    np.testing.assert_array_equal(rows, [model.joint_feature(x, y) for y in pairs])


def test_the_default_model_is_the_full_one():
    model = StepMRF()
    assert model.features == "full" and model.size_joint_feature == 1589
    assert StepMRF("edge").features == "edge"
    assert StepMRF("edge").families == ("argument_environment", "primitive_task")


def test_the_blocks_of_the_model():
    from taskseq.features.context import HISTORY_ARG_COLUMNS, TASK_REL_COLUMNS
    from taskseq.learn.mrf import RELATIONS_ROW, _blocks
    from taskseq.sim.tasks import TASKS

    prims, prev = ALL_PRIMITIVES, ALL_PRIMITIVES + ("none",)
    hands = ("holding", "empty_hand")
    expected = [
        ("argument_environment1", "argument_environment", (("held", "distance"),)),
        ("argument_environment2", "argument_environment", (("held", "distance"),)),
        ("argument_environment_pair", "argument_environment", (("collide",),)),
        ("primitive_task", "primitive_task", (TASKS, prims)),
        ("argument_environment_task_relation1", "argument_environment_task", (TASKS, TASK_REL_COLUMNS)),
        ("argument_environment_task_object1", "argument_environment_task", (TASKS, hands, OBJECT_COLUMNS)),
        ("argument_environment_task_relation2", "argument_environment_task", (TASKS, TASK_REL_COLUMNS)),
        ("argument_environment_task_object2", "argument_environment_task", (TASKS, hands, OBJECT_COLUMNS)),
        ("primitive_argument_environment1", "primitive_argument_environment", (prims, OBJECT_COLUMNS)),
        ("primitive_argument_environment2", "primitive_argument_environment", (prims, OBJECT_COLUMNS)),
        ("primitive_previous_task1", "primitive_previous_task", (TASKS, prev, prims)),
        ("primitive_previous_task2", "primitive_previous_task", (TASKS, prev, prims)),
        ("primitive_argument_previous_argument1", "primitive_argument_previous_argument", (prims, HISTORY_ARG_COLUMNS)),
        ("primitive_argument_previous_argument2", "primitive_argument_previous_argument", (prims, HISTORY_ARG_COLUMNS)),
        ("relations1", "relations", (TASKS, prims, RELATIONS_ROW)),
        ("relations2", "relations", (TASKS, prims, RELATIONS_ROW)),
        ("relations_pair", "relations", (TASKS, prims, TASK_REL_COLUMNS, TASK_REL_COLUMNS)),
        ("cues1", "cues", (TASKS, prims, CUE_COLUMNS)), ("cues2", "cues", (TASKS, prims, CUE_COLUMNS)),
    ]
    blocks = _blocks()
    assert [(b.name, b.family, b.labels) for b in blocks] == expected
    assert all(b.shape == tuple(len(labels) for labels in b.labels) for b in blocks)
    assert [b.size for b in blocks] == [math.prod(len(labels) for labels in e[2]) for e in expected]
    assert sum(b.size for b in blocks) == StepMRF("choice").size_joint_feature


def test_a_volume_exactly_twice_the_references_counts_as_twice():
    state = world({2: 0.0}, [(14, 2, 0, 0.3), (15, 2, 0, -0.3)])
    width, depth, height = state.specs["obj14"].size
    state.specs["obj15"] = replace(state.specs["obj14"], id="obj15", size=(width, depth, 2 * height))  # a taller copy
    ids = sorted(state.specs)
    r = relations(state, Task("pick_and_place", ("obj14", "obj02")), ids)
    tall = ids.index("obj15")
    assert [r[tall, RELATION_COLUMNS.index(f"volume_ge_{t:g}x_object")] for t in VOLUME_RATIOS] == [
        1.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0]
    assert r[tall, RELATION_COLUMNS.index("log_volume_ratio_object")] == pytest.approx(math.log10(2) / 2)


def test_the_oracle_charges_done_nothing_for_the_arguments_a_done_label_lacks():
    """Gold `done`, and `done` scored 2.5 above every other candidate: with its loss 0 against the pairs' 3, the
    most violated labelling is the first pair (2.5 + 0 < 0 + 3); at 3.5 it is `done` itself."""
    model = StepMRF("edge")
    x = hand_step(np.random.default_rng(8), 3, 1)
    w = np.zeros(model.size_joint_feature)
    w[model.feature_names().index("primitive_task[pick_and_place,done]")] = 2.5
    assert model.inference(x, w) == (7, -1, -1)
    assert model.loss_augmented_inference(x, (7, -1, -1), w) == (3, 0, 1)
    assert model.batch_loss_augmented_inference([x], [(7, -1, -1)], w).tolist() == [[3, 0, 1]]
    w[model.feature_names().index("primitive_task[pick_and_place,done]")] = 3.5
    assert model.batch_loss_augmented_inference([x], [(7, -1, -1)], w).tolist() == [[7, -1, -1]]
