"""The procedural world family: drawn rooms pass the world's checks, every kept scenario replays, draws repeat."""

from __future__ import annotations

import filecmp
import json
from dataclasses import replace

import numpy as np
import pytest

from taskseq.cli import main
from taskseq.demonstrations.generate import generate
from taskseq.settings import Generate, Params, Procedural
from taskseq.sim.catalog import (
    ENVIRONMENTS_BY_ID,
    OBJECTS,
    OBJECTS_BY_ID,
    EnvironmentSpec,
    Placement,
    build_environment,
)
from taskseq.sim.primitives import execute
from taskseq.sim.procedural import (
    CATALOG_KINDS,
    NEW_KINDS,
    SHAPES,
    SHELF_CLEARANCE,
    Kind,
    Redraw,
    _catalog,
    _count,
    _Room,
    check_fits,
    draw_room,
)
from taskseq.sim.scenarios import QUOTAS, drawn_scenarios, world_scenarios
from taskseq.sim.tasks import goal_reached

CATALOG_NAMES = {o.name for o in OBJECTS}


@pytest.fixture(scope="module")
def drawn():
    return world_scenarios(Generate(seed=5, family="procedural", procedural=Procedural(environments=13)))


def test_every_kept_room_passes_the_checks_and_every_task_can_be_demonstrated_in_it():
    rng = np.random.default_rng(1)
    kept = 0
    for i in range(40):
        try:
            env, objects = draw_room(f"proc{i:03d}", Procedural(), rng)
        except Redraw:
            continue
        state = build_environment(env, objects=objects)  # raises on overlapping items
        assert check_fits(state) == []
        kept += 1
    assert kept >= 10
    pool, report = drawn_scenarios(2, 6, Procedural())
    assert {e for e in (s.env_id for s in pool)} == {f"proc{i:03d}" for i in range(1, 7)}
    for env in {s.env_id for s in pool}:
        assert {s.task.name for s in pool if s.env_id == env} == set(QUOTAS)
    assert report.environments == 6


def test_every_demonstration_of_a_drawn_world_replays_to_its_goal(drawn):
    scenarios, _ = drawn
    assert len(scenarios) >= 100
    for s in scenarios:
        for seq in s.demonstrations:
            state = s.initial
            for action in seq:
                state = execute(state, action)
            assert goal_reached(s.task, s.initial, state), s.id


def test_drawn_rooms_hold_varied_catalog_objects_and_kinds_the_catalog_never_had(drawn):
    scenarios, _ = drawn
    specs = {o: spec for s in scenarios for o, spec in s.initial.specs.items()}
    names = {spec.name for spec in specs.values()}
    new_names = {k.name for kinds in NEW_KINDS.values() for k in kinds}
    assert names & new_names and names & CATALOG_NAMES
    catalog_sizes = {o.size for o in OBJECTS}
    varied = [spec for spec in specs.values() if spec.name in CATALOG_NAMES and spec.category != "floor"]
    assert varied and sum(spec.size not in catalog_sizes for spec in varied) > 0.9 * len(varied)
    # every object id belongs to one room: a held-out room takes its objects with it
    rooms = {o: {s.env_id for s in scenarios if o in s.initial.specs} for o in specs if o != "obj01"}
    assert all(len(r) == 1 for r in rooms.values())


def test_a_new_kinds_flags_are_drawn_with_its_probabilities_and_those_that_define_it_stay():
    draws = 400
    for kind in (k for group in NEW_KINDS.values() for k in group):
        fixed = frozenset(kind.flags.split())
        flags = [kind.draw_flags(np.random.default_rng([7, seed])) for seed in range(draws)]
        assert flags == [kind.draw_flags(np.random.default_rng([7, seed])) for seed in range(draws)]  # seeded
        assert all(fixed <= f and len(f & set(SHAPES)) <= 1 for f in flags), kind.name
        varying = {f for f, _ in kind.maybe} | {s for s, _ in kind.shapes if s}
        assert all(f - fixed <= varying for f in flags), kind.name
        for flag, p in (*kind.maybe, *kind.shapes):
            share = sum((flag in f) if flag else not f & set(SHAPES) for f in flags) / draws
            assert abs(share - p) < 0.08, (kind.name, flag, share)
        assert (len(set(flags)) > 1) == bool(varying), kind.name  # objects of one kind differ where flags vary
    assert any(k.maybe or k.shapes for k in NEW_KINDS["vessel"] + NEW_KINDS["pourer"] + NEW_KINDS["bin"])


@pytest.mark.parametrize("change, message", [
    ({"maybe": (("container", 0.5),)}, r"\['container'\] define the kind and cannot vary"),
    ({"maybe": (("movable", 0.5),)}, r"\['movable'\] define the kind and cannot vary"),
    ({"maybe": (("handle", 1.0),)}, r"must lie in \(0, 1\)"),
    ({"maybe": (("handle", 0.0),)}, r"must lie in \(0, 1\)"),
    ({"shapes": (("cylinder", 0.5), ("bowl", 0.5))}, "shapes must be cylinder, box or ''"),
    ({"shapes": (("cylinder", 0.5), ("box", 0.4))}, "summing to 1"),
    ({"flags": "cylinder container", "shapes": (("cylinder", 0.5), ("", 0.5))}, r"\['cylinder'\] both fixed and drawn"),
])
def test_a_kind_that_draws_a_flag_defining_it_or_a_bad_probability_is_refused(change, message):
    base = {"name": "cup2", "category": "cup", "flags": "container movable", "width": (0.07, 0.08),
            "length": (0, 0), "height": (0.09, 0.1)}
    with pytest.raises(ValueError, match=message):
        Kind(**{**base, **change})
    assert Kind(**{**base, "category": "bin", "flags": "container", "maybe": (("movable", 0.5),)}).maybe  # bins only
    # what may be drawn: no shape (''), probabilities that sum to 1 up to rounding, a shape fixed when none is drawn
    assert Kind(**{**base, "shapes": (("cylinder", 0.7), ("box", 0.2), ("", 0.1))}).shapes
    assert Kind(**{**base, "flags": "cylinder container movable", "maybe": (("handle", 0.5),)}).maybe


def test_the_same_seed_draws_the_same_bytes_and_another_seed_other_rooms(tmp_path):
    world = Generate(seed=3, family="procedural", procedural=Procedural(environments=4))
    generate(world, tmp_path / "a")
    generate(world, tmp_path / "b")
    generate(replace(world, seed=4), tmp_path / "c")
    files = sorted(p.name for p in (tmp_path / "a").iterdir())
    assert files == [f"proc{i:03d}.jsonl" for i in range(1, 5)]
    assert filecmp.cmpfiles(tmp_path / "a", tmp_path / "b", files, shallow=False)[0] == files
    assert filecmp.cmpfiles(tmp_path / "a", tmp_path / "c", files, shallow=False)[0] == []


def test_the_benchmark_scales_with_the_number_of_rooms():
    small, _ = world_scenarios(Generate(seed=0, family="procedural", procedural=Procedural(environments=13)))
    large, _ = world_scenarios(Generate(seed=0, family="procedural", procedural=Procedural(environments=39)))
    assert 100 <= len(small) <= 113 and 300 <= len(large) <= 339
    assert len({s.env_id for s in large}) == 39


def test_check_fits_names_what_overhangs_or_stands_too_tall_for_its_shelf_level():
    objects = {o.id: o for o in OBJECTS}
    shelf = objects["obj08"]  # levels 0.5 0.8 1.1 1.4
    tall = replace(objects["obj42"], id="tall", size=(0.07, 0.19, 0.35))
    wide = replace(objects["obj39"], id="wide", size=(0.5, 0.23, 0.035))
    env = EnvironmentSpec("t", ((shelf.id, 0.0), ("obj02", 2.0)),
                          (Placement("tall", shelf.id, 0), Placement("obj14", "wide"),
                           Placement("wide", "obj02", 0, 0.7)))
    with pytest.raises(ValueError):  # placed before what holds it
        build_environment(env, objects={**objects, "tall": tall, "wide": wide})
    env = replace(env, items=(Placement("tall", shelf.id, 0), Placement("wide", "obj02", 0, 0.7)))
    problems = check_fits(build_environment(env, objects={**objects, "tall": tall, "wide": wide}))
    assert problems == ["tall does not fit under level 1 of obj08", "wide overhangs obj02"]
    env = replace(env, items=(Placement("tall", shelf.id, 3), Placement("wide", "obj02", 0, 0.3)))
    assert check_fits(build_environment(env, objects={**objects, "tall": tall, "wide": wide})) == []


def _env02_after(change) -> list[str]:
    """check_fits of env02 after `change(state)`: the soda can on the side table, the milk in its carton, the
    cereal box (level 0) and the carton (level 2) on the bookshelf obj07."""
    state = build_environment(ENVIRONMENTS_BY_ID["env02"])
    change(state)
    return check_fits(state)


def _shift(obj: str, dx: float = 0.0, dy: float = 0.0):
    def change(state):
        x, y, z = state.poses[obj]
        state.poses[obj] = (x + dx, y + dy, z)
    return change


def _resize(obj: str, **size: float):
    def change(state):
        spec = state.specs[obj]
        w, l, h = spec.size  # noqa: E741
        state.specs[obj] = replace(spec, size=(size.get("w", w), size.get("l", l), size.get("h", h)))
    return change


def _edges(state, obj):
    x0, y0, _, x1, y1, _ = state.box(obj)
    return x0, y0, x1, y1


@pytest.mark.parametrize("side", range(4), ids=["x low", "y low", "x high", "y high"])
def test_an_item_may_reach_its_supports_edge_and_no_further_on_every_side(side):
    state = build_environment(ENVIRONMENTS_BY_ID["env02"])
    gap = _edges(state, "obj05")[side] - _edges(state, "obj23")[side]  # the can's way to the side table's edge
    sign = 1.0 if side < 2 else -1.0  # low edges: past the edge is lower

    def to_edge(beyond: float):
        d = gap - sign * beyond
        return _shift("obj23", dx=d if side % 2 == 0 else 0.0, dy=d if side % 2 else 0.0)

    assert _env02_after(to_edge(0.0)) == _env02_after(to_edge(5e-7)) == []  # at the edge, within a micrometre
    assert _env02_after(to_edge(2e-6)) == ["obj23 overhangs obj05"]


@pytest.mark.parametrize("dimension", ["w", "l", "h"])
def test_what_a_container_holds_may_be_as_large_as_it_and_no_larger(dimension):
    carton = OBJECTS_BY_ID["obj21"]
    same = dict(zip("wlh", carton.size, strict=True))
    assert _env02_after(_resize("obj28", **same)) == []
    larger = {**same, dimension: same[dimension] + 0.001}
    assert _env02_after(_resize("obj28", **larger)) == ["obj28 is larger than obj21, which holds it"]


def test_a_shelf_item_and_what_stands_on_it_stay_below_the_next_level_of_its_own_level():
    levels = OBJECTS_BY_ID["obj07"].surface_heights()  # the bookshelf standing on the floor
    limit = levels[1] - levels[0] - SHELF_CLEARANCE  # the cereal box stands on level 0
    assert _env02_after(_resize("obj42", h=limit)) == []
    assert _env02_after(_resize("obj42", h=limit + 2e-6)) == ["obj42 does not fit under level 1 of obj07"]
    carton = levels[3] - levels[2] - SHELF_CLEARANCE  # the carton stands on level 2
    assert _env02_after(_resize("obj21", h=carton + 2e-6)) == ["obj21 does not fit under level 3 of obj07"]

    def stacked(state):  # the crumpled paper (6 cm) moved from the book onto the cereal box, cut 5 cm shorter
        _resize("obj42", h=limit - 0.05)(state)
        x, y, z = state.poses["obj42"]
        state.support["obj43"] = ("obj42", "on")
        state.poses["obj43"] = (x, y, z + limit - 0.05)

    assert _env02_after(stacked) == ["obj42 does not fit under level 1 of obj07"]  # the paper's top counts


def test_a_distribution_that_cannot_fit_a_room_stops_with_the_reasons_counted():
    crowded = Procedural(environments=1, tables=(1, 1), shelves=(0, 0), vessels=(60, 60))
    with pytest.raises(RuntimeError, match="no room for an object"):
        drawn_scenarios(0, 1, crowded)


def test_procedural_settings_are_checked_and_name_the_key(tmp_path):
    for setting, message in (("procedural.tables=2 1", "procedural.tables must be two counts, low then high"),
                             ("procedural.bins=0 2", "procedural.tables and procedural.bins must start at 1"),
                             ("procedural.new_objects=1.5", r"procedural.new_objects must lie in \[0, 1\)"),
                             ("world.family=castle", "world.family must be one of paper, procedural")):
        with pytest.raises(ValueError, match=message):
            Params.load(None, [setting])


def test_generate_draws_a_procedural_world_that_ingest_accepts(tmp_path):
    raw, metrics = tmp_path / "raw", tmp_path / "world.json"
    assert main(["--no-mlflow", "generate", "--world-seed", "2", "--set", "world.family=procedural",
                 "--set", "procedural.environments=3", "--output", str(raw), "--metrics", str(metrics)]) == 0
    report = json.loads(metrics.read_text())
    assert report["family"] == "procedural" and report["environments"] == 3 and report["demonstrations"] > 0
    assert report["redraws"] == sum(report["redraws_by_reason"].values())
    assert main(["--no-mlflow", "ingest", "--world-seed", "2", "--input", str(raw), "--output",
                 str(tmp_path / "processed")]) == 0


def test_drawn_objects_keep_to_the_distribution_that_describes_them():
    """Catalog objects vary each dimension within the spread (a shelf keeps its height, so its levels stay
    where they are), new objects keep to their kind's ranges (round ones as long as wide) and flags, about
    `new_objects` of the draws are new, and sizes are whole millimetres."""
    assert {o.category for o in _catalog("table", "shelf")} == {"table", "shelf"}
    assert CATALOG_KINDS["shelf"] == _catalog("shelf") and len(CATALOG_KINDS["vessel"]) > 3
    dist = Procedural()
    room = _Room("t", dist, np.random.default_rng(0))
    assert set(room.objects) == {"obj01"}  # the floor, under its catalog id
    ratios, new, drawable = {"shelf": [], "table": []}, 0, 0
    kinds = {k.name: k for ks in NEW_KINDS.values() for k in ks}
    for i in range(400):
        kind = ("shelf", "table", "vessel", "pourer", "stirrer", "bin", "item", "liquid")[i % 8]
        spec = room.draw(kind)
        drawable += kind in NEW_KINDS  # a draw that could have been of a new kind
        assert all(round(v, 3) == v for v in spec.size), spec
        if spec.name in kinds:
            new += 1
            k = kinds[spec.name]
            assert k.width[0] <= spec.w <= k.width[1] and k.height[0] <= spec.h <= k.height[1], spec
            assert spec.l == spec.w if k.length == (0, 0) else k.length[0] <= spec.l <= k.length[1], spec
            assert set(k.flags.split()) <= spec.flags, spec
            continue
        original = next(o for o in OBJECTS if o.name == spec.name and o.category == spec.category
                        and all(abs(a / b - 1) <= dist.size_spread + 0.02 for a, b in zip(spec.size, o.size,
                                                                                          strict=True)))
        if kind in ratios:
            ratios[kind].append([a / b for a, b in zip(spec.size, original.size, strict=True)])
    shelf, table = np.array(ratios["shelf"]), np.array(ratios["table"])
    assert (shelf[:, 2] == 1.0).all() and not (table[:, 2] == 1.0).all()
    for r in (shelf[:, :2], table):
        assert r.min() < 1 - 0.8 * dist.size_spread and r.max() > 1 + 0.8 * dist.size_spread
    assert drawable == 300 and abs(new / drawable - dist.new_objects) < 0.06  # sd of the share: 0.03
    counts = [_count(room.rng, (1, 3)) for _ in range(200)]
    assert set(counts) == {1, 2, 3}


def test_a_liquid_is_cut_to_fit_inside_its_container():
    """Within 90% of the container's narrower side and 80% of its height; a roomy container leaves it as drawn."""
    room = _Room("t", Procedural(), np.random.default_rng(0))
    small = replace(OBJECTS_BY_ID["obj14"], id="small", size=(0.06, 0.05, 0.04))
    big = replace(OBJECTS_BY_ID["obj14"], id="big", size=(0.5, 0.5, 0.5))
    for container in (small, big) * 5:
        room.liquid_in(container)
        placed = room.items[-1]
        liquid = room.objects[placed.obj]
        assert placed.on == container.id and liquid.category == "liquid"
        if container is small:
            assert liquid.w <= 0.045 + 1e-12 and liquid.l <= 0.045 + 1e-12 and liquid.h <= 0.032 + 1e-12
            assert min(liquid.w, liquid.l) == pytest.approx(0.045) or liquid.h == pytest.approx(0.032)  # cut
        else:
            assert liquid.w > 0.045 and liquid.h > 0.032  # liquids are drawn wider and taller than that
