"""The teach stage's split of taught and held-out data, with spies in place of the learner and the planner: the
training steps are the benchmark's outside the held-out environments plus exactly the first k demonstrations of
each, written and read back as a person's; the planner is judged on the same other tasks for every k, never on a
task it was taught; the tables, the figure and the tracked metrics carry the outcomes the spies gave, by hand.
Then `experiments/teaching.py` on hand-made tasks, outcomes and programs."""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from taskseq.experiments import teaching
from taskseq.experiments.teaching import Outcome, pooled, success_on, teaching_order
from taskseq.serve.environments import world_environment
from taskseq.settings import Learner, Params, Teach, World
from taskseq.sim.demonstrator import demonstrate
from taskseq.sim.primitives import Action
from taskseq.sim.scenarios import doable_tasks
from taskseq.sim.tasks import TASKS, Task
from taskseq.stages import teach
from taskseq.stages.options import TeachOptions

ENVS = ("env12", "env13")
KS = (0, 1, 2)
SEEDS = (0, 1)
LEARNER = Learner(tol=1e-3, max_iter=7)
FULL_C = 2.5  # the full model's C in the selection file the spied stage reads


def bench(seed: int) -> list[dict]:
    """Hand-made benchmark records (the spied `build_steps` reads only what the tags below name)."""
    return [{"env_id": env, "demo_id": f"{seed}/{env}/{i}", "task": {"name": "stir", "args": [f"obj{i}"]},
             "steps": []} for i, env in enumerate(("env01", "env12", "env02", "env13", "env11", "env12"))]


def tag(record: dict) -> tuple:
    """What a training step is made from: the record's environment, demo, task, participant and actions."""
    return (record["env_id"], record["demo_id"] if "participant" not in record else None,
            (record["task"]["name"], *record["task"]["args"]), record.get("participant"),
            tuple((s["primitive"], *s["args"]) for s in record["steps"]))


def outcome(seed: int, k: int, env_id: str) -> Outcome:
    """The spied planner's results, chosen by hand: env12 has 2 pours and 1 stir held out, env13 1 pour."""
    if env_id.endswith("env12"):
        by_kind = {"pour": (2, min(k, 2) if seed == 0 else 1), "stir": (1, int(k >= 1))}
    else:
        by_kind = {"pour": (1, 1)}
    return Outcome(env_id, sum(n for n, _ in by_kind.values()), sum(s for _, s in by_kind.values()), by_kind)


@pytest.fixture
def spied(tmp_path, monkeypatch, capsys):
    calls = SimpleNamespace(loaded=[], fits=[], judged=[], orders=[], plots=[], metrics=[])

    def load_benchmark(processed):
        calls.loaded.append(Path(processed))
        return SimpleNamespace(records=bench(int(Path(processed).parent.name)))

    def fit(contexts, C, learner):
        calls.fits.append((list(contexts), C, learner))
        return f"planner {len(calls.fits)}"

    def success_on_spy(planner, env_id, state, tasks, max_steps):
        calls.judged.append((planner, env_id, state, list(tasks), max_steps))
        n = len(calls.fits) - 1  # the planner last fit: world n // len(KS), k n % len(KS)
        return outcome(SEEDS[n // len(KS)], KS[n % len(KS)], env_id)

    def order_spy(tasks, rng):
        state = rng.bit_generator.state
        order = teaching_order(tasks, rng)
        calls.orders.append((list(tasks), state, order))
        return order

    monkeypatch.setattr(teach, "load_benchmark", load_benchmark)
    monkeypatch.setattr(teach, "build_steps", lambda records: ([tag(r) for r in records], None))
    monkeypatch.setattr(teach, "fit", fit)
    monkeypatch.setattr(teach, "success_on", success_on_spy)
    monkeypatch.setattr(teach, "teaching_order", order_spy)
    monkeypatch.setattr(teach, "line_plot_png", lambda *a, **kw: calls.plots.append((a, kw)))
    tracker = SimpleNamespace(metrics=lambda values: calls.metrics.append(values))
    settings = teach.Settings(World(seeds=SEEDS), Teach(environments=ENVS, k=KS, seed=5), LEARNER, 17)
    selection = tmp_path / "selection.json"
    selection.write_text(json.dumps({"settings": {"full": {"C": FULL_C}, "relations": {"C": 0.1}}}))
    calls.table = teach.run(settings, TeachOptions(worlds=tmp_path / "worlds", output=tmp_path / "out",
                                                 selection=selection), tracker)
    calls.out = tmp_path / "out"
    calls.worlds = tmp_path / "worlds"
    calls.printed = capsys.readouterr().out
    return calls


def test_each_world_is_read_from_its_own_processed_tables(spied):
    assert spied.loaded == [spied.worlds / "0" / "processed", spied.worlds / "1" / "processed"]


def test_the_tasks_of_each_environment_are_ordered_by_one_generator_seeded_by_teach_seed_and_world(spied):
    assert len(spied.orders) == len(SEEDS) * len(ENVS)
    for s, seed in enumerate(SEEDS):
        rng = np.random.default_rng([5, seed])
        for e, env in enumerate(ENVS):
            tasks, state, order = spied.orders[s * len(ENVS) + e]
            assert [t for t, _ in tasks] == [t for t, _ in doable_tasks(world_environment(seed, env).state)]
            assert state == rng.bit_generator.state  # env13's order follows env12's draws
            rng.permutation(len(tasks))
            assert sorted(order) == list(range(len(tasks)))


def test_training_is_the_benchmark_outside_the_held_out_environments_plus_the_first_k_taught_tasks(spied):
    assert len(spied.fits) == len(SEEDS) * len(KS)
    for s, seed in enumerate(SEEDS):
        base = [tag(r) for r in bench(seed) if r["env_id"] not in ENVS]
        assert [b[0] for b in base] == ["env01", "env02", "env11"]
        for i, k in enumerate(KS):
            contexts, C, learner = spied.fits[s * len(KS) + i]
            assert C == FULL_C and learner == LEARNER  # the full model's C, not another method's
            people = []
            for e, env in enumerate(ENVS):
                tasks, _, order = spied.orders[s * len(ENVS) + e]
                for task, actions in [tasks[j] for j in order[:k]]:
                    people.append((f"w{seed}-{env}", None, (task.name, *task.args), "scripted",
                                   tuple((a.primitive, *a.args) for a in actions)))
            assert contexts == base + people
            assert len(people) == k * len(ENVS)


def test_the_planner_is_judged_on_the_same_other_tasks_for_every_k_and_never_on_a_taught_one(spied):
    assert len(spied.judged) == len(SEEDS) * len(KS) * len(ENVS)
    for s, seed in enumerate(SEEDS):
        for e, env in enumerate(ENVS):
            tasks, _, order = spied.orders[s * len(ENVS) + e]
            taught = [tasks[j][0] for j in order[: max(KS)]]
            expected = [tasks[j][0] for j in order[max(KS):]]
            assert sorted(map(str, taught + expected)) == sorted(str(t) for t, _ in tasks)  # every doable task
            state = world_environment(seed, env).state
            for i, _ in enumerate(KS):
                planner, env_id, judged_state, judged, max_steps = spied.judged[(s * len(KS) + i) * len(ENVS) + e]
                assert planner == f"planner {s * len(KS) + i + 1}"  # the one trained for this world and k
                assert env_id == f"w{seed}-{env}" and max_steps == 17
                assert judged == expected and not set(map(str, judged)) & set(map(str, taught))
                assert judged_state.poses == state.poses and judged_state.support == state.support


def test_the_tables_carry_the_outcomes_per_world_and_their_mean_and_sd_over_worlds(spied):
    rows = list(csv.DictReader(io.StringIO((spied.out / "teach_seeds.csv").read_text())))
    assert list(rows[0]) == ["world_seed", "k", "held_out_tasks", "successes", "success",
                             *[f"success_{t}" for t in TASKS]]
    got = [(r["world_seed"], r["k"], r["held_out_tasks"], r["successes"], r["success"], r["success_pour"],
            r["success_stir"], r["success_throw_away"]) for r in rows]
    assert got == [("0", "0", "4", "1", "25.00", "33.33", "0.00", "nan"),
                   ("0", "1", "4", "3", "75.00", "66.67", "100.00", "nan"),
                   ("0", "2", "4", "4", "100.00", "100.00", "100.00", "nan"),
                   ("1", "0", "4", "2", "50.00", "66.67", "0.00", "nan"),
                   ("1", "1", "4", "3", "75.00", "66.67", "100.00", "nan"),
                   ("1", "2", "4", "3", "75.00", "66.67", "100.00", "nan")]
    table = list(csv.DictReader(io.StringIO((spied.out / "teach.csv").read_text())))
    assert list(table[0]) == ["k", "success_mean", *[f"success_{t}_mean" for t in TASKS], "success_sd", "n_seeds"]
    assert [(r["k"], r["success_mean"], r["success_pour_mean"], r["success_stir_mean"], r["success_pour_to_mean"],
             r["success_sd"], r["n_seeds"]) for r in table] == [
        ("0", "37.50", "50.00", "0.00", "nan", "17.68", "2"),
        ("1", "75.00", "66.67", "100.00", "nan", "0.00", "2"),
        ("2", "87.50", "83.33", "100.00", "nan", "17.68", "2")]
    assert [r["k"] for r in spied.table] == list(KS)
    assert spied.table[0]["success_mean"] == 37.5 and spied.table[0]["success_sd"] == pytest.approx(12.5 * 2**0.5)
    assert spied.table[2]["success_pour_mean"] == pytest.approx(250 / 3) and spied.table[1]["n_seeds"] == 2
    assert spied.metrics == [{"success_k0": 37.5}, {"success_k1": 75.0}, {"success_k2": 87.5}]
    out = spied.printed
    assert "world 0, k = 0: 1/4 held-out tasks succeed (25.0%)\n" in out
    assert "world 1, k = 2: 3/4 held-out tasks succeed (75.0%)\n" in out


def test_the_page_and_the_figure_say_what_was_measured(spied):
    cells = {"pour": ["50.0", "66.7", "83.3"], "stir": ["0.0", "100.0", "100.0"]}
    rows = [f"| {k} | {m} | " + " | ".join(cells.get(t, ["nan"] * 3)[i] for t in TASKS) + " | 2 |"
            for i, (k, m) in enumerate(zip(KS, ["37.5 ± 17.7", "75.0 ± 0.0", "87.5 ± 17.7"], strict=True))]
    assert (spied.out / "teach.md").read_text() == "\n".join([
        "# Teaching unseen environments", "",
        "Environments env12, env13, held out of the training data; a scripted person demonstrates k tasks in each; "
        "success of the full model on the other tasks there (mean ± sd over world seeds).", "",
        "| k | success (%) | stir | pick_and_place | pour | pour_to | throw_away | world seeds |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|", *rows, "",
        "Task kinds: mean over world seeds of the success on the held-out tasks of that kind.", ""])
    [(args, kwargs)] = spied.plots
    series, path, title, xlabel, ylabel = args
    assert list(series) == ["full model"]
    xs, ys, sds = series["full model"]
    assert xs == [0, 1, 2] and ys == [37.5, 75.0, 87.5] and sds == pytest.approx([12.5 * 2**0.5, 0.0, 12.5 * 2**0.5])
    assert path == str(spied.out / "teach.png")
    assert title == "unseen environments env12, env13: mean ± sd over worlds 0, 1"
    assert (xlabel, ylabel) == ("tasks demonstrated per environment (k)", "success on the other tasks (%)")
    assert kwargs == {"xticks": [0, 1, 2], "xticklabels": ["0", "1", "2"]}


def test_one_world_has_an_sd_of_zero(tmp_path, monkeypatch):
    monkeypatch.setattr(teach, "load_benchmark", lambda processed: SimpleNamespace(records=bench(0)))
    monkeypatch.setattr(teach, "build_steps", lambda records: ([tag(r) for r in records], None))
    monkeypatch.setattr(teach, "fit", lambda contexts, C, learner: "planner")
    monkeypatch.setattr(teach, "success_on", lambda planner, env_id, state, tasks, max_steps: outcome(0, 2, env_id))
    monkeypatch.setattr(teach, "line_plot_png", lambda *a, **kw: None)
    settings = teach.Settings(World(seeds=(3,)), Teach(environments=("env13",), k=(1,), seed=0), LEARNER, 20)
    [row] = teach.run(settings, TeachOptions(worlds=tmp_path, output=tmp_path / "out"))
    assert row["success_sd"] == 0.0 and row["n_seeds"] == 1 and row["success_mean"] == 100.0


@pytest.mark.parametrize("envs, unknown", [(("env00",), "['env00']"), (("env14", "env13", "env1"),
                                                                           "['env1', 'env14']")])
def test_an_environment_outside_env01_to_env13_is_refused_before_anything_is_read(tmp_path, envs, unknown):
    settings = teach.Settings(World(seeds=(0,)), Teach(environments=envs), LEARNER, 20)
    with pytest.raises(ValueError, match=rf"^teach.environments: unknown environments {re.escape(unknown)}$"):
        teach.run(settings, TeachOptions(worlds=tmp_path / "none", output=tmp_path / "out"))
    assert not (tmp_path / "out").exists()


def test_the_first_and_last_environments_are_known(tmp_path, monkeypatch):
    seen = []
    monkeypatch.setattr(teach, "load_benchmark", lambda processed: seen.append(processed) or
                        SimpleNamespace(records=[]))
    monkeypatch.setattr(teach, "build_steps", lambda records: ([], None))
    monkeypatch.setattr(teach, "fit", lambda contexts, C, learner: "planner")
    monkeypatch.setattr(teach, "success_on", lambda planner, env_id, state, tasks, max_steps: outcome(0, 0, env_id))
    monkeypatch.setattr(teach, "line_plot_png", lambda *a, **kw: None)
    settings = teach.Settings(World(seeds=(0,)), Teach(environments=("env01", "env13"), k=(0,)), LEARNER, 20)
    teach.run(settings, TeachOptions(worlds=tmp_path, output=tmp_path / "out"))
    assert len(seen) == 1


def test_the_settings_come_from_train_teach_world_and_the_closed_loop_step_cap():
    base = Params()
    params = dataclasses.replace(base, train=dataclasses.replace(base.train, tol=0.004, max_iter=11, n_slacks=3),
                                 world=World(seeds=(4, 9)), teach=Teach(environments=("env02",), k=(0, 5)),
                                 crossval=dataclasses.replace(base.crossval, max_steps=13))
    s = teach.settings(params)
    assert s.world == World(seeds=(4, 9)) and s.teach == Teach(environments=("env02",), k=(0, 5))
    assert s.max_steps == 13
    assert s.learner == Learner(tol=0.004, max_iter=11, n_slacks=3)


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
