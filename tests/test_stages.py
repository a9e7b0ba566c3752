"""The stage layout: DVC knows every file a stage runs, and settings defaults equal params.yaml."""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from dataclasses import fields
from pathlib import Path

import pytest
import yaml
from params_reads import keys_read

from taskseq.methods import Lineup
from taskseq.settings import SECTIONS, Methods, Params, parse_section
from taskseq.stages import STAGES

ROOT = Path(__file__).resolve().parents[1]
DVC = yaml.safe_load((ROOT / "dvc.yaml").read_text())["stages"]
_spec = importlib.util.spec_from_file_location("stage_deps", ROOT / "scripts" / "stage_deps.py")
stage_deps = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(stage_deps)


def dvc_stage(name: str) -> dict:
    """A stage of dvc.yaml by name; a `foreach` stage's template."""
    stage = DVC[name]
    return stage.get("do", stage)


def test_every_stage_of_dvc_yaml_has_its_module():
    assert sorted(DVC) == sorted(STAGES)


@pytest.mark.parametrize("stage", STAGES)
def test_dvc_deps_are_exactly_the_project_code_a_stage_loads(stage):
    deps = [d for d in dvc_stage(stage)["deps"] if d.startswith("taskseq")]
    assert deps == stage_deps.code_deps(stage), f"dvc.yaml stage {stage}: run python scripts/stage_deps.py"
    assert f"taskseq/stages/{stage}.py" in deps


def test_the_deps_writer_replaces_a_stages_code_deps_and_keeps_everything_else():
    text = ("stages:\n  a:\n    cmd: x\n    deps:\n      - data/in  # read\n      - taskseq/old.py\n"
            "      - taskseq/sim\n    outs:\n      - out\n  b:\n    foreach: [1]\n    do:\n      deps:\n"
            "        - taskseq/cli.py\n")
    new = stage_deps.rewrite(text, {"a": ["taskseq/learn", "taskseq/stages/a.py"], "b": ["taskseq/b.py"]})
    assert new == text.replace("      - taskseq/old.py\n      - taskseq/sim\n",
                               "      - taskseq/learn\n      - taskseq/stages/a.py\n").replace(
        "        - taskseq/cli.py\n", "        - taskseq/b.py\n")
    with pytest.raises(ValueError, match="no code deps found for c"):
        stage_deps.rewrite(text, {"c": ["taskseq/c.py"]})


def _stages_a_change_can_rerun(repo, graph, path: str) -> set[str]:
    """The stages of dvc.yaml that `dvc repro` may re-run after a change to the file `path`, as DVC's own graph
    has them: those that list it among their deps, and every stage downstream of those (re-run only when an
    output it reads changed)."""
    import networkx as nx

    def covers(dep: str) -> bool:
        return path == dep or path.startswith(dep.rstrip("/") + "/")

    direct = [s for s in graph if s.dvcfile.relpath == "dvc.yaml"
              and any(covers(os.path.relpath(d.fs_path, repo.root_dir)) for d in s.deps)]
    return {s.addressing for s in direct} | {a.addressing for s in direct for a in nx.ancestors(graph, s)}


@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # DVC's own, from its graph of outputs
def test_a_change_to_one_stages_code_reaches_only_that_stage_and_what_reads_its_outputs():
    from dvc.repo import Repo

    repo = Repo(str(ROOT))
    graph = repo.index.graph

    def reruns(path):
        return _stages_a_change_can_rerun(repo, graph, path)

    assert reruns("taskseq/stages/teach.py") == {"teach"}
    assert reruns("taskseq/serve/app.py") == {"teach"}  # the web app's record writer, which teach writes through
    assert reruns("taskseq/stages/scenes.py") == {"scenes", "report"}
    assert reruns("taskseq/bench/speed.py") == set()  # a tool's code
    seeds = Params.load(ROOT / "params.yaml").world.seeds
    assert reruns("taskseq/stages/drawn_world.py") == {
        *(f"{stage}@{s}" for stage in ("drawn_world", "scenes_world") for s in seeds), "scenes", "teach",
        "stats@drawn_rooms", "stats@transfer", "report"}  # the drawn worlds' stages, none of the reported worlds'


@pytest.mark.parametrize("stage", ["train", "select", "fold_models", "crossval", "noise", "feedback", "recipes",
                                   "scenes_world"])
def test_stages_that_load_planners_start_without_scikit_learn(stage):
    # importing scikit-learn takes about a second in every stage process and worker; only the baselines'
    # fits need it, and they import it themselves
    code = f"import sys, taskseq.stages.{stage}; print('sklearn' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    assert out.stdout.strip() == "False"


def test_settings_defaults_equal_params_yaml():
    params = yaml.safe_load((ROOT / "params.yaml").read_text())
    for section, cls in SECTIONS.items():
        assert section in params, f"params.yaml has no section {section}"
        if cls is Methods:  # no defaults in code: the file is where the methods' entries are written, once
            continue
        assert parse_section(cls, params[section]) == cls(), f"defaults of {cls.__name__} differ from params.yaml"
        assert set(params[section]) == {f.name for f in fields(cls)}, section


def test_params_yaml_names_every_method_of_table1_once_with_settings_it_has():
    methods = Params.load(ROOT / "params.yaml").methods
    lineup = Lineup(methods)  # raises for a name no spec has, or a setting its method does not have
    written = [name for name, _ in methods.entries]
    assert sorted(written) == sorted(lineup.names()) and len(set(written)) == len(written)


def test_no_stage_command_passes_a_setting_that_changes_no_result():
    for name in STAGES:
        cmd = dvc_stage(name)["cmd"]
        assert not re.search(r"--n-jobs|--recordings(?!-dir)", cmd), name


def leaf_keys(entries: list[str]) -> set[str]:
    """dvc.yaml params entries as `section.key`: a whole section stands for each of its keys."""
    out = set()
    for entry in entries:
        section, _, key = entry.partition(".")
        out |= {f"{section}.{f.name}" for f in fields(SECTIONS[section])} if not key else {entry}
    return out


@pytest.mark.parametrize("stage", STAGES)
def test_dvc_params_are_exactly_the_settings_a_stage_reads(stage):
    declared = leaf_keys(dvc_stage(stage).get("params", []))
    read = keys_read(stage)
    assert declared == read, f"dvc.yaml stage {stage}: lists {sorted(declared - read)} it never reads, " \
                             f"misses {sorted(read - declared)}"


@pytest.mark.parametrize("stage", STAGES)
def test_stage_commands_carry_paths_and_the_world_seed_only(stage):
    cmd = dvc_stage(stage)["cmd"]
    options = re.findall(r"--([a-z-]+)", cmd)
    allowed = {f.name.replace("_", "-") for f in fields(STAGES[stage].options)} | {"world-seed"}
    assert set(options) <= allowed, f"{stage} passes {sorted(set(options) - allowed)}"
    assert "${" not in re.sub(r"\$\{item(\.\w+)?\}", "", cmd).replace("${world.seeds[0]}", ""), cmd
