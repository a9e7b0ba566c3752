"""The procedural world family: drawn rooms pass the world's checks, every kept scenario replays, draws repeat."""

from __future__ import annotations

import filecmp
import json
from dataclasses import replace

import numpy as np
import pytest

from pipeline.cli import main
from pipeline.logs.generate import generate
from pipeline.settings import Generate, Params, Procedural
from pipeline.sim.catalog import OBJECTS, EnvironmentSpec, Placement, build_environment
from pipeline.sim.primitives import execute
from pipeline.sim.procedural import NEW_KINDS, SHAPES, Kind, Redraw, check_fits, draw_room
from pipeline.sim.scenarios import QUOTAS, drawn_scenarios, world_scenarios
from pipeline.sim.tasks import goal_reached

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
    ({"shapes": (("cylinder", 0.5), ("box", 0.4))}, "summing to 1"),
    ({"flags": "cylinder container", "shapes": (("cylinder", 0.5), ("", 0.5))}, r"\['cylinder'\] both fixed and drawn"),
])
def test_a_kind_that_draws_a_flag_defining_it_or_a_bad_probability_is_refused(change, message):
    base = {"name": "cup2", "category": "cup", "flags": "container movable", "width": (0.07, 0.08),
            "length": (0, 0), "height": (0.09, 0.1)}
    with pytest.raises(ValueError, match=message):
        Kind(**{**base, **change})
    assert Kind(**{**base, "category": "bin", "flags": "container", "maybe": (("movable", 0.5),)}).maybe  # bins only


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
