"""The tags a stage's run carries say what the run started from: the commit, whether the tree had changes, the
lock file and the inputs, checked against a throwaway git repository with known answers."""

from __future__ import annotations

import hashlib
import subprocess
from pathlib import Path

import pytest

from taskseq.track.mlflow_runs import hash_inputs, provenance


def _git(repo: Path, *args: str) -> str:
    return subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@example.org", *args], cwd=repo,
                          check=True, capture_output=True, text=True).stdout.strip()


@pytest.fixture
def repo(tmp_path, monkeypatch) -> Path:
    _git(tmp_path, "init", "-q")
    (tmp_path / "dvc.lock").write_text("schema: '2.0'\nstages: {}\n")
    (tmp_path / "params.yaml").write_text("seed: 0\n")
    _git(tmp_path, "add", ".")
    _git(tmp_path, "commit", "-q", "-m", "start")
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("DVC_STAGE", raising=False)
    return tmp_path


def test_a_clean_tree_says_clean_at_its_commit(repo):
    tags = provenance("ingest", [])
    assert tags["git.commit"] == _git(repo, "rev-parse", "HEAD") and len(tags["git.commit"]) == 40
    assert tags["git.dirty"] == "false"
    assert tags["dvc.lock.md5"] == hashlib.md5((repo / "dvc.lock").read_bytes()).hexdigest()
    assert tags["dvc.stage"] == "ingest"


def test_a_changed_tracked_file_says_dirty_and_a_new_commit_is_named(repo):
    (repo / "params.yaml").write_text("seed: 1\n")
    assert provenance("ingest", [])["git.dirty"] == "true"
    _git(repo, "commit", "-q", "-am", "seed 1")
    tags = provenance("ingest", [])
    assert tags["git.dirty"] == "false" and tags["git.commit"] == _git(repo, "rev-parse", "HEAD")


def test_an_untracked_file_leaves_the_tree_clean(repo):
    (repo / "notes.txt").write_text("scratch")
    assert provenance("ingest", [])["git.dirty"] == "false"


def test_the_lock_hash_follows_the_lock_file(repo):
    before = provenance("ingest", [])["dvc.lock.md5"]
    (repo / "dvc.lock").write_text("schema: '2.0'\nstages: {a: {}}\n")
    after = provenance("ingest", [])["dvc.lock.md5"]
    assert after != before and after == hashlib.md5((repo / "dvc.lock").read_bytes()).hexdigest()
    part = repo / "pipelines" / "table1" / "dvc.lock"  # a part's lock counts too
    part.parent.mkdir(parents=True)
    part.write_text("schema: '2.0'\nstages: {}\n")
    assert provenance("ingest", [])["dvc.lock.md5"] == after  # a lock with no part's dvc.yaml beside it is no part
    (part.parent / "dvc.yaml").write_text("stages: {}\n")
    with_part = provenance("ingest", [])["dvc.lock.md5"]
    part.write_text("schema: '2.0'\nstages: {b: {}}\n")
    assert len({after, with_part, provenance("ingest", [])["dvc.lock.md5"]}) == 3
    (repo / "dvc.lock").unlink()
    assert provenance("ingest", [])["dvc.lock.md5"] == "none"


def test_outside_a_repository_commit_and_state_are_unknown(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("GIT_CEILING_DIRECTORIES", str(tmp_path.parent))
    tags = provenance("ingest", [])
    assert tags["git.commit"] == "unknown" and tags["git.dirty"] == "unknown" and tags["dvc.lock.md5"] == "none"


def test_under_dvc_the_stage_is_dvcs_name(repo, monkeypatch):
    monkeypatch.setenv("DVC_STAGE", "crossval@7")
    assert provenance("crossval", [])["dvc.stage"] == "crossval@7"


def test_the_data_hash_covers_names_and_bytes_of_every_input(repo):
    data = repo / "data"
    data.mkdir()
    (data / "a.txt").write_text("1")
    first = hash_inputs([data])
    assert provenance("ingest", [data])["data.hash"] == first
    (data / "a.txt").write_text("2")
    assert hash_inputs([data]) != first
    (data / "a.txt").write_text("1")
    assert hash_inputs([data]) == first
    (data / "a.txt").rename(data / "b.txt")
    assert hash_inputs([data]) != first
