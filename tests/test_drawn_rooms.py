"""Training steps from drawn rooms, and the method that trains on them (`ours + ... + drawn rooms`)."""

from __future__ import annotations

import runpy
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from taskseq.evaluate.methods import ScorerMethod
from taskseq.features.drawn_rooms import drawn_room_steps
from taskseq.learn.estimator import StepScorer
from taskseq.methods import Lineup
from taskseq.selection import Selection
from taskseq.settings import Generate, Params, Procedural
from taskseq.sim.scenarios import world_scenarios

ROOT = Path(__file__).resolve().parents[1]
PARAMS = Params.load(ROOT / "params.yaml")


def _rooms(scenarios) -> set[tuple]:
    """Each room as what a person would recognise it by: every object's name and size, and where it stands."""
    by_room: dict[str, set] = {}
    for s in scenarios:
        st = s.initial
        by_room.setdefault(s.env_id, set()).update(
            (o.name, o.size, tuple(round(v, 6) for v in st.poses[i])) for i, o in st.specs.items())
    return {tuple(sorted(objects)) for objects in by_room.values()}


def test_steps_are_every_demonstrated_step_of_the_draw_done_included_and_the_same_on_every_call():
    rooms = drawn_room_steps(2, 1000, Procedural())
    scenarios, _ = world_scenarios(Generate(1000, "procedural", replace(Procedural(), environments=2)))
    demonstrated = sum(len(seq) + 1 for s in scenarios for seq in s.demonstrations)
    assert len(rooms) == demonstrated > 0
    assert all(x.gold is not None and x.relations is not None for x in rooms)
    drawn_room_steps.cache_clear()
    again = drawn_room_steps(2, 1000, Procedural())
    assert [x.gold for x in again] == [x.gold for x in rooms]
    for a, b in zip(again, rooms, strict=True):
        np.testing.assert_array_equal(a.objects, b.objects)
        np.testing.assert_array_equal(a.relations, b.relations)


def test_a_number_of_rooms_below_one_is_refused_with_its_value():
    with pytest.raises(ValueError, match="at least 1, got 0"):
        drawn_room_steps(0, 1000, Procedural())
    with pytest.raises(ValueError, match="rooms must be at least 1"):
        Lineup(Params.load(None, ["methods.drawn_rooms.rooms=0"]).methods).factory("drawn_rooms")


def test_the_rooms_trained_on_are_none_of_the_rooms_any_world_reports_or_develops_on():
    """The spy the held-out figures rest on: no room of a reported or development world (drawn with the
    repository's settings) is among the rooms the method trains on."""
    settings = Lineup(PARAMS.methods).settings_of("drawn_rooms")
    assert settings.rooms_seed not in (*PARAMS.world.seeds, PARAMS.world.dev_seed)
    training, _ = world_scenarios(Generate(settings.rooms_seed, "procedural",
                                           replace(PARAMS.procedural, environments=settings.rooms)))
    trained_on = _rooms(training)
    assert len(trained_on) == settings.rooms
    for seed in (*PARAMS.world.seeds, PARAMS.world.dev_seed):
        world, _ = world_scenarios(Generate(seed, "procedural", PARAMS.procedural))
        assert not _rooms(world) & trained_on, f"a room of world {seed} is among the rooms trained on"


def test_the_method_fits_on_its_training_steps_and_the_drawn_rooms_and_nothing_else(monkeypatch, benchmark_steps):
    contexts, meta = benchmark_steps
    first = list(dict.fromkeys(m.scenario_id for m in meta))[:4]
    keep = [i for i, m in enumerate(meta) if m.scenario_id in first]
    contexts, meta = [contexts[i] for i in keep], [meta[i] for i in keep]
    seen = []
    monkeypatch.setattr(StepScorer, "fit", lambda self, steps, warm_start=None: seen.append(list(steps)) or self)
    method = Lineup(Params.load(None, ["methods.drawn_rooms.rooms=2"]).methods,
                    Selection({"drawn_rooms": 1.0}, source="s")).factory("drawn_rooms")()
    assert method.policy == "lookahead" and method.features == "choice"
    method.fit(contexts, meta)
    rooms = drawn_room_steps(2, 1000, Procedural())
    assert len(seen) == 1 and len(seen[0]) == len(contexts) + len(rooms)
    assert all(a is b for a, b in zip(seen[0], contexts + list(rooms), strict=True))


def test_the_rooms_address_the_stored_model_and_other_methods_keep_their_keys(benchmark_steps):
    contexts = benchmark_steps[0][:30]
    plain = ScorerMethod(features="choice", C=1.0)
    assert "training_rooms" not in plain.learner_params()  # every stored model of the other methods keeps its key
    keys = {replace(plain, training_rooms=n, rooms_seed=s, rooms_from=d).key(contexts)
            for n, s, d in [(0, 0, Procedural()), (2, 1000, Procedural()), (3, 1000, Procedural()),
                            (2, 1001, Procedural()), (2, 1000, Procedural(stacks=0.25))]}
    assert len(keys) == 5


def test_the_method_draws_its_rooms_from_params_yaml_procedural():
    params = Params.load(None, ["procedural.stacks=0.25"])
    method = Lineup(params.methods, Selection({"drawn_rooms": 1.0}, source="s"),
                    procedural=params.procedural).factory("drawn_rooms")()
    assert method.rooms_from == params.procedural and method.training_rooms == 52


def test_the_choice_script_refuses_a_rooms_seed_that_is_a_worlds(tmp_path, capsys):
    params = tmp_path / "params.yaml"
    text = (ROOT / "params.yaml").read_text()
    params.write_text(text.replace("rooms_seed: 1000", "rooms_seed: 100"))
    main = runpy.run_path(str(ROOT / "scripts" / "drawn_rooms.py"))["main"]
    with pytest.raises(SystemExit):
        main(["--params", str(params), "--rooms", "2"])
    assert "rooms_seed 100 is a world's seed" in capsys.readouterr().err


def test_the_choice_script_ranks_by_sequence_arg_then_success_then_fewer_rooms():
    rank = runpy.run_path(str(ROOT / "scripts" / "drawn_rooms.py"))["rank"]
    rows = [{"rooms": 52, "sequence_arg": 90.0, "success": 99.0}, {"rooms": 26, "sequence_arg": 90.0, "success": 99.0},
            {"rooms": 13, "sequence_arg": 90.0, "success": 99.5}, {"rooms": 104, "sequence_arg": 91.0, "success": 90.0}]
    assert [r["rooms"] for r in rank(rows)] == [104, 13, 26, 52]


# --- the steps kept in the cache -----------------------------------------------------------------------------------

def _digests(steps):
    from taskseq.learn.fit_cache import step_digest

    return [step_digest(x) for x in steps]


@pytest.fixture
def steps_cache(tmp_path, monkeypatch):
    from taskseq.runtime import cache

    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path / "cache"))
    drawn_room_steps.cache_clear()
    yield tmp_path / "cache" / "steps"
    drawn_room_steps.cache_clear()


def test_with_the_cache_on_the_drawn_steps_are_kept_and_read_back_the_same_bytes(steps_cache, monkeypatch):
    from taskseq.features import drawn_rooms

    first = drawn_room_steps(2, 5, Procedural())
    (entry,) = steps_cache.glob("??/*.steps")
    assert sorted(p.name for p in entry.iterdir()) == ["objects.npz", "steps.parquet"]
    drawn_room_steps.cache_clear()
    draw = drawn_rooms.world_scenarios
    monkeypatch.setattr(drawn_rooms, "world_scenarios", lambda *a: pytest.fail("drawn again, not read back"))
    again = drawn_room_steps(2, 5, Procedural())
    assert again is not first and _digests(again) == _digests(first)
    drawn_room_steps.cache_clear()
    monkeypatch.setattr(drawn_rooms, "world_scenarios", draw)
    assert _digests(drawn_room_steps(2, 6, Procedural())) != _digests(first)  # another seed: another entry
    assert len(list(steps_cache.glob("??/*.steps"))) == 2


def test_an_unreadable_kept_draw_is_drawn_again_and_replaced(steps_cache):
    first = drawn_room_steps(2, 5, Procedural())
    (entry,) = steps_cache.glob("??/*.steps")
    (entry / "steps.parquet").write_bytes(b"not parquet")
    drawn_room_steps.cache_clear()
    with pytest.warns(UserWarning, match="an unreadable entry of the cache is drawn again"):
        again = drawn_room_steps(2, 5, Procedural())
    assert _digests(again) == _digests(first)
    drawn_room_steps.cache_clear()
    assert _digests(drawn_room_steps(2, 5, Procedural())) == _digests(first)  # the entry was replaced whole


def test_without_the_cache_no_draw_is_kept(tmp_path, monkeypatch):
    from taskseq.runtime import cache

    monkeypatch.delenv(cache.CACHE_ENV, raising=False)
    monkeypatch.chdir(tmp_path)
    drawn_room_steps.cache_clear()
    drawn_room_steps(2, 5, Procedural())
    drawn_room_steps.cache_clear()
    assert list(tmp_path.iterdir()) == []
