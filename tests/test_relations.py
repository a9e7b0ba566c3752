"""Relations of objects to the step's reference objects: geometry only, never names or categories."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from taskseq.features.context import RELATION_COLUMNS, relations, step_context
from taskseq.sim.state import WorldState
from taskseq.sim.tasks import Task
from tests.conftest import world


def col(name: str) -> int:
    return RELATION_COLUMNS.index(name)


def pour_world() -> WorldState:
    # table obj02 with a bottle (obj20) holding a liquid (obj27), two cups (obj14, obj15) and a stirrer
    return world({2: 0.0}, [(14, 2, 0, 0.3), (15, 2, 0, -0.3), (20, 2, 0, 0.0), (27, 20), (35, 2, 0, 0.5)])


def rename(state: WorldState, mapping: dict[str, str], category: str | None = None) -> WorldState:
    """The same world with objects renamed (ids and names), and optionally every category replaced."""
    specs = {mapping.get(o, o): replace(s, id=mapping.get(o, o), name=f"thing {mapping.get(o, o)}",
                                         category=category or s.category) for o, s in state.specs.items()}
    support = {mapping.get(o, o): (mapping.get(on, on), rel) for o, (on, rel) in state.support.items()}
    poses = {mapping.get(o, o): p for o, p in state.poses.items()}
    held = mapping.get(state.held, state.held) if state.held else None
    return replace(state, specs=specs, support=support, poses=poses, held=held,
                   held_above=mapping.get(state.held_above, state.held_above) if state.held_above else None,
                   stirred={mapping.get(o, o) for o in state.stirred})


def test_relations_follow_geometry_not_names_or_categories():
    state = pour_world()
    ids = sorted(state.specs)
    base = relations(state, Task("pour", ("obj27",)), ids)
    mapping = {o: f"x{k:02d}" for k, o in enumerate(reversed(ids))}  # renamed, and the sorted order changes
    other = rename(state, mapping, category="item")
    new_ids = [mapping[o] for o in ids]
    moved = relations(other, Task("pour", (mapping["obj27"],)), new_ids)
    np.testing.assert_array_equal(base, moved)


def test_a_cup_that_holds_the_liquid_and_the_container_is_marked():
    state = pour_world()
    ids = sorted(state.specs)
    r = relations(state, Task("pour", ("obj27",)), ids)
    bottle, liquid = ids.index("obj20"), ids.index("obj27")
    assert r[bottle, col("is_container")] == 1.0 and r[:, col("is_container")].sum() == 1.0
    assert r[liquid, col("is_object")] == 1.0 and r[liquid, col("volume_ge_1x_object")] == 0.0  # not with itself
    vol = {o: state.specs[o].attributes()["volume"] for o in ids}
    for o in ids:
        if o != "obj27":
            assert r[ids.index(o), col("volume_ge_1x_object")] == float(vol[o] >= vol["obj27"])
    assert not r[:, [col(f"{k}_held") for k in ("is", "volume_ge_1x", "near")]].any()  # the gripper is empty


def test_step_contexts_carry_relations():
    state = pour_world()
    ctx = step_context(state, Task("pour", ("obj27",)), [])
    assert ctx.relations.shape == (ctx.n, len(RELATION_COLUMNS))


def test_step_context_rows_agree_with_the_states_own_queries(benchmark_tables):
    """The per-step rows are built in one pass over the state; each must say what `WorldState` says."""
    from taskseq.demonstrations.benchmark import Benchmark
    from taskseq.features.context import OBJECT_COLUMNS, scale_attribute
    from taskseq.sim.primitives import execute

    scenarios = Benchmark.from_records([i.record for i in benchmark_tables[1]]).scenarios
    checked = 0
    for sc in list(scenarios.values())[::7]:
        state, demo = sc.initial, sc.demonstrations[0]
        for k in range(len(demo) + 1):
            ctx = step_context(state, sc.task, list(demo[:k]))
            for i, o in enumerate(ctx.object_ids):
                row = dict(zip(OBJECT_COLUMNS, ctx.objects[i], strict=True))
                assert row["has_load"] == float(bool(state.loads(o)))
                assert row["holds_liquid"] == float(bool(state.liquids_in(o)))
                assert row["over_shelf"] == float(state.over_shelf(o))
                attrs = state.specs[o].attributes()
                assert all(row[a] == scale_attribute(a, attrs[a]) for a in attrs)
                for j, g in enumerate(sc.task.args[:2]):
                    assert ctx.task_rel[i, 2 + j] == float(o != g and state.overlap_top(o, g))
            checked += 1
            if k < len(demo):
                state = execute(state, demo[k])
    assert checked > 50
