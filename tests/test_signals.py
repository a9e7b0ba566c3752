"""A stage stopped by SIGTERM or Ctrl-C: one line, exit 143 or 130, its MLflow run KILLED, nothing written."""

import os
import signal
import sqlite3
import subprocess
import sys
import time

import pytest

from pipeline.features.dataset import write_features
from pipeline.logs.ingest import write_tables


@pytest.fixture(scope="module")
def data(benchmark_tables, benchmark_steps, tmp_path_factory):
    root = tmp_path_factory.mktemp("signals")
    write_tables(benchmark_tables[0], root / "processed")
    write_features(*benchmark_steps, root / "features")
    return root


def _default_sigint() -> None:
    """A shell's background jobs start with SIGINT ignored, and Python then installs no Ctrl-C handler;
    give the stage the SIGINT a terminal's foreground job has."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _working(stdout) -> bool:
    """The stage has opened its run and started training (it prints that line once set up)."""
    return stdout.exists() and "training" in stdout.read_text()


@pytest.mark.parametrize(("sig", "code", "name"), [(signal.SIGTERM, 143, "SIGTERM"), (signal.SIGINT, 130, "Ctrl-C")])
def test_a_stopped_stage_marks_its_run_killed_and_writes_nothing(data, tmp_path, sig, code, name):
    db = tmp_path / "mlflow.db"
    # one job: no worker processes, whose helpers would hold the output pipes open after the stage ends
    env = {**os.environ, "MLFLOW_TRACKING_URI": f"sqlite:///{db}", "TASKSEQ_N_JOBS": "1"}
    out, metrics, log, said = tmp_path / "store", tmp_path / "folds.json", tmp_path / "stderr.txt", tmp_path / "out"
    with log.open("w") as fh, said.open("w") as sh:
        proc = subprocess.Popen([sys.executable, "-u", "-m", "pipeline.cli", "folds", "--features",
                                 str(data / "features"), "--processed", str(data / "processed"), "--output", str(out),
                                 "--metrics", str(metrics)], env=env, stdout=sh, stderr=fh,
                                preexec_fn=_default_sigint)
        while proc.poll() is None and not _working(said):
            time.sleep(0.2)
        assert proc.poll() is None, "the stage ended before it could be stopped"
        proc.send_signal(sig)
        proc.wait(timeout=300)
    err = log.read_text()
    assert proc.returncode == code, err[-3000:]
    lines = [line for line in err.splitlines() if line.startswith("taskseq")]
    assert lines == [f"taskseq folds: stopped by {name}; nothing was written; its MLflow run is marked KILLED"]
    assert "Traceback" not in err
    assert not out.exists() and not metrics.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".store")]  # no half-written temporary folder
    with sqlite3.connect(db) as conn:
        assert conn.execute("select name, status from runs").fetchall() == [("folds", "KILLED")]
