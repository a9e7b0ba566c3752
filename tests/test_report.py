"""reports/summary.md puts each of our results next to the paper's figure."""

import json

from pipeline.evaluate.methods import METHOD_LABELS
from pipeline.report.summary import build_summary


def test_summary_sets_our_numbers_beside_the_papers(tmp_path):
    (tmp_path / "dataset.json").write_text(json.dumps({"environments": 13, "objects": 43, "tasks": 5,
                                                       "scenarios": 113, "sequences": 127, "steps": 759}))
    (tmp_path / "crossval.json").write_text(json.dumps({
        "full": {"steps": {"average/prim": 96.8, "average/arg": 88.4}, "sequence/prim": 69.9,
                 "sequence/arg": 56.6, "success": 77.0},
        "multiclass": {"steps": {"average/prim": 95.0, "average/arg": None}},
    }))
    header = "rate,sequence_arg,sequence_arg_std,sequence_prim,success\n"
    (tmp_path / "noise.csv").write_text(header + "0.1,42.8,3.0,59,59\n")
    (tmp_path / "feedback.csv").write_text("k,n,sequence_arg,sequence_prim,success\n2,1,62.8,75,78\n3,20,85.8,87,91\n")
    (tmp_path / "recipes.json").write_text(json.dumps({"totals": {"no_feedback": 1, "feedback_first_step": 2,
                                                                  "recipes": 12}, "runs": []}))
    text = build_summary(tmp_path, METHOD_LABELS)
    assert "| steps | 736 | 759 |" in text
    assert "| ours - full | 96.8 | 96.7 | 88.4 | 90.0 | 69.9 | 91.6 | 56.6 | 69.7 | 77.0 |" in text
    assert "| multiclass | 95.0 | 78.4 | - | - |" in text
    assert "| 0.1 | 42.8 ± 3.0 | 55.8 |" in text
    assert "| 2 | 1 | 62.8 | 74.1 |" in text and "| 3 | all | 85.8 | 81.4 |" in text
    assert "| no feedback | 1/12 | 9/12 |" in text


def test_summary_skips_what_was_not_run(tmp_path):
    assert build_summary(tmp_path, METHOD_LABELS).startswith("# Results")
