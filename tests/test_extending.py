"""docs/adding-a-method.md, followed step by step: one module and one params.yaml entry add a method to Table I,
with a setting of its own and a C of its own, to MLflow and the store."""

from __future__ import annotations

import json
import re
import shutil
import sys
from pathlib import Path

import pytest
import yaml
from mlflow.tracking import MlflowClient

import taskseq.methods
from taskseq.cli import main
from taskseq.methods import Lineup, MethodSpec, method_labels, register, spec
from taskseq.selection import Selection
from taskseq.settings import Params
from taskseq.track.mlflow_runs import EXPERIMENT

ROOT = Path(__file__).resolve().parents[1]
TUTORIAL = ROOT / "docs" / "adding-a-method.md"
SMALL = ["--set", "crossval.folds=2", "--set", "train.tol=0.01", "--set", "train.max_iter=300",
         "--set", "train.n_slacks=0"]


def tutorial_module() -> tuple[str, str]:
    """The file name and code the tutorial tells a reader to save (its first Python block)."""
    text = TUTORIAL.read_text()
    name = re.search(r"Save this\s+as\s+`taskseq/methods/(\w+\.py)`", text).group(1)
    code = re.search(r"```python\n(.*?)```", text, re.S).group(1)
    return name, code


def tutorial_entry() -> dict:
    """The entry the tutorial tells a reader to add to params.yaml's `methods` section (its first YAML block)."""
    return yaml.safe_load(re.search(r"```yaml\n(.*?)```", TUTORIAL.read_text(), re.S).group(1))


@pytest.fixture
def added(tmp_path, monkeypatch):
    """The tutorial's module saved beside `taskseq/methods/` (a folder on the package's path), the specs read
    afresh; both restored afterwards."""
    folder = tmp_path / "methods"
    folder.mkdir()
    name, code = tutorial_module()
    (folder / name).write_text(code)
    monkeypatch.setattr(taskseq.methods, "__path__", [*taskseq.methods.__path__, str(folder)])
    monkeypatch.setattr(spec, "_SPECS", dict(spec._SPECS))
    taskseq.methods.load()  # what importing the package does
    yield name.removesuffix(".py")
    sys.modules.pop(f"taskseq.methods.{name.removesuffix('.py')}", None)


@pytest.fixture
def params(added, tmp_path) -> Path:
    """params.yaml with the tutorial's entry; the other methods run in Table I only, to keep the run small."""
    data = yaml.safe_load((ROOT / "params.yaml").read_text())
    data["methods"] = {"full": {"experiments": "select noise feedback recipes"}, **tutorial_entry()}
    path = tmp_path / "params.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


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


def test_the_tutorials_method_reaches_table1_mlflow_the_store_and_the_tables_over_worlds(added, params, tiny,
                                                                                          tmp_path, monkeypatch):
    assert added == "full_dagger"
    labels = method_labels()
    assert labels["full_dagger"] == "ours - full + dagger"
    builtin = [name for name, s in spec.specs().items() if s.make.__module__ == "taskseq.methods.builtin"]
    added_rows = list(labels)[len(builtin):]  # below the built-in rows, the added ones by name
    assert list(labels)[:len(builtin)] == builtin and "full_dagger" in added_rows and added_rows == sorted(added_rows)
    # its entry: select gives it a C of its own; its setting is read, checked and overridden like any other
    methods = Params.load(params).methods
    assert Lineup(methods).names("select") == ["full", "full_dagger"]
    assert Lineup(methods).factory("full_dagger")().dagger_rounds == 1
    assert Lineup(Params.load(params, ["methods.full_dagger.rounds=2"]).methods).factory("full_dagger")(
        ).dagger_rounds == 2
    with pytest.raises(ValueError, match="methods.full_dagger.rounds must be a whole number, got 'two'"):
        Lineup(Params.load(params, ["methods.full_dagger.rounds=two"]).methods).factories()
    # the C `select` chose for it, as selection.json holds it (the other MRF methods' too, which fold_models trains)
    selection = tmp_path / "selection.json"
    every = [n for n, m in Lineup(methods).mrf().items() if n not in ("only_edge", "only_clique")]
    selection.write_text(json.dumps({"C": 2.0, "method": "full", "settings": {
        **{n: {"C": 2.0} for n in every}, "full_dagger": {"C": 0.5}}}))
    uri = f"sqlite:///{tmp_path / 'mlflow.db'}"
    monkeypatch.setenv("MLFLOW_TRACKING_URI", uri)
    data = ["--features", str(tiny / "features"), "--processed", str(tiny / "processed"), "--params", str(params),
            "--selection", str(selection)]

    # the model store: the fold_models stage trains it with the built-in MRF methods
    assert main(["fold_models", *data, *SMALL, "--output", str(tiny / "store"), "--n-jobs", "1"]) == 0
    stored = json.loads((tiny / "store" / "index.json").read_text())["models"]
    uses = {u["method"] for m in stored for u in m["uses"]}
    assert "full_dagger" in uses and "full" in uses

    # Table I of the world, and a child run in MLflow with the method's settings and its own C
    world = tiny / "worlds" / "0"
    assert main(["crossval", *data, *SMALL, "--model-store", str(tiny / "store"), "--methods", "full",
                 "full_dagger", "--recordings", "0", "--output", str(world), "--n-jobs", "1"]) == 0
    table = (world / "table1.md").read_text()
    assert "ours - full + dagger" in table and "ours - full |" in table
    summary = json.loads((world / "crossval.json").read_text())
    assert summary["full_dagger"]["n_scenarios"] == summary["full"]["n_scenarios"] > 0
    client = MlflowClient(tracking_uri=uri)
    experiment = client.get_experiment_by_name(EXPERIMENT)
    (child,) = client.search_runs([experiment.experiment_id], "attributes.run_name = 'full_dagger'")
    assert child.data.params["dagger_rounds"] == "1" and child.data.params["feature_set"] == "full"
    assert child.data.params["C"] == "0.5"

    # the tables over worlds: the rest of the world's results (small), a second world (the same) and the aggregate
    rest = [*data, *SMALL, "--model-store", str(tiny / "store"), "--output", str(world)]
    assert main(["--no-mlflow", "noise", *rest, "--set", "noise.rates=0.0", "--set", "noise.draws=1",
                 "--n-jobs", "1"]) == 0
    assert main(["--no-mlflow", "feedback", *rest, "--set", "feedback.k=2", "--set", "feedback.n=0",
                 "--n-jobs", "1"]) == 0
    assert main(["--no-mlflow", "recipes", *rest]) == 0
    shutil.copytree(world, tiny / "worlds" / "5")
    out = tiny / "reports"
    assert main(["--no-mlflow", "aggregate", "--set", "world.seeds=[0, 5]", "--worlds", str(tiny / "worlds"),
                 "--output", str(out)]) == 0
    rows = (out / "table1.md").read_text().splitlines()
    names = [r.split("|")[1].strip() for r in rows if r.startswith("|")]
    assert names.index("ours - full + dagger") > names.index("ours - full")
    assert "full_dagger" in json.loads((out / "crossval_means.json").read_text())


def test_a_method_needs_a_c_of_its_own_when_a_selection_file_is_given(added, params):
    lineup = Lineup(Params.load(params).methods, Selection({"full": 2.0}, source="selection.json"))
    assert lineup.factory("only_edge")().C == 2.0  # the paper's ablations take the full model's, as their spec says
    with pytest.raises(ValueError, match="selection.json: no C for method full_dagger: add select to "
                                         "methods.full_dagger.experiments in params.yaml"):
        lineup.factory("full_dagger")


def test_an_entry_names_a_method_and_settings_it_has(added, tmp_path):
    with pytest.raises(ValueError, match="methods.full_chained is no method of Table I"):
        Lineup(Params.load(None, ["methods.full_chained.experiments=select"]).methods)
    lineup = Lineup(Params.load(None, ["methods.full.rounds=2"]).methods)
    with pytest.raises(ValueError, match="unknown setting methods.full.rounds"):
        lineup.factories()  # every stage asks for its methods before any work


def test_a_name_is_registered_once(added):
    with pytest.raises(ValueError, match="registered twice"):
        register(MethodSpec("full", "another full model", lambda build: None))
    in_the_package = lambda build: None  # noqa: E731
    in_the_package.__module__ = "taskseq.methods.choice"
    with pytest.raises(ValueError, match="registered by taskseq/methods/choice.py: a module that adds a method is "
                                         "named as the method"):
        register(MethodSpec("choice_again", "x", in_the_package))
    with pytest.raises(ValueError, match="Python identifier"):
        MethodSpec("two words", "x", lambda build: None)
