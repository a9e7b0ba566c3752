"""A stage run by DVC refuses to load a method module its dvc.yaml deps do not list (`runtime.dvc_deps`)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from taskseq.runtime import dvc_deps

ROOT = Path(__file__).resolve().parents[1]
DVC_YAML = """stages:
  noise:
    foreach: [0, 3]
    do:
      cmd: taskseq noise
      deps:
        - data/worlds/${item}/features
        - taskseq/methods/builtin.py
        - taskseq/methods/noise_trained.py
  select:
    cmd: taskseq select
    deps:
      - taskseq/methods
  choose_C:
    foreach:
      full: taskseq/methods/builtin.py
      noise_trained: taskseq/methods/noise_trained.py
    do:
      cmd: taskseq choose_C --method ${key}
      deps:
        - reports/${key}
        - ${item}
        - taskseq/methods/builtin.py
"""
VEIL_YAML = """stages:
  train:
    cmd: taskseq veil train
    deps:
      - ../taskseq/veil/mrf.py
"""


@pytest.fixture
def repo(tmp_path, monkeypatch):
    (tmp_path / "dvc.yaml").write_text(DVC_YAML)
    (tmp_path / "veil").mkdir()
    (tmp_path / "veil" / "dvc.yaml").write_text(VEIL_YAML)
    monkeypatch.setenv(dvc_deps.DVC_ROOT, str(tmp_path))
    dvc_deps._deps.cache_clear()
    yield tmp_path
    dvc_deps._deps.cache_clear()


def test_a_file_or_its_folder_among_the_deps_is_declared(repo, monkeypatch):
    monkeypatch.setenv(dvc_deps.DVC_STAGE, "noise@3")
    assert dvc_deps.undeclared(repo / "taskseq/methods/noise_trained.py") is None
    problem = dvc_deps.undeclared(repo / "taskseq/methods/choice.py")
    assert problem == (f"{repo / 'dvc.yaml'}: stage noise@3 does not list taskseq/methods/choice.py among its deps, "
                       "so a change to it would not run the stage again")
    monkeypatch.setenv(dvc_deps.DVC_STAGE, "select")
    assert dvc_deps.undeclared(repo / "taskseq/methods/choice.py") is None  # the folder is listed


def test_a_run_of_a_per_method_stage_lists_its_own_item(repo, monkeypatch):
    monkeypatch.setenv(dvc_deps.DVC_STAGE, "choose_C@noise_trained")
    assert dvc_deps.undeclared(repo / "taskseq/methods/noise_trained.py") is None
    assert dvc_deps.undeclared(repo / "reports/noise_trained/x.json") is None  # `${key}` filled in
    assert "stage choose_C@noise_trained does not list taskseq/methods/choice.py" in \
        dvc_deps.undeclared(repo / "taskseq/methods/choice.py")
    monkeypatch.setenv(dvc_deps.DVC_STAGE, "choose_C@full")
    assert "stage choose_C@full does not list taskseq/methods/noise_trained.py" in \
        dvc_deps.undeclared(repo / "taskseq/methods/noise_trained.py")


def test_a_stage_of_another_dvc_file_reads_its_deps_from_its_own_folder(repo, monkeypatch):
    monkeypatch.setenv(dvc_deps.DVC_STAGE, "veil/dvc.yaml:train")
    assert dvc_deps.undeclared(repo / "taskseq/veil/mrf.py") is None
    assert "veil/dvc.yaml: stage veil/dvc.yaml:train does not list taskseq/veil/lookahead.py" in \
        dvc_deps.undeclared(repo / "taskseq/veil/lookahead.py")


def test_a_stage_of_a_part_run_in_the_root_reads_its_deps_from_the_root(repo, monkeypatch):
    part = repo / dvc_deps.PARTS / "table1"
    part.mkdir(parents=True)
    (part / "dvc.yaml").write_text(DVC_YAML.replace("    do:\n", "    do:\n      wdir: ../..\n", 1))
    monkeypatch.setenv(dvc_deps.DVC_STAGE, "pipelines/table1/dvc.yaml:noise@3")
    assert dvc_deps.undeclared(repo / "taskseq/methods/noise_trained.py") is None
    assert dvc_deps.undeclared(repo / "data/worlds/3/features/steps.parquet") is None
    assert "pipelines/table1/dvc.yaml: stage pipelines/table1/dvc.yaml:noise@3 does not list " \
           "taskseq/methods/choice.py" in dvc_deps.undeclared(repo / "taskseq/methods/choice.py")
    assert dvc_deps.pipeline_files(repo) == [repo / "dvc.yaml", part / "dvc.yaml"]


@pytest.mark.parametrize("stage", [None, "nosuch", "nosuch/dvc.yaml:train"])
def test_outside_dvc_or_an_unknown_stage_checks_nothing(repo, monkeypatch, stage):
    if stage is None:
        monkeypatch.delenv(dvc_deps.DVC_STAGE, raising=False)
    else:
        monkeypatch.setenv(dvc_deps.DVC_STAGE, stage)
    assert dvc_deps.undeclared(repo / "taskseq/methods/choice.py") is None


def test_a_file_outside_the_repository_is_not_its_business(repo, monkeypatch, tmp_path_factory):
    monkeypatch.setenv(dvc_deps.DVC_STAGE, "noise@0")
    assert dvc_deps.undeclared(tmp_path_factory.mktemp("elsewhere") / "mine.py") is None


def _spec_in_a_stage(stage_file: Path, stage: str, name: str) -> subprocess.CompletedProcess:
    """`method_spec(name)` in a fresh process that DVC would have started for `stage` of `stage_file` (its deps
    name this repository's files by absolute path, so the repository's own code is what is checked)."""
    env = {**os.environ, dvc_deps.DVC_ROOT: str(ROOT), dvc_deps.DVC_STAGE: f"{stage_file}:{stage}"}
    code = f"from taskseq.methods import method_spec; print(method_spec({name!r}).label)"
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=ROOT)


def test_a_stage_stops_on_a_method_module_its_deps_leave_out_and_says_what_to_run(tmp_path):
    stage_file = tmp_path / "dvc.yaml"
    stage_file.write_text(f"stages:\n  noise:\n    cmd: x\n    deps:\n      - {ROOT / 'taskseq/methods/builtin.py'}\n")
    out = _spec_in_a_stage(stage_file, "noise", "noise_trained")
    assert out.returncode != 0
    assert ("does not list taskseq/methods/noise_trained.py among its deps" in out.stderr
            and "methods.noise_trained.experiments" in out.stderr and "python scripts/stage_deps.py" in out.stderr)
    assert _spec_in_a_stage(stage_file, "noise", "full").returncode == 0  # a built-in method: builtin.py is listed
    stage_file.write_text(f"stages:\n  noise:\n    cmd: x\n    deps:\n      - {ROOT / 'taskseq/methods'}\n")
    listed = _spec_in_a_stage(stage_file, "noise", "noise_trained")
    assert listed.returncode == 0, listed.stderr
