"""reports/summary.md puts each of our results (mean ± sd over world seeds) next to the paper's figure."""

import json

import pytest

from taskseq.methods import method_labels
from taskseq.report.summary import build_summary


def test_summary_sets_our_numbers_beside_the_papers(tmp_path):
    (tmp_path / "dataset.json").write_text(json.dumps({"0": {"steps": 759}, "3": {"steps": 741}}))
    (tmp_path / "selection.json").write_text(json.dumps({"dev_seed": 100, "criterion": "sequence_arg", "settings": {
        "full": {"C": 3.0, "candidates": [{"C": 3.0, "sequence_arg": 61.1}]}}}))
    (tmp_path / "crossval_means.json").write_text(json.dumps({
        "full": {"average_prim": 96.8, "average_prim_sd": 0.4, "average_arg": 88.4, "average_arg_sd": 1.0,
                 "sequence_prim": 69.9, "sequence_prim_sd": 2.0, "sequence_arg": 56.6, "sequence_arg_sd": 7.5,
                 "success": 77.0, "success_sd": 3.0},
        "multiclass": {"average_prim": 95.0, "average_prim_sd": 0.5},
    }))
    (tmp_path / "failures.csv").write_text("world_seed,method,task,kind,programs\n0,full,all,exact,6\n"
                                           "0,full,all,wrong_object,3\n0,full,all,step_cap,1\n")
    header = "method,rate,sequence_arg,sequence_arg_sd,sequence_prim,sequence_prim_sd,success,success_sd\n"
    (tmp_path / "noise.csv").write_text(header + "full,0.1,42.8,3.0,59,1,59,1\nrelations,0.1,50.0,2.0,59,1,59,1\n")
    fb = "method,k,n,sequence_arg,sequence_arg_sd,sequence_prim,sequence_prim_sd,success,success_sd\n"
    (tmp_path / "feedback.csv").write_text(fb + "full,2,1,62.8,1.0,75,1,78,1\nfull,3,all,85.8,2.0,87,1,91,1\n")
    (tmp_path / "recipes.json").write_text(json.dumps({"methods": {"full": {"recipes": 12, "per_seed": {
        "0": {"no_feedback": 1, "feedback_first_step": 2}, "3": {"no_feedback": 4, "feedback_first_step": 5}}}}}))
    text = build_summary(tmp_path, method_labels())
    assert "| steps | 736 | 759 | 741 |" in text
    assert "Each MRF method's C, chosen by 6-fold cross-validation on the development world (seed 100" in text
    assert "(sequence arg per C tried: ours - full C = 3 (3: 61.1))" in text
    assert ("| ours - full | 96.8 ± 0.4 | 96.7 | 88.4 ± 1.0 | 90.0 | 69.9 ± 2.0 | 91.6 | 56.6 ± 7.5 | 69.7 | "
            "77.0 ± 3.0 |") in text
    assert "| multiclass | 95.0 ± 0.5 | 78.4 | - | - |" in text
    assert "wrong object 30.0%; step cap 10.0%" in text and "Exact matches 60.0%" in text
    assert "| ours - full | 0.1 | 42.8 ± 3.0 | 55.8 |" in text and "| ours + relations | 0.1 | 50.0 ± 2.0 |" in text
    assert "| ours - full | 2 | 1 | 62.8 ± 1.0 | 74.1 |" in text
    assert "| ours - full | 3 | all | 85.8 ± 2.0 | 81.4 |" in text
    assert "| ours - full | none | 1/12, 4/12 | 9/12 |" in text


def test_summary_skips_what_was_not_run(tmp_path):
    text = build_summary(tmp_path, method_labels())
    assert text.startswith("# Results\n\nEvery number below comes from `dvc repro`")
    assert "## " not in text  # no section for a stage whose results are missing
    (tmp_path / "recipes.json").write_text(json.dumps({"methods": {"full": {"recipes": 12, "per_seed": {
        "0": {"no_feedback": 1, "feedback_first_step": 2}}}}}))
    text = build_summary(tmp_path, method_labels())
    assert [line for line in text.splitlines() if line.startswith("## ")] == [
        "## Recipes (environments held out from training; successes per world seed)"]


def test_summary_gives_each_methods_own_c(tmp_path):
    row = {"sequence_arg": 61.1, "success": 80.0, "average_arg": 86.0}
    (tmp_path / "selection.json").write_text(json.dumps({
        "dev_seed": 100, "criterion": "sequence_arg", "method": "relations",
        "settings": {"full": {"C": 10.0, "candidates": [{"C": 3.0, **row, "sequence_arg": 60.2}, {"C": 10.0, **row}]},
                     "relations": {"C": 3.0, "candidates": [{"C": 3.0, **row, "sequence_arg": 82.3}]}},
        "methods": [{"method": "relations", "C": 3.0, **row, "sequence_arg": 82.3},
                    {"method": "full", "C": 10.0, **row}]}))
    text = build_summary(tmp_path, method_labels())
    assert ("(sequence arg per C tried: ours - full C = 10 (3: 60.2, 10: 61.1); ours + relations C = 3 (3: 82.3))"
            in text)
    assert "(ours + relations 82.3, ours - full 61.1); the shipped planner" in text and text.count("## Settings") == 1


def test_the_transfer_column_shows_what_transfer_md_shows(tmp_path):
    """From the unrounded means: the CSV's two decimals (2.25) would give 2.2 where the table shows 2.3."""
    from taskseq.stages.scenes import transfer_markdown

    row = {"method": "dagger", "sequence_arg": 65.2933, "sequence_arg_sd": 2.2549, "sequence_prim": 74.48,
           "sequence_prim_sd": 1.43, "success": 80.1249, "success_sd": 2.75, "goal_reached": 86.62,
           "goal_reached_sd": 4.59}
    (tmp_path / "scenes" / "paper").mkdir(parents=True)
    (tmp_path / "scenes" / "paper" / "crossval_means.json").write_text(json.dumps(
        {"dagger": {"sequence_arg": 80.5, "sequence_arg_sd": 4.7, "success": 93.5}}))
    (tmp_path / "scenes" / "transfer.json").write_text(json.dumps({"dagger": row}))
    text = build_summary(tmp_path, method_labels())
    line = next(line for line in text.splitlines() if line.startswith("| ours + relations + dagger |"))
    assert line.endswith("| 80.5 ± 4.7 (93.5) | - | 65.3 ± 2.3 (80.1) |")
    assert "| 65.3 ± 2.3 | 74.5 ± 1.4 | 80.1 ± 2.8 |" in transfer_markdown([row], 3)


def test_a_selection_file_without_each_methods_c_is_refused_with_its_name(tmp_path):
    (tmp_path / "selection.json").write_text(json.dumps({"C": 3.0, "dev_seed": 100, "criterion": "sequence_arg",
                                                         "candidates": [{"C": 3.0, "sequence_arg": 61.1}]}))
    with pytest.raises(ValueError, match=r"selection\.json: no `settings`.*run `taskseq select` again"):
        build_summary(tmp_path, method_labels())
