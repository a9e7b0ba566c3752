"""scripts/teach_adapt.py: a room correction is one weight vector shared by every task, fitted with the planner's
scores as an offset."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from taskseq.learn.estimator import StepScorer
from taskseq.learn.mrf import StepMRF
from taskseq.sim.tasks import TASKS

ROOT = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("teach_adapt", ROOT / "scripts" / "teach_adapt.py")
teach_adapt = importlib.util.module_from_spec(spec)
spec.loader.exec_module(teach_adapt)


def test_the_correction_adds_the_same_weight_to_every_tasks_copy_and_nothing_elsewhere():
    mrf = StepMRF("choice")
    T = teach_adapt.sharing(mrf).tocsc()
    names = np.array(mrf.feature_names())
    families = mrf.family_of()
    moved = np.asarray(T.sum(axis=1)).ravel()
    assert set(np.unique(moved)) == {0.0, 1.0}  # a weight takes one entry of d, or none
    assert set(families[moved > 0]) == {"relations", "cues", "primitive_argument_environment"}
    assert not any(n.startswith("relations_pair") for n in names[moved > 0])
    copies_per_family = {"relations": len(TASKS), "cues": len(TASKS), "primitive_argument_environment": 1}
    for column in range(T.shape[1]):
        rows = T.indices[T.indptr[column]:T.indptr[column + 1]]
        family = set(families[rows])
        assert len(family) == 1, column  # one entry of d is one weight of one family ...
        assert len(rows) == copies_per_family[family.pop()], column  # ... in every task's copy, or once if shared
        # the copies are the same weight in each task: the block and labels but the task's are the same
        labels = {n.split("[")[0] + "[" + ",".join(n.split("[")[1].split(",")[1:]) for n in names[rows]}
        tasks = {n.split("[")[1].split(",")[0] for n in names[rows]}
        assert len(labels) == 1 and (len(rows) == 1 or tasks == set(TASKS)), names[rows]


@pytest.fixture(scope="module")
def planner_and_lesson(benchmark_steps):
    """A choice planner fitted on part of world 0 and a 'room' of steps it does not all get right."""
    contexts = benchmark_steps[0]
    planner = StepScorer("choice", C=0.3).fit(contexts[:300])
    rest = contexts[300:]
    wrong = [x for x, y in zip(rest, planner.predict(rest), strict=True) if tuple(y) != tuple(x.gold)]
    right = [x for x, y in zip(rest, planner.predict(rest), strict=True) if tuple(y) == tuple(x.gold)]
    assert len(wrong) >= 5
    return planner, wrong[:10] + right[:20]


def test_a_correction_fits_the_rooms_steps_and_stays_near_the_planner_at_a_small_C(planner_and_lesson):
    planner, lesson = planner_and_lesson
    gold = [tuple(x.gold) for x in lesson]
    right_before = sum(tuple(y) == g for y, g in zip(planner.predict(lesson), gold, strict=True))
    strong = teach_adapt.corrected(planner, lesson, C=100.0)
    right_after = sum(tuple(y) == g for y, g in zip(strong.predict(lesson), gold, strict=True))
    assert right_after > right_before
    weak = teach_adapt.corrected(planner, lesson, C=1e-4)
    assert np.linalg.norm(weak.w_ - planner.w_) < 1e-2 * np.linalg.norm(strong.w_ - planner.w_)
    # only the shared families moved
    families = planner.model_.family_of()
    changed = set(families[strong.w_ != planner.w_])
    assert changed and changed <= {"relations", "cues", "primitive_argument_environment"}


def test_the_learners_objective_is_the_corrections_own_with_the_planners_scores_as_offset(planner_and_lesson):
    """0.5 ||d||^2 + C sum_i max_y [loss(y_i, y) + s(y) - s(y_i)], s the scores of w0 + T d, computed candidate by
    candidate: the learner's primal at its weights, so the margin it enforces is the corrected planner's."""
    planner, lesson = planner_and_lesson
    C = 3.0
    model, ssvm = teach_adapt.fit_correction(planner, lesson, C)
    w = model.weights(ssvm.w_)
    slack = 0.0
    for x in lesson:
        (cp, ca1, ca2), s = planner.model_.scores(x, w)
        p, a1, a2 = x.gold
        loss = (cp != p).astype(float) + (ca1 != a1) + (ca2 != a2)
        gold = s[(cp == p) & (ca1 == a1) & (ca2 == a2)][0]
        slack += float(np.max(loss + s) - gold)
    primal = 0.5 * float(ssvm.w_ @ ssvm.w_) + C * slack
    assert primal == pytest.approx(ssvm.primal_objective_, rel=1e-9, abs=1e-9)
    assert slack > 0  # the lesson is not separable at this C: the offset matters to the sum


def test_the_script_runs_the_teach_protocol_on_a_development_draw(tmp_path):
    """One development draw, one C: the rows without a correction are the teach protocol's own (the misses
    `scripts/teach_weight.py` recorded for that draw at the weight params.yaml uses), every row is the committed
    report's for that draw, and the correction changes the untaught planner's programs there."""
    out = tmp_path / "adapt.json"
    assert teach_adapt.main(["--Cs", "1", "--dev-seeds", "100", "--output", str(out)]) == 0
    report = json.loads(out.read_text())
    rows = {(r["refit_k"], r["C"]): r for r in report["rows"]}
    assert set(rows) == {(0, 0.0), (0, 1.0), (3, 0.0), (3, 1.0)} and report["dev_seeds"] == [100]
    assert len({r["programs"] for r in rows.values()}) == 1  # every row judges the same tasks
    recorded = json.loads((ROOT / "reports" / "teach_weight.json").read_text())
    assert report["weight"] == recorded["chosen"]
    at_weight = next(r for r in recorded["ranked"] if r["weight"] == recorded["chosen"])
    assert [rows[(0, 0.0)]["misses"], rows[(3, 0.0)]["misses"]] == at_weight["misses"]["100"]
    # and the committed report's column for that draw, corrections included, comes out again
    committed = {(r["refit_k"], r["C"]): r["misses_by_world"]["100"]
                 for r in json.loads((ROOT / "reports" / "teach_adapt.json").read_text())["rows"]}
    assert {key: r["misses"] for key, r in rows.items()} == {key: committed[key] for key in rows}
    assert rows[(0, 1.0)]["misses"] != rows[(0, 0.0)]["misses"]


def test_a_reported_world_is_refused(capsys):
    with pytest.raises(SystemExit):
        teach_adapt.main(["--dev-seeds", "0"])
    assert "is a reported world seed" in capsys.readouterr().err
