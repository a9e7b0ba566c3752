"""A queued DVC experiment runs in a temporary copy of the repository and records into the repository's store."""

import os
import shutil
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

PIPELINE = """stages:
  generate:
    cmd: taskseq generate --world-seed ${world.dev_seed} --output raw
    params:
      - world.dev_seed
    outs:
      - raw
"""


def _run(cmd: list[str], cwd: Path, env: dict[str, str]) -> str:
    done = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, f"{' '.join(cmd)}\n{done.stdout}\n{done.stderr}"
    return done.stdout


@pytest.mark.skipif(shutil.which("git") is None, reason="needs git")
def test_a_queued_experiment_records_into_the_repositorys_mlflow_store(tmp_path):
    repo = tmp_path / "repo"
    repo.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("MLFLOW_TRACKING_URI", "DVC_ROOT")}
    env.update(GIT_AUTHOR_NAME="t", GIT_AUTHOR_EMAIL="t@t", GIT_COMMITTER_NAME="t", GIT_COMMITTER_EMAIL="t@t",
               PATH=f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}")
    (repo / "dvc.yaml").write_text(PIPELINE)
    (repo / "params.yaml").write_text("world:\n  dev_seed: 0\n")
    (repo / ".gitignore").write_text("/mlflow.db\n/mlartifacts/\n")
    for cmd in (["git", "init", "-q"], ["dvc", "init", "-q"], ["git", "add", "-A"], ["git", "commit", "-qm", "x"]):
        _run(cmd, repo, env)
    _run(["dvc", "exp", "run", "--queue", "-S", "world.dev_seed=1,2"], repo, env)
    _run(["dvc", "queue", "start", "-j", "1"], repo, env)
    deadline = time.monotonic() + 600  # a bound on waiting for a worker that died, not a speed check
    while time.monotonic() < deadline:
        status = _run(["dvc", "queue", "status"], repo, env)
        if "Queued" not in status and "Running" not in status:
            break
        time.sleep(2)
    assert status.count("Success") == 2, status
    # the experiments are listed while the idle worker still runs: once asked to stop, a worker's shutdown ran
    # beside `dvc exp show`, which was once ended by SIGTERM on a loaded machine
    shown = _run(["dvc", "exp", "show", "--csv"], repo, env)
    assert "world.dev_seed" in shown and ",1," in shown.replace("\n", ",") and ",2," in shown.replace("\n", ",")
    _run(["dvc", "queue", "stop"], repo, env)
    assert (repo / "mlflow.db").exists()  # in the repository, not in the temporary copies
    with sqlite3.connect(repo / "mlflow.db") as db:
        runs = db.execute("select r.run_uuid, p.value from runs r join params p on p.run_uuid = r.run_uuid "
                          "where r.name = 'generate' and r.status = 'FINISHED' and p.key = 'cli.world_seed'").fetchall()
        assert sorted(seed for _, seed in runs) == ["1", "2"]
        metrics = db.execute("select key, value from metrics where run_uuid = ? and key = 'demonstrations'",
                             (runs[0][0],)).fetchall()
    assert metrics and metrics[0][1] > 0
