"""docs/adding-a-method.md, followed step by step: one module adds a method to Table I, MLflow and the store."""

from __future__ import annotations

import json
import re
import shutil
import sys
from pathlib import Path

import pytest
from mlflow.tracking import MlflowClient

import taskseq.methods
from taskseq.cli import main
from taskseq.evaluate import registry
from taskseq.track.mlflow_runs import EXPERIMENT

ROOT = Path(__file__).resolve().parents[1]
TUTORIAL = ROOT / "docs" / "adding-a-method.md"
SMALL = ["--set", "crossval.folds=2", "--set", "train.tol=0.01", "--set", "train.max_iter=300",
         "--set", "train.n_slacks=0"]


def tutorial_module() -> tuple[str, str]:
    """The file name and code the tutorial tells a reader to save (its first Python block)."""
    text = TUTORIAL.read_text()
    name = re.search(r"Save this\s+as `taskseq/methods/(\w+\.py)`", text).group(1)
    code = re.search(r"```python\n(.*?)```", text, re.S).group(1)
    return name, code


@pytest.fixture
def added(tmp_path, monkeypatch):
    """The tutorial's module saved beside `taskseq/methods/` (a folder on the package's path), the registry
    read afresh; both restored afterwards."""
    folder = tmp_path / "methods"
    folder.mkdir()
    name, code = tutorial_module()
    (folder / name).write_text(code)
    monkeypatch.setattr(taskseq.methods, "__path__", [*taskseq.methods.__path__, str(folder)])
    monkeypatch.setattr(registry, "_ADDED", {})
    monkeypatch.setattr(registry, "_complete", False)
    taskseq.methods.load()  # what importing the package does
    yield name.removesuffix(".py")
    sys.modules.pop(f"taskseq.methods.{name.removesuffix('.py')}", None)


@pytest.fixture
def tiny(benchmark_logs, tmp_path) -> Path:
    root = tmp_path / "tiny"
    (root / "raw").mkdir(parents=True)
    for env in ("env01", "env04"):
        shutil.copy(benchmark_logs / f"{env}.jsonl", root / "raw")
    assert main(["--no-mlflow", "ingest", "--input", str(root / "raw"), "--output", str(root / "processed"),
                 "--metrics", str(root / "worlds" / "0" / "dataset.json")]) == 0
    assert main(["--no-mlflow", "features", "--input", str(root / "processed"),
                 "--output", str(root / "features")]) == 0
    return root


def test_the_tutorials_method_reaches_table1_mlflow_the_store_and_the_tables_over_worlds(added, tiny, tmp_path,
                                                                                          monkeypatch):
    assert added == "full_chained"
    labels = registry.method_labels()
    assert labels["full_chained"] == "ours - full + chained starts"
    assert list(labels)[-1] == "full_chained"  # below the built-in rows
    uri = f"sqlite:///{tmp_path / 'mlflow.db'}"
    monkeypatch.setenv("MLFLOW_TRACKING_URI", uri)
    data = ["--features", str(tiny / "features"), "--processed", str(tiny / "processed")]

    # the model store: the fold_models stage trains it with the built-in MRF methods
    assert main(["fold_models", *data, *SMALL, "--output", str(tiny / "store"), "--n-jobs", "1"]) == 0
    stored = json.loads((tiny / "store" / "index.json").read_text())["models"]
    uses = {u["method"] for m in stored for u in m["uses"]}
    assert "full_chained" in uses and "full" in uses

    # Table I of the world, and a child run in MLflow with the method's settings
    world = tiny / "worlds" / "0"
    assert main(["crossval", *data, *SMALL, "--model-store", str(tiny / "store"), "--methods", "full",
                 "full_chained", "--recordings", "0", "--output", str(world), "--n-jobs", "1"]) == 0
    table = (world / "table1.md").read_text()
    assert "ours - full + chained starts" in table and "ours - full |" in table
    summary = json.loads((world / "crossval.json").read_text())
    assert summary["full_chained"]["n_scenarios"] == summary["full"]["n_scenarios"] > 0
    client = MlflowClient(tracking_uri=uri)
    experiment = client.get_experiment_by_name(EXPERIMENT)
    (child,) = client.search_runs([experiment.experiment_id], "attributes.run_name = 'full_chained'")
    assert child.data.params["chained_starts"] == "True" and child.data.params["feature_set"] == "full"

    # the tables over worlds: the rest of the world's results (small), a second world (the same) and the aggregate
    rest = [*data, *SMALL, "--model-store", str(tiny / "store"), "--output", str(world)]
    assert main(["--no-mlflow", "noise", *rest, "--set", "noise.rates=0.0", "--set", "noise.draws=1",
                 "--set", "noise.methods=full", "--n-jobs", "1"]) == 0
    assert main(["--no-mlflow", "feedback", *rest, "--set", "feedback.k=2", "--set", "feedback.n=0",
                 "--set", "feedback.methods=full", "--n-jobs", "1"]) == 0
    assert main(["--no-mlflow", "recipes", *rest, "--set", "recipes.methods=full"]) == 0
    shutil.copytree(world, tiny / "worlds" / "5")
    out = tiny / "reports"
    assert main(["--no-mlflow", "aggregate", "--set", "world.seeds=[0, 5]", "--worlds", str(tiny / "worlds"),
                 "--output", str(out)]) == 0
    rows = (out / "table1.md").read_text().splitlines()
    names = [r.split("|")[1].strip() for r in rows if r.startswith("|")]
    assert names.index("ours - full + chained starts") > names.index("ours - full")
    assert "full_chained" in json.loads((out / "crossval_means.json").read_text())


def test_the_list_is_refused_until_the_methods_package_has_registered_them(monkeypatch):
    monkeypatch.setattr(registry, "_complete", False)
    with pytest.raises(RuntimeError, match="import taskseq.methods first"):
        registry.method_labels()


def test_a_name_is_registered_once(added):
    registry.added_methods()
    with pytest.raises(ValueError, match="registered twice"):
        registry.register("full", "another full model")(lambda settings: None)
    with pytest.raises(ValueError, match="Python identifier"):
        registry.register("two words", "x")
