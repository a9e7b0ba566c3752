"""The teach stage's split of taught and held-out data in drawn rooms, with a spy in place of the shipped planner:
the training steps are the drawn world's outside the held-out rooms plus exactly the first k demonstrations of each,
written and read back as a person's and counted `teach.weight` times; the planner is judged on the same other tasks
for every k, never on a task it was shown; the tables pair every k with k = 0 task by task. Then
`experiments/teaching.py` on hand-made tasks, outcomes and programs."""

from __future__ import annotations

import csv
import json
import math
import runpy
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from taskseq.cli import main
from taskseq.experiments import teaching
from taskseq.experiments.crossval import SequenceOutcome
from taskseq.experiments.teaching import Outcome, pooled, rooms_to_teach, success_on, teaching_order, weighted
from taskseq.serve.environments import world_environment
from taskseq.settings import Learner, Params, Teach, World
from taskseq.sim.demonstrator import demonstrate
from taskseq.sim.primitives import Action
from taskseq.sim.scenarios import room_scenarios
from taskseq.sim.tasks import Task
from taskseq.stages import teach
from taskseq.stages.options import TeachOptions

ROOT = Path(__file__).resolve().parents[1]
ROOMS = ("proc002", "proc003")
KS = (0, 1, 2)
SEEDS = (0, 1)
LEARNER = Learner(tol=1e-3, max_iter=7)


@pytest.fixture(scope="module")
def worlds(tmp_path_factory):
    """Two drawn worlds of three rooms, as the scenes stage leaves them (`<seed>/processed`)."""
    root = tmp_path_factory.mktemp("drawn")
    for seed in SEEDS:
        raw = root / f"raw{seed}"
        assert main(["--no-mlflow", "generate", "--world-seed", str(seed), "--set", "world.family=procedural",
                     "--set", "procedural.environments=3", "--output", str(raw)]) == 0
        processed = root / str(seed) / "processed"
        assert main(["--no-mlflow", "ingest", "--input", str(raw), "--output", str(processed)]) == 0
    return root


class Spy:
    """The shipped planner as the stage sees it: what it was fitted on, and what it was asked to run."""

    def __init__(self, log: list) -> None:
        self.log = log

    def fit(self, contexts, meta, scenarios):
        assert {m.scenario_id for m in meta} <= set(scenarios)  # every training scenario can be rolled out
        self.entry = {"steps": list(contexts), "meta": list(meta), "ran": []}
        self.log.append(self.entry)
        return self

    def run(self, scenario, max_steps):
        self.entry["ran"].append((scenario, max_steps))
        return SimpleNamespace(scenario=scenario)


def outcome(world_seed: int, k: int, scenario) -> SequenceOutcome:
    """Hand-chosen: every pour is right from k = 1 on; in world 0 every other task from k = 2; success as arg, except
    that in world 1 everything succeeds."""
    right = (scenario.task.name == "pour" and k >= 1) or (world_seed == 0 and k >= 2)
    return SequenceOutcome(scenario.id, scenario.task.name, (), "done", right, right, True, True,
                           right or world_seed == 1, "exact" if right else "other_success")


@pytest.fixture
def spied(worlds, tmp_path, monkeypatch):
    calls = SimpleNamespace(fits=[], plots=[], metrics=[])

    def judged(make, method, scenarios, max_steps):
        n = calls.fits.index(method.entry)  # the stage fits world by world, k by k
        return [outcome(SEEDS[n // len(KS)], KS[n % len(KS)], method.run(s, max_steps).scenario) for s in scenarios]

    monkeypatch.setattr(teach, "judged", judged)
    monkeypatch.setattr(teach, "line_plot_png", lambda *a, **kw: calls.plots.append((a, kw)))
    monkeypatch.setattr(teach, "Lineup", lambda *a, **kw: SimpleNamespace(
        mrf=lambda names: {names[0]: lambda: Spy(calls.fits)}))
    tracker = SimpleNamespace(metrics=lambda values: calls.metrics.append(values))
    settings = teach.Settings(World(seeds=SEEDS), Teach(environments=ROOMS, k=KS, seed=5, weight=3), LEARNER, 17,
                              Params().methods)
    selection = tmp_path / "selection.json"
    selection.write_text(json.dumps({"method": "drawn_rooms", "settings": {"drawn_rooms": {"C": 0.3}}}))
    calls.table = teach.run(settings, TeachOptions(worlds=worlds, output=tmp_path / "out", selection=selection),
                            tracker)
    calls.out, calls.worlds = tmp_path / "out", worlds
    return calls


def _rooms_of(meta) -> set[str]:
    return {m.scenario_id.split("/")[0] for m in meta}


def test_training_is_the_drawn_world_outside_the_held_out_rooms_plus_the_first_k_taught_tasks_weighted(spied):
    assert len(spied.fits) == len(SEEDS) * len(KS)
    for n, fit in enumerate(spied.fits):
        k = KS[n % len(KS)]
        base = [m for m in fit["meta"] if "/scripted-" not in m.sequence_id]
        taught = [m for m in fit["meta"] if "/scripted-" in m.sequence_id]
        assert not _rooms_of(base) & set(ROOMS) and _rooms_of(base) == {"proc001"}
        assert len(base) == len(spied.fits[n - n % len(KS)]["meta"])  # k = 0 trains on the base alone
        sequences = {m.sequence_id for m in taught}
        assert len(sequences) == k * len(ROOMS) and _rooms_of(taught) == (set(ROOMS) if k else set())
        assert all(sum(m.sequence_id == s for m in taught) % 3 == 0 for s in sequences)  # each counted 3 times
        assert len(taught) == 3 * len(taught) // 3 and len(fit["steps"]) == len(fit["meta"])
    # the tasks shown at k are those shown at k - 1 and one more per room
    for seed in range(len(SEEDS)):
        shown = [{m.scenario_id for m in spied.fits[seed * len(KS) + i]["meta"] if "/scripted-" in m.sequence_id}
                 for i in range(len(KS))]
        assert shown[0] <= shown[1] <= shown[2] and len(shown[2]) == len(ROOMS) * max(KS)


def test_the_planner_is_judged_on_the_same_other_tasks_for_every_k_and_never_on_a_shown_one(spied):
    for seed in range(len(SEEDS)):
        fits = spied.fits[seed * len(KS):(seed + 1) * len(KS)]
        ran = [[s.id for s, _ in f["ran"]] for f in fits]
        assert ran[0] == ran[1] == ran[2] and all(cap == 17 for f in fits for _, cap in f["ran"])
        shown = {m.scenario_id for m in fits[-1]["meta"] if "/scripted-" in m.sequence_id}
        assert not shown & set(ran[0]) and {r.split("/")[0] for r in ran[0]} == set(ROOMS)
        states = {s.env_id: s.initial for s, _ in fits[0]["ran"]}
        every = {s.id for room in ROOMS for s in room_scenarios(room, states[room])}
        assert set(ran[0]) | shown == every  # every task the demonstrator can do there is shown or judged


def test_the_tables_pair_every_k_with_k0_and_carry_the_outcomes_by_hand(spied):
    programs = list(csv.DictReader((spied.out / "teach_programs.csv").open()))
    assert {(r["world_seed"], r["k"]) for r in programs} == {(str(s), str(k)) for s in SEEDS for k in KS}
    per_seed = {(int(r["world_seed"]), int(r["k"])): r for r in csv.DictReader((spied.out / "teach_seeds.csv").open())}
    for (seed, k), row in per_seed.items():
        mine = [p for p in programs if p["world_seed"] == str(seed) and p["k"] == str(k)]
        pours = sum(p["task"] == "pour" for p in mine)
        right = len(mine) if seed == 0 and k >= 2 else pours if k >= 1 else 0
        assert int(row["held_out_tasks"]) == len(mine)
        assert float(row["sequence_arg"]) == pytest.approx(100 * right / len(mine), abs=0.005)
        assert float(row["success"]) == pytest.approx(100.0 if seed == 1 else 100 * right / len(mine), abs=0.005)
    table = {int(r["k"]): r for r in csv.DictReader((spied.out / "teach.csv").open())}
    n = sum(1 for p in programs if p["k"] == "0")
    assert int(table[0]["arg_misses"]) == n and float(table[0]["misses_removed"]) == 0.0
    assert int(table[0]["better"]) == int(table[0]["worse"]) == 0 and float(table[0]["p"]) == 1.0
    k2 = [p for p in programs if p["k"] == "2"]
    fixed = sum(p["sequence_arg"] == "1" for p in k2)
    assert int(table[2]["better"]) == fixed and int(table[2]["worse"]) == 0
    assert float(table[2]["misses_removed"]) == pytest.approx(100 * fixed / n, abs=0.005)
    assert float(table[2]["p"]) == pytest.approx(2 * 0.5 ** fixed, rel=1e-3)
    # the table is from unrounded figures, the per-world file rounds them
    seq = [float(per_seed[(s, 1)]["sequence_arg"]) for s in SEEDS]
    assert float(table[1]["sequence_arg_mean"]) == pytest.approx(np.mean(seq), abs=0.02)
    assert float(table[1]["sequence_arg_sd"]) == pytest.approx(np.std(seq, ddof=1), abs=0.02)
    md = (spied.out / "teach.md").read_text()
    assert "the shipped planner, ours + relations + choice cues + safety lookahead + drawn rooms (`drawn_rooms`)" in md
    assert "counted 3 times" in md and f"| 2 | {float(table[2]['sequence_arg_mean']):.1f} ±" in md
    assert spied.metrics[-1] == {"sequence_arg_k2": pytest.approx(float(table[2]["sequence_arg_mean"]), abs=0.005),
                                 "success_k2": pytest.approx(float(table[2]["success_mean"]), abs=0.005)}
    (args, kwargs), = spied.plots
    assert set(args[0]) == {"sequence arg", "success"} and kwargs["xticks"] == list(KS)


def test_a_room_the_drawn_world_does_not_have_is_refused_naming_the_rooms_it_has(worlds, tmp_path):
    selection = tmp_path / "selection.json"
    selection.write_text(json.dumps({"method": "full", "settings": {"full": {"C": 1.0}}}))
    settings = teach.Settings(World(seeds=(0,)), Teach(environments=("proc009",), k=(0,)), LEARNER, 17,
                              Params().methods)
    with pytest.raises(ValueError, match=r"proc009 not among world 0's rooms \(proc001, proc002, proc003\)"):
        teach.run(settings, TeachOptions(worlds=worlds, output=tmp_path / "out", selection=selection))
    assert not (tmp_path / "out").exists()


def test_a_selection_without_a_ranked_method_is_refused(worlds, tmp_path):
    selection = tmp_path / "selection.json"
    selection.write_text(json.dumps({"settings": {"full": {"C": 1.0}}}))
    settings = teach.Settings(World(seeds=(0,)), Teach(environments=ROOMS, k=(0,)), LEARNER, 17, Params().methods)
    with pytest.raises(ValueError, match="names no method ranked first"):
        teach.run(settings, TeachOptions(worlds=worlds, output=tmp_path / "out", selection=selection))


def test_teach_settings_refuse_a_weight_below_one_and_a_negative_k():
    with pytest.raises(ValueError, match="teach.weight must be at least 1"):
        Params.load(None, ["teach.weight=0"])
    with pytest.raises(ValueError, match="teach.k must list"):
        Params.load(None, ["teach.k=0 -1"])
    s = teach.settings(Params.load(None, ["teach.weight=4", "world.seeds=[2]", "crossval.max_steps=9"]))
    assert s.teach.weight == 4 and s.world.seeds == (2,) and s.max_steps == 9


def test_weighted_counts_each_taught_step_weight_times_after_the_base():
    assert weighted(["a", "b"], ["ma", "mb"], ["t"], ["mt"], 3) == (["a", "b", "t", "t", "t"],
                                                                      ["ma", "mb", "mt", "mt", "mt"])
    with pytest.raises(ValueError, match="at least 1"):
        weighted([], [], ["t"], ["mt"], 0)


def test_rooms_to_teach_shows_the_first_of_the_teaching_order_and_tests_the_rest():
    env = world_environment(0, "env02")
    candidates = room_scenarios("env02", env.state)
    order = teaching_order([(s.task, list(s.demonstrations[0])) for s in candidates], np.random.default_rng(3))
    (room,) = rooms_to_teach({"env02": env.state}, 2, np.random.default_rng(3))
    assert [t for t, _ in room.shown] == [candidates[i].task for i in order[:2]]
    assert [a for _, a in room.shown] == [candidates[i].demonstrations[0] for i in order[:2]]
    assert [s.id for s in room.tested] == [candidates[i].id for i in order[2:]]


def test_the_weight_script_ranks_by_sequence_arg_then_success_then_the_smaller_weight():
    rank = runpy.run_path(str(ROOT / "scripts" / "teach_weight.py"))["rank"]
    rows = [{"weight": 10, "sequence_arg": 90.0, "success": 99.0}, {"weight": 3, "sequence_arg": 90.0, "success": 99.0},
            {"weight": 1, "sequence_arg": 90.0, "success": 99.5}, {"weight": 30, "sequence_arg": 91.0, "success": 9.0}]
    assert [r["weight"] for r in rank(rows)] == [30, 1, 3, 10]


def test_the_weight_script_refuses_a_reported_world_as_a_development_draw(capsys):
    main = runpy.run_path(str(ROOT / "scripts" / "teach_weight.py"))["main"]
    with pytest.raises(SystemExit) as exit_:
        main(["--dev-seeds", "100", "3", "--weights", "1"])
    assert exit_.value.code == 2
    assert "--dev-seeds: 3 is a reported world seed" in capsys.readouterr().err


def test_the_weight_script_counts_misses_at_the_smallest_and_the_largest_k():
    misses = runpy.run_path(str(ROOT / "scripts" / "teach_weight.py"))["misses"]
    programs = [{"world_seed": seed, "k": k, "sequence_arg": arg} for seed, k, arg in
                ((1, 0, 0), (1, 0, 0), (1, 0, 1), (1, 1, 1), (1, 3, 0), (1, 3, 1), (1, 3, 1), (2, 0, 0))]
    assert misses(programs, 1, (0, 1, 3)) == (2, 1)
    assert misses(programs, 2, (0, 1, 3)) == (1, 0)


def test_the_room_prior_adds_beta_to_exactly_the_candidates_that_use_an_object_as_a_taught_step_did():
    """`scripts/teach_room_prior.py`: a candidate gains beta per (primitive, position, object) a taught step had,
    nothing else moves, and with beta 0 the ranking is the scorer's own, ties included."""
    from taskseq.features.context import step_context
    from taskseq.learn.estimator import StepScorer
    from taskseq.learn.mrf import StepMRF

    script = runpy.run_path(str(ROOT / "scripts" / "teach_room_prior.py"))
    env = world_environment(0, "env01")
    x = step_context(env.state, Task("pour", ("obj27",)), [])
    scorer = StepScorer.from_weights("full", np.random.default_rng(0).normal(size=StepMRF("full").size_joint_feature))
    uses = {("grasp", 0, "obj20"), ("place_above", 1, "obj14"), ("grasp", 0, "not-in-this-room")}
    (cp, ca1, ca2), plain = scorer.model_.scores(x, scorer.w_)
    _, primed = script["RoomPrior"](scorer, uses, 0.5).scores(x)
    grasp, place = (["move_close", "grasp", "release", "place_above", "hold_above", "follow_traj_circle",
                     "follow_traj_pour", "done"].index(p) for p in ("grasp", "place_above"))
    ids = np.array(x.object_ids)
    favoured = (((cp == grasp) & (ca1 >= 0) & (ids[ca1] == "obj20"))
                | ((cp == place) & (ca2 >= 0) & (ids[ca2] == "obj14")))
    assert favoured.sum() > 1
    assert np.array_equal(primed, plain + np.where(favoured, 0.5, 0.0))
    assert list(script["RoomPrior"](scorer, uses, 0.0).ranked(x)) == list(scorer.ranked(x))
    room = SimpleNamespace(shown=((Task("pour", ("obj27",)), (Action("grasp", ("obj20",)),
                                                              Action("hold_above", ("obj20", "obj14")))),
                                  (Task("stir", ("obj32",)), (Action("grasp", ("obj33",)),))))
    assert script["taught_uses"](room, 1) == {("grasp", 0, "obj20"), ("hold_above", 0, "obj20"),
                                              ("hold_above", 1, "obj14")}


def test_the_room_prior_script_refuses_a_reported_world_and_a_negative_beta(capsys):
    main = runpy.run_path(str(ROOT / "scripts" / "teach_room_prior.py"))["main"]
    for argv, said in ((["--dev-seeds", "100", "7"], "--dev-seeds: 7 is a reported world seed"),
                       (["--betas", "0", "-1"], "every beta must be at least 0")):
        with pytest.raises(SystemExit) as exit_:
            main(argv)
        assert exit_.value.code == 2 and said in capsys.readouterr().err


def test_records_are_written_by_the_servers_writer_and_read_back_as_ingest_reads_them():
    env = world_environment(0, "env01")
    tasks = [Task("pour", ("obj27",)), Task("throw_away", ("obj43",))]
    records = [teach.person_record(env, t, demonstrate(env.state, t)[0], teach.SCRIPTED) for t in tasks]
    back = teach.written_and_read_back(records)
    assert back == records and back is not records
    assert teach.written_and_read_back([]) == []
    unsafe = teach.person_record(env, Task("pour_to", ("obj27", "obj14")), [Action.parse(a) for a in (
        "move_close(obj20)", "grasp(obj27)", "hold_above(obj27,obj14)", "release(obj27)")], teach.SCRIPTED)
    with pytest.raises(ValueError, match="safety rule"):  # the writer's checks apply
        teach.written_and_read_back([unsafe])


# --- experiments/teaching.py ---------------------------------------------------------------------------------------

def test_success_on_counts_each_tasks_program_success_by_kind(monkeypatch):
    runs = []
    wins = {"pour(a)", "stir(c)"}

    def plan(planner, state, task, max_steps):
        runs.append((planner, state, str(task), max_steps))
        return SimpleNamespace(success=str(task) in wins)

    monkeypatch.setattr(teaching, "plan", plan)
    tasks = [Task("pour", ("a",)), Task("pour", ("b",)), Task("stir", ("c",)), Task("pour", ("d",))]
    out = success_on("P", "w0-env02", "S", iter(tasks), 9)
    assert runs == [("P", "S", str(t), 9) for t in tasks]
    assert out == Outcome("w0-env02", 4, 2, {"pour": (3, 1), "stir": (1, 1)})
    assert out.success == 50.0
    assert success_on("P", "e", "S", [], 9) == Outcome("e", 0, 0, {})


def test_pooled_success_is_over_every_task_together_or_one_kind():
    a = Outcome("a", 3, 2, {"pour": (2, 2), "stir": (1, 0)})
    b = Outcome("b", 1, 0, {"pour": (1, 0)})
    assert pooled([a, b]) == 50.0
    assert pooled([a, b], "pour") == pytest.approx(200 / 3)
    assert pooled([a, b], "stir") == 0.0
    assert math.isnan(pooled([a, b], "throw_away")) and math.isnan(pooled([]))
    assert Outcome("a", 4, 1, {}).success == 25.0 and math.isnan(Outcome("a", 0, 0, {}).success)


def test_fit_trains_the_full_model_with_the_learners_settings(monkeypatch):
    made = []

    class Scorer:
        def __init__(self, method, **kwargs):
            made.append((method, kwargs))

        def fit(self, contexts):
            made.append(contexts)
            return "fitted"

    monkeypatch.setattr(teaching, "StepScorer", Scorer)
    assert teaching.fit(["c1", "c2"], 0.7, LEARNER) == "fitted"
    assert made == [("full", {"C": 0.7, "tol": 1e-3, "max_iter": 7, "n_slacks": LEARNER.n_slacks}), ["c1", "c2"]]


def test_the_teaching_order_is_a_seeded_permutation_taking_one_task_kind_after_another():
    kinds = ["pour", "pour", "stir", "throw_away", "pour", "stir", "throw_away"]
    tasks = [(Task(k, (f"o{i}",)), []) for i, k in enumerate(kinds)]
    perm = list(np.random.default_rng(11).permutation(len(tasks)))
    order = teaching_order(tasks, np.random.default_rng(11))
    # by hand: the permutation's tasks of each kind in its order; the kinds in the order the permutation first
    # meets them; then one of each kind in turn
    by_kind = {}
    for i in perm:
        by_kind.setdefault(kinds[i], []).append(int(i))
    rounds = [[by_kind[k][r] for k in by_kind if r < len(by_kind[k])] for r in range(3)]
    assert order == [i for r in rounds for i in r]
    assert sorted(order) == list(range(7)) and all(type(i) is int for i in order)
    assert [kinds[i] for i in order[:3]] == list(by_kind)  # the first three cover the three kinds
    assert teaching_order(tasks, np.random.default_rng(11)) == order
    assert teaching_order([], np.random.default_rng(0)) == []
