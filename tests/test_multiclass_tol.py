"""The multiclass baseline's stopping tolerance: chosen on the development world by `scripts/multiclass_tol.py`."""

from __future__ import annotations

import json
import runpy
import shutil
from pathlib import Path

import pytest

from taskseq.cli import main as taskseq
from taskseq.settings import Params

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = runpy.run_path(str(ROOT / "scripts" / "multiclass_tol.py"))


def test_the_choice_is_the_loosest_tolerance_before_the_first_that_changes_a_prediction():
    rows = [{"tol": 1e-4, "differ_from_tightest": 0}, {"tol": 1e-3, "differ_from_tightest": 0},
            {"tol": 1e-2, "differ_from_tightest": 2}, {"tol": 1e-1, "differ_from_tightest": 0}]
    assert SCRIPT["choose"](rows) == 1e-3
    assert SCRIPT["choose"](list(reversed(rows))) == 1e-3  # the order they come in does not matter


def test_params_hold_the_tolerance_the_development_world_chose():
    """A setting written once, from its measurement: params.yaml's value is the committed report's choice."""
    report = json.loads((ROOT / "reports" / "multiclass_tol.json").read_text())
    assert report["world"] == "data/dev"
    assert Params.load(ROOT / "params.yaml").crossval.multiclass_tol == report["chosen"]
    assert report["rows"][0]["differ_from_tightest"] == 0 and len(report["rows"]) >= 2


def test_the_script_compares_held_out_predictions_on_a_world_and_writes_only_where_told(benchmark_logs, tmp_path,
                                                                                         capsys):
    world = tmp_path / "world"
    (world / "raw").mkdir(parents=True)
    for env in ("env01", "env04"):
        shutil.copy(benchmark_logs / f"{env}.jsonl", world / "raw")
    assert taskseq(["ingest", "--input", str(world / "raw"), "--output", str(world / "processed"),
                    "--metrics", str(tmp_path / "dataset.json")]) == 0
    assert taskseq(["features", "--input", str(world / "processed"), "--output", str(world / "features")]) == 0
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    assert SCRIPT["main"](["--world", str(world), "--tols", "1e-2", "1e-5"]) == 0
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before  # nothing written unasked
    out = tmp_path / "tol.json"
    assert SCRIPT["main"](["--world", str(world), "--tols", "1e-2", "1e-5", "--output", str(out)]) == 0
    report = json.loads(out.read_text())
    assert [r["tol"] for r in report["rows"]] == [1e-5, 1e-2]  # the tightest first: the reference
    assert report["rows"][0]["differ_from_tightest"] == 0
    assert report["steps"] > 0 and all(0 <= r["avg_prim"] <= 100 for r in report["rows"])
    assert report["chosen"] == SCRIPT["choose"](report["rows"])
    assert "chosen: crossval.multiclass_tol" in capsys.readouterr().out


@pytest.mark.parametrize(("argv", "message"), [
    (["--world", "no/such/world"], "no/such/world/features is not a folder"),
    (["--tols", "0", "1e-3"], "every tolerance must be a number above 0"),
    (["--tols", "nan"], "every tolerance must be a number above 0"),
])
def test_bad_arguments_are_named(argv, message, capsys):
    with pytest.raises(SystemExit):
        SCRIPT["main"](argv)
    assert message in capsys.readouterr().err


def test_the_evaluation_page_shows_the_report():
    assert "<!-- generated: multiclass-tol -->" in (ROOT / "docs" / "evaluation.md").read_text()
