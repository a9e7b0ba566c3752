"""A stage stopped by SIGTERM or Ctrl-C: one line, exit 143 or 130, its MLflow run KILLED, nothing written."""

import os
import signal
import sqlite3
import subprocess
import sys
import time

import pytest

from taskseq.demonstrations.ingest import write_tables
from taskseq.features.dataset import write_features


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
        proc = subprocess.Popen([sys.executable, "-u", "-m", "taskseq.cli", "fold_models", "--features",
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
    assert lines == [f"taskseq fold_models: stopped by {name}; nothing was written; its MLflow run is marked KILLED"]
    assert "Traceback" not in err
    assert not out.exists() and not metrics.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".store")]  # no half-written temporary folder
    with sqlite3.connect(db) as conn:
        assert conn.execute("select name, status from runs").fetchall() == [("fold_models", "KILLED")]


@pytest.fixture
def handlers():
    """The stopping handlers installed for the test, the previous ones back afterwards."""
    from taskseq.runtime import stopping

    before = signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGINT)
    stopping.install()
    yield stopping
    stopping.acknowledge()  # a signal a test raised and caught is not left for a later test's writes
    signal.signal(signal.SIGTERM, before[0])
    signal.signal(signal.SIGINT, before[1])


@pytest.mark.parametrize(("sig", "kind"), [(signal.SIGTERM, "Stopped"), (signal.SIGINT, "KeyboardInterrupt")])
def test_a_signal_inside_a_held_block_is_raised_when_the_block_is_done(handlers, sig, kind):
    done = []
    with pytest.raises(KeyboardInterrupt) as stop:
        with handlers.held():
            os.kill(os.getpid(), sig)
            time.sleep(0.1)  # the handler runs here, between two bytecodes of the block
            done.append("rest of the block")
        done.append("after the block")
    assert done == ["rest of the block"]
    assert type(stop.value).__name__ == kind


def test_a_stop_raised_as_a_held_block_ends_is_raised_again_where_it_was_dropped(handlers):
    """The stop a held block raises at its end is noted as the handler notes one: dropped where it landed (a
    destructor), the next check raises it again."""
    with pytest.raises(KeyboardInterrupt), handlers.held():
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.1)
    with pytest.raises(KeyboardInterrupt):
        handlers.check()  # what every atomic write calls first
    handlers.acknowledge()
    handlers.check()  # said to have stopped: nothing raised


@pytest.mark.parametrize("write", ["folder", "file"])
def test_a_stop_dropped_where_it_landed_replaces_no_output(handlers, tmp_path, write):
    """Python drops an exception raised in a ctypes callback (Numba's compiler writing its cache calls one) or a
    destructor: the command runs on, but no atomic write replaces anything afterwards, and the stop is raised
    there."""
    from taskseq.runtime.atomic import atomic_directory, write_text_atomic

    class LandsInADestructor:
        def __del__(self):
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.1)  # the handler runs here, inside the destructor, whose exception Python drops

    target = tmp_path / "out"
    target.mkdir() if write == "folder" else target.write_text("before")
    LandsInADestructor()  # made and dropped at once: the stop lands in its destructor
    with pytest.raises(KeyboardInterrupt):
        if write == "folder":
            with atomic_directory(target) as tmp:
                (tmp / "made").write_text("after")
        else:
            write_text_atomic(target, "after")
    assert (not list(target.iterdir())) if write == "folder" else target.read_text() == "before"
    assert [p.name for p in tmp_path.iterdir()] == ["out"]  # no temporary left behind
    handlers.acknowledge()  # the command said it stopped: writes go on
    write_text_atomic(tmp_path / "later", "written")
    assert (tmp_path / "later").read_text() == "written"


def test_a_dropped_stop_prints_no_traceback_and_ends_the_command_at_its_write(tmp_path):
    """In a process of its own (pytest keeps its own hook for dropped exceptions): the stop lands in a destructor,
    Python drops it without a word, and the next atomic write raises it instead of writing."""
    script = (
        "import os, signal, sys, time\n"
        "from taskseq.runtime import stopping\n"
        "from taskseq.runtime.atomic import write_text_atomic\n"
        "stopping.install()\n"
        "class LandsInADestructor:\n"
        "    def __del__(self):\n"
        "        os.kill(os.getpid(), signal.SIGINT)\n"
        "        time.sleep(0.1)\n"
        "LandsInADestructor()\n"
        "print('ran on')\n"
        "try:\n"
        "    write_text_atomic(sys.argv[1], 'written')\n"
        "except KeyboardInterrupt:\n"
        "    sys.exit(130)\n")
    out = tmp_path / "out.txt"
    done = subprocess.run([sys.executable, "-c", script, str(out)], capture_output=True, text=True,
                          preexec_fn=_default_sigint, timeout=120)
    assert (done.returncode, done.stdout) == (130, "ran on\n"), done.stderr
    assert "Traceback" not in done.stderr and "Exception ignored" not in done.stderr, done.stderr
    assert not out.exists()


def test_a_stop_inside_a_constructor_ends_with_one_line_and_no_destructor_traceback(tmp_path):
    """Ctrl-C landing in Numba's compiler leaves an llvmlite object half built, whose destructor then fails
    ("Exception ignored ... AttributeError") as the stop's traceback is freed: the command still says one line."""
    script = (
        "import os, signal, sys, time\n"
        "from taskseq import cli\n"
        "from taskseq.tool_commands import TOOLS, Tool\n"
        "class HalfBuilt:\n"
        "    def __init__(self):\n"
        "        os.kill(os.getpid(), signal.SIGINT)\n"
        "        time.sleep(0.1)\n"
        "        self.handle = 'set once built'\n"
        "    def __del__(self):\n"
        "        del self.handle\n"
        "def run(args):\n"
        "    HalfBuilt()\n"
        "    return 0\n"
        "TOOLS['cache'] = Tool(TOOLS['cache'].help, TOOLS['cache'].options, run)\n"
        "sys.exit(cli.main(['cache', sys.argv[1]]))\n")
    done = subprocess.run([sys.executable, "-c", script, str(tmp_path)], capture_output=True, text=True,
                          preexec_fn=_default_sigint, timeout=120)
    assert done.returncode == 130, done.stderr
    assert done.stderr == "taskseq cache: stopped by Ctrl-C; nothing was written\n"


def test_a_signal_while_the_run_is_being_opened_still_leaves_it_killed(handlers, tmp_path, monkeypatch):
    """A signal landing as the run's first record is sent: the run must end KILLED, not RUNNING or FAILED."""
    from taskseq.track import mlflow_runs

    monkeypatch.setenv("MLFLOW_TRACKING_URI", f"sqlite:///{tmp_path / 'mlflow.db'}")
    real_send = mlflow_runs._Channel.send

    def send_then_signal(self, message):
        real_send(self, message)
        if message["op"] == "start":
            os.kill(os.getpid(), signal.SIGTERM)  # lands as the run is opened, before the stage's block is entered
            time.sleep(0.1)

    monkeypatch.setattr(mlflow_runs._Channel, "send", send_then_signal)
    reached = []
    with pytest.raises(handlers.Stopped), mlflow_runs.stage_run("fold_models", {}) as run:
        reached.append(run)
    assert not reached  # the stage's work never started
    with sqlite3.connect(tmp_path / "mlflow.db") as conn:  # written whole before the stage's exception leaves
        assert conn.execute("select name, status from runs").fetchall() == [("fold_models", "KILLED")]


def test_a_stage_killed_outright_leaves_no_run_running(data, tmp_path):
    """SIGKILL gives the stage no chance to say how its run ends; the writer, seeing it go, says KILLED."""
    db = tmp_path / "mlflow.db"
    env = {**os.environ, "MLFLOW_TRACKING_URI": f"sqlite:///{db}", "TASKSEQ_N_JOBS": "1"}
    said = tmp_path / "out"
    with said.open("w") as sh:
        proc = subprocess.Popen([sys.executable, "-u", "-m", "taskseq.cli", "fold_models", "--features",
                                 str(data / "features"), "--processed", str(data / "processed"), "--output",
                                 str(tmp_path / "store")], env=env, stdout=sh, stderr=subprocess.DEVNULL)
        while proc.poll() is None and not _working(said):
            time.sleep(0.2)
        assert proc.poll() is None, "the stage ended before it could be stopped"
        proc.kill()
        proc.wait()
    # the writer serves on after the stage is gone; its answer comes in its own time
    runs = []
    for _ in range(600):
        if db.exists():
            with sqlite3.connect(db) as conn:
                if conn.execute("select 1 from sqlite_master where name = 'runs'").fetchall():
                    runs = conn.execute("select name, status from runs").fetchall()
        if runs and runs != [("fold_models", "RUNNING")]:
            break
        time.sleep(0.1)
    assert runs == [("fold_models", "KILLED")]
