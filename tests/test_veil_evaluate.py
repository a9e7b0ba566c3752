"""The people's-demonstrations evaluation on an invented release: folds, goals, policies, the held-out rule, reports.

The release is the fixture's domain and catalogue with four kitchens of its own objects in shuffled orders and
people's sequences written here: "Tea Beaker" fills a beaker with tea at the tub (a sequence per kitchen and
person, some with a person's wasted step), "Tidy Honey" puts the honey on the tub.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from taskseq.cli import main
from taskseq.veil import evaluate, experiment, ingest
from taskseq.veil.evaluate import (
    Executor,
    derive_goals,
    environment_folds,
    lift,
    people_runs,
    rollout,
    split,
)
from taskseq.veil.experiment import Settings, run_experiment
from taskseq.veil.features import Vocabulary
from taskseq.veil.grounding import Step
from taskseq.veil.methods import DomainScorer
from taskseq.veil.release import read_release
from taskseq.veil.replay import replay_release

FIXTURE = Path(__file__).parent / "fixtures" / "veil" / "release"
ORDERS = {1: ("Teapot_1", "Beaker_1", "Beaker_2", "Honey_1", "Tub", "TubKnob"),
          2: ("Honey_1", "Tub", "Beaker_2", "TubKnob", "Teapot_1", "Beaker_1"),
          3: ("TubKnob", "Beaker_1", "Tub", "Teapot_1", "Honey_1", "Beaker_2"),
          4: ("Beaker_2", "Teapot_1", "TubKnob", "Beaker_1", "Tub", "Honey_1")}
TEA = ["moveto Beaker_1", "grasp Beaker_1", "moveto Tub", "keep Beaker_1 On Tub", "turn TubKnob"]
TIDY = ["moveto Honey_1", "grasp Honey_1", "moveto Tub", "keep Honey_1 On Tub"]


def _point(number: int, objective: str, actions: list[str]) -> str:
    lines = "".join(f"<action>{a}</action>\n" for a in actions)
    return (f"<point>\n<text>invented</text>\n<environment>kitchen_scenario_environment_number_{number}"
            f"</environment>\n<objective>{objective}</objective>\n<action_sequence>\n{lines}</action_sequence>\n"
            "</point>\n")


@pytest.fixture(scope="module")
def release_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("veil") / "release"
    shutil.copytree(FIXTURE, root)
    kitchens = root / "Environments" / "kitchen"
    for f in kitchens.glob("*.xml"):
        f.unlink()
    for number, order in ORDERS.items():
        objects = "".join(f"<object><name>{n}</name><position>({3 * i}, 40, 5)</position>"
                          f"<rotation>(0, 0, 0)</rotation></object>\n" for i, n in enumerate(order))
        (kitchens / f"kitchen{number}.xml").write_text(f"<environment>\n{objects}</environment>\n")
    shutil.rmtree(root / "Environments" / "livingRoom")
    (root / "Environments" / "livingRoom").mkdir()
    points = []
    for number in ORDERS:
        points.append(_point(number, "Tea Beaker", TEA))
        points.append(_point(number, "Tea Beaker", ["moveto Teapot_1"] + TEA))  # a person's wasted step
        points.append(_point(number, "Tidy Honey", TIDY))
    (root / "data.xml").write_text("<root>\n" + "".join(points) + "</root>\n")
    return root


@pytest.fixture(scope="module")
def replays(release_dir: Path):
    release = read_release(release_dir)
    return release, replay_release(release)


def test_folds_hold_out_whole_environment_numbers(replays) -> None:
    _, reps = replays
    folds = environment_folds(reps, 2)
    assert folds == [frozenset({1, 3}), frozenset({2, 4})]
    for held_out in folds:
        train, test = split(reps, held_out)
        assert {evaluate.env_number(r.point.env_id) for r in train}.isdisjoint(held_out)
        assert {evaluate.env_number(r.point.env_id) for r in test} == held_out
    with pytest.raises(ValueError, match="n_folds"):
        environment_folds(reps, 5)


def test_goals_are_the_lifted_facts_the_training_sequences_make_true(replays) -> None:
    _, reps = replays
    goals = derive_goals(reps)
    assert goals["Tea Beaker"] == {("state", "Beaker", "Tea"), ("On", "Beaker", "Tub"), ("state", "TubKnob", "TubRuns")}
    assert goals["Tidy Honey"] == {("On", "Honey", "Tub")}
    people = people_runs(reps, goals)
    assert all(r.goal_share == 1.0 for r in people)
    # the two people of a kitchen's "Tea Beaker" differ by one step of six: each is the other's nearest
    tea = [r for r in people if r.objective == "Tea Beaker"]
    assert {round(r.edit_distance, 6) for r in tea} == {round(1 / 6, 6)}
    assert all(r.edit_distance is None for r in people if r.objective == "Tidy Honey")  # one person each


def test_a_learned_mrf_reaches_the_goal_in_kitchens_it_never_saw_and_feasible_never_takes_a_refused_step(
        replays) -> None:
    release, reps = replays
    train, test = split(reps, frozenset({4}))
    objectives = sorted({r.point.objective for r in reps})
    method = DomainScorer("mrf", Vocabulary.of(release.catalog, objectives, categories=True), C=10.0).fit(train)
    goals = derive_goals(train)
    executor = Executor(release)
    for r in test:
        steps, final, refused, stopped = rollout(method, executor, r.initial, r.point.objective, "feasible", 12)
        assert stopped and refused == 0
        assert goals[r.point.objective] <= lift(final), [str(s) for s in steps]
    # a plain policy takes the first ranked step even when the domain refuses it, and counts it
    class GraspFirst:
        name = "grasp_first"

        def ranked(self, state, history, objective):
            yield Step("grasp", "Tub")
            yield Step("done")

    steps, final, refused, stopped = rollout(GraspFirst(), executor, test[0].initial, "Tea Beaker", "plain", 3)
    assert refused == 3 and not stopped and final == test[0].initial
    _, _, refused, stopped = rollout(GraspFirst(), executor, test[0].initial, "Tea Beaker", "feasible", 3)
    assert refused == 0 and stopped


def test_held_out_environments_never_reach_any_fit_of_their_fold(replays, release_dir: Path, monkeypatch) -> None:
    """A spy on every job (which numbers it holds out), every method's fit (C's inner fits included) and every
    ranking."""
    events: list[tuple[str, object]] = []
    real_make, real_job = experiment.make_method, experiment.fold_job

    class Spy:
        def __init__(self, inner):
            self.inner, self.name = inner, inner.name
            self.predicts_next_step = getattr(inner, "predicts_next_step", True)

        def fit(self, train):
            events.append(("fit", {evaluate.env_number(r.point.env_id) for r in train}))
            self.inner.fit(train)
            return self

        def ranked(self, state, history, objective):
            events.append(("rank", evaluate.env_number(state.world.env_id)))
            return self.inner.ranked(state, history, objective)

    def job(k, held_out, *args):
        events.append(("job", set(held_out)))
        return real_job(k, held_out, *args)

    monkeypatch.setattr(experiment, "make_method", lambda *a, **k: Spy(real_make(*a, **k)))
    monkeypatch.setattr(experiment, "fold_job", job)
    report = run_experiment(release_dir, Settings(folds=2, C_grid=(1.0, 10.0), max_steps=8, resamples=100,
                                                  lookahead_widths=(1, 3)))
    folds = [set(f["held_out"]) for f in report["folds"]]
    held_out, jobs, checked = None, [], 0
    for kind, value in events:
        if kind == "job":
            held_out = value
            jobs.append(value)
        elif kind == "fit":
            assert not value & held_out, f"a job holding out {held_out} trained on {value & held_out}"
        elif value in held_out:
            checked += 1
    groups = experiment.fit_groups(Settings().methods)
    assert sorted(map(sorted, jobs)) == sorted(sorted(f) for f in folds for _ in groups)
    assert checked > 0


def test_the_command_writes_reports_and_gives_the_same_bytes_twice(release_dir: Path, tmp_path: Path) -> None:
    params = tmp_path / "params.yaml"
    params.write_text("veil:\n  folds: 2\n  C_grid: [1.0]\n  max_steps: 8\n  resamples: 100\n"
                      "  methods: [chance, most_frequent, nearest_demonstration, mrf_categories]\n")
    outputs = []
    for name in ("a", "b"):
        out = tmp_path / name
        assert main(["veil", "evaluate", "--release", str(release_dir), "--output", str(out), "--params",
                     str(params), "--quiet", "--recordings-dir", str(tmp_path / f"rec_{name}")]) == 0
        outputs.append(out)
    recordings = sorted((tmp_path / "rec_a").glob("*.rrd"))
    assert [r.name.split("_")[0] for r in recordings] == ["fold0", "fold0", "fold1", "fold1"]  # `recordings: 2`
    assert all(r.read_bytes()[:3] == b"RRF" for r in recordings)
    first = json.loads((outputs[0] / "report.json").read_text())
    assert set(first["next_step"]) == {"chance", "most_frequent", "nearest_demonstration", "mrf_categories"}
    assert "mrf_categories/feasible" in first["closed_loop"] and "people" in first["closed_loop"]
    assert "| ours - full + categories |" in (outputs[0] / "tables.md").read_text()
    # the import's counts, as `taskseq veil import` makes them, with no name of a state; and the figure
    counts = ingest.summarize(read_release(release_dir), replay_release(read_release(release_dir)))
    assert first["noisy_steps"] == ingest.counts_without_names(counts)
    assert f"| kept | {counts['steps_kept']:,} (" in (outputs[0] / "tables.md").read_text()
    assert (outputs[0] / "results.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for f in ("report.json", "tables.md", "results.png"):
        assert (outputs[0] / f).read_bytes() == (outputs[1] / f).read_bytes()
    # the command runs its jobs in parallel (one worker per core); one job at a time gives the same report
    settings = experiment.read_settings(params)
    serial = tmp_path / "serial"
    experiment.write_reports(run_experiment(release_dir, settings, n_jobs=1), serial)
    parallel = tmp_path / "parallel"
    experiment.write_reports(run_experiment(release_dir, settings, n_jobs=2), parallel)
    for f in ("report.json", "tables.md"):
        assert (serial / f).read_bytes() == (parallel / f).read_bytes() == (outputs[0] / f).read_bytes()


def test_bad_settings_are_refused_with_their_name(release_dir: Path, tmp_path: Path, capsys) -> None:
    params = tmp_path / "params.yaml"
    params.write_text("veil:\n  methods: [mrf_attributes, oracle]\n")
    out = tmp_path / "out"
    assert main(["veil", "evaluate", "--release", str(release_dir), "--output", str(out), "--params",
                 str(params)]) == 2
    assert "oracle" in capsys.readouterr().err
    assert not out.exists()
    params.write_text("veil:\n  fold: 3\n")
    assert main(["veil", "evaluate", "--release", str(release_dir), "--output", str(out), "--params",
                 str(params)]) == 2
    assert "fold" in capsys.readouterr().err and not out.exists()


@pytest.fixture(scope="module")
def other_dir(release_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A second folder of the same format: two kitchens the release does not have, with their own people."""
    root = tmp_path_factory.mktemp("veil_other") / "release"
    shutil.copytree(release_dir, root)
    kitchens = root / "Environments" / "kitchen"
    for f in kitchens.glob("*.xml"):
        f.unlink()
    points = []
    for number, order in ((5, ORDERS[2][::-1]), (6, ORDERS[3][::-1])):
        objects = "".join(f"<object><name>{n}</name><position>({2 * i}, 41, 6)</position>"
                          f"<rotation>(0, 0, 0)</rotation></object>\n" for i, n in enumerate(order))
        (kitchens / f"kitchen{number}.xml").write_text(f"<environment>\n{objects}</environment>\n")
        points += [_point(number, "Tea Beaker", TEA), _point(number, "Tidy Honey", TIDY)]
    (root / "data.xml").write_text("<root>\n" + "".join(points) + "</root>\n")
    return root


def test_a_trained_model_is_evaluated_on_another_folder_with_the_same_metrics_and_plans_there(
        release_dir: Path, other_dir: Path, tmp_path: Path, capsys) -> None:
    params = tmp_path / "params.yaml"
    params.write_text("veil:\n  folds: 2\n  C_grid: [1.0, 10.0]\n  max_steps: 10\n  resamples: 100\n"
                      "  lookahead_widths: [1, 3]\n")
    model = tmp_path / "model.npz"
    assert main(["--no-mlflow", "veil", "train", "--release", str(release_dir), "--output", str(model),
                 "--params", str(params)]) == 0
    out = tmp_path / "other"
    assert main(["--no-mlflow", "veil", "evaluate", "--model", str(model), "--release", str(other_dir),
                 "--output", str(out), "--params", str(params), "--quiet"]) == 0
    report = json.loads((out / "report.json").read_text())
    (name,) = report["next_step"]
    assert name in experiment.MRF_ROWS and report["model"]["name"] == name
    assert set(report["next_step"][name]) == {"verb", "args", "both"}
    assert {f"{name}/plain", f"{name}/feasible", f"{name}/lookahead", "people"} <= set(report["closed_loop"])
    assert report["folds"][0]["held_out"] == [5, 6]
    assert report["closed_loop"][f"{name}/feasible"]["goal_share"]["mean"] == 1.0
    assert report["closed_loop"][f"{name}/lookahead"]["goal_share"]["mean"] == 1.0
    assert report["model"]["lookahead_width"] in (1, 3)  # chosen on the release's inner split, saved with it
    capsys.readouterr()
    env = other_dir / "Environments" / "kitchen" / "kitchen6.xml"
    assert main(["veil", "plan", "--model", str(model), "--environment", str(env), "--objective", "Tidy Honey"]) == 0
    printed = capsys.readouterr().out
    assert "keep_on(Honey_1, Tub)" in printed and "goal reached 100%" in printed
    assert main(["plan", "--model", str(model), "--env", str(env), "--task", "Tidy Honey"]) == 0
    assert capsys.readouterr().out == printed  # `taskseq plan` given a release's environment file: the same plan
    assert main(["veil", "plan", "--model", str(model), "--environment", str(env), "--objective", "Tidy Honey",
                 "--policy", "feasible"]) == 0
    assert "keep_on(Honey_1, Tub)" in capsys.readouterr().out
    assert main(["veil", "plan", "--model", str(model), "--environment", str(env), "--objective", "Bake"]) == 2
    assert "Bake" in capsys.readouterr().err
    assert main(["veil", "plan", "--model", str(tmp_path / "none.npz"), "--environment", str(env),
                 "--objective", "Tidy Honey"]) == 2
