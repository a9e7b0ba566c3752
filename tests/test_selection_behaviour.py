"""Choosing C: every grid value is cross-validated with its own C, the figures of each candidate are its own, and the
documented rule picks among them; the selection file is read back with errors that name what is wrong."""

from __future__ import annotations

import json

import pytest

from pipeline.evaluate import selection
from pipeline.evaluate.crossval import FoldResult, SequenceOutcome
from pipeline.evaluate.selection import read_selection, select_C
from pipeline.features.context import StepContext
from pipeline.settings import Folds, Learner
from pipeline.sim.primitives import ALL_PRIMITIVES

GRASP = ALL_PRIMITIVES.index("grasp")
# per C: sequences right (of 4), successes (of 4), steps with the right arguments (of 2)
FIGURES = {0.5: (2, 4, 1), 2.0: (3, 1, 2), 8.0: (3, 2, 0)}


def _ctx(gold):
    import numpy as np

    return StepContext(["a", "b"], np.zeros((2, 1)), np.zeros((2, 4)), np.zeros((2, 2), dtype=bool), 0, (0, 0),
                       (-1, -1, -1, -1), gold)


def _fake_cross_validate(calls):
    def cross_validate(methods, contexts, meta, bench, n_folds, seed, group_by, max_steps, n_jobs, verbose):
        calls.append({"data": (contexts, meta, bench), "n_folds": n_folds, "seed": seed, "group_by": group_by,
                      "max_steps": max_steps, "workers": (n_jobs, verbose)})
        out = []
        for name, make in methods.items():
            method = make()
            assert method.name == name and method.features == "full"
            right, successes, args = FIGURES[method.C]
            calls.append((name, method.C, method.tol, method.max_iter))
            seqs = [SequenceOutcome(f"s{i}", "pour", (), "done", True, i < right, i < successes, True, i < successes,
                                    "exact") for i in range(4)]
            preds = [(GRASP, 0, -1) if i < args else (GRASP, 1, -1) for i in range(2)]
            out.append(FoldResult(name, 0, [0, 1], preds, seqs))
        return out

    return cross_validate


def test_select_c_cross_validates_each_c_and_applies_the_rule(monkeypatch):
    calls = []
    monkeypatch.setattr(selection, "cross_validate", _fake_cross_validate(calls))
    contexts, meta, bench = [_ctx((GRASP, 0, -1)), _ctx((GRASP, 0, -1))], ["m0", "m1"], "the benchmark"
    result = select_C((0.5, 2.0, 8.0), Learner(C=99.0, tol=0.02, max_iter=7), Folds(folds=3, seed=4),
                      contexts, meta, bench, max_steps=9, n_jobs=3, verbose=2)
    assert calls[0] == {"data": (contexts, meta, bench), "n_folds": 3, "seed": 4, "group_by": Folds().group_by,
                        "max_steps": 9, "workers": (3, 2)}
    assert calls[1:] == [("C=0.5", 0.5, 0.02, 7), ("C=2", 2.0, 0.02, 7), ("C=8", 8.0, 0.02, 7)]
    assert result["candidates"] == [
        {"C": 0.5, "sequence_arg": 50.0, "success": 100.0, "average_arg": 50.0},
        {"C": 2.0, "sequence_arg": 75.0, "success": 25.0, "average_arg": 100.0},
        {"C": 8.0, "sequence_arg": 75.0, "success": 50.0, "average_arg": 0.0},
    ]
    assert result["C"] == 8.0  # a tie in sequence accuracy, broken by success
    assert result["criterion"] == "sequence_arg, then success, then the smaller C"


def test_an_empty_grid_is_refused():
    with pytest.raises(ValueError, match="^select: the grid of C values is empty$"):
        select_C((), Learner(), Folds(), [], [], None, 20)


def test_read_selection_returns_c(tmp_path):
    path = tmp_path / "selection.json"
    path.write_text(json.dumps({"C": 2, "candidates": []}))
    assert read_selection(path) == 2.0 and isinstance(read_selection(path), float)
    path.write_text(json.dumps({"C": 0.25}))
    assert read_selection(path) == 0.25  # below 1 is a valid slack weight


@pytest.mark.parametrize("text, message", [
    ("{not json", "not valid JSON"),
    (json.dumps({"C": 0}), "field 'C' must be a positive number, got 0"),
    (json.dumps({"C": -1.5}), "got -1.5"),
    (json.dumps({"C": True}), "got True"),
    (json.dumps({"C": "2"}), "got '2'"),
    (json.dumps({"c": 2}), "got None"),
    (json.dumps([2.0]), "got None"),
])
def test_read_selection_names_the_file_and_what_is_wrong(tmp_path, text, message):
    path = tmp_path / "selection.json"
    path.write_text(text)
    with pytest.raises(ValueError, match=f"{path}: .*{message}"):
        read_selection(path)


def test_a_missing_selection_file_says_how_to_make_it(tmp_path):
    with pytest.raises(FileNotFoundError, match="no selection file; run `taskseq select`"):
        read_selection(tmp_path / "none.json")
