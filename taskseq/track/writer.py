"""The process that writes the stages' MLflow runs: started by the first stage, kept by the next ones.

Importing MLflow and opening its SQLite store take about 2.5 s, longer than
most stages' own work, and a pipeline runs a dozen stages back to back. So
stages do not open the store themselves: a stage connects to this process
over a Unix socket (one per store, in a folder only this user can enter),
sends what to record as JSON lines and goes on with its work, and at its end
waits until everything it sent is written. The first stage to find no writer
starts one; it stays while stages keep coming and leaves after `IDLE` seconds
without any, so the next `dvc repro` of a stage, or the next stage of one,
finds it ready.

A stage names its runs by numbers of its own (0 is the stage's run) and sends
the times it saw, so the runs' times are the stage's. The writer is in a
session of its own and ignores Ctrl-C and SIGTERM: the stage handles them and
sends the ends of its runs as KILLED. When a stage's connection ends before
it said so (SIGKILL, a crash), the writer closes every run of it still open
as KILLED, so no run is left RUNNING. A write the store refuses is reported
to the stage, which then fails with the store's message.

Run as `python -m taskseq.track.writer TRACKING_URI` (what a stage does).
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import signal
import socket
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

EXPERIMENT = "taskseq"
# The experiment shows its runs table when opened, not the GenAI traces page (MLflow 3 infers a kind otherwise).
EXPERIMENT_KIND = {"mlflow.experimentKind": "custom_model_development"}
BATCH = 1000  # MLflow takes at most 1000 metrics per batch
IDLE = 20.0  # seconds without any stage after which the writer leaves


def address(uri: str) -> Path:
    """The socket of the writer for `uri`: one per store, per Python and per version of this file."""
    version = hashlib.md5(Path(__file__).read_bytes()).hexdigest()
    tag = hashlib.md5(f"{uri}\0{sys.executable}\0{version}".encode()).hexdigest()[:16]
    return _private_folder() / f"{tag}.sock"


def _private_folder() -> Path:
    folder = Path(tempfile.gettempdir()) / f"taskseq-writer-{os.getuid()}"
    folder.mkdir(mode=0o700, exist_ok=True)
    if folder.stat().st_uid != os.getuid() or folder.stat().st_mode & 0o077:
        raise PermissionError(f"{folder}: not a folder of this user's alone; remove it")
    return folder


class RunWriter:
    """Applies one stage's messages to the store, in order."""

    def __init__(self, client: Any, experiment: str) -> None:
        self.client = client
        self.experiment = experiment
        self.runs: dict[int, str] = {}  # the stage's number of a run -> MLflow's run id
        self.open: list[int] = []  # runs started and not ended, oldest first

    def apply(self, m: dict[str, Any]) -> None:
        from mlflow.entities import Metric, Param

        op, ref = m["op"], m["run"]
        if op == "start":
            tags = dict(m["tags"])
            if m.get("parent") is not None:
                tags["mlflow.parentRunId"] = self.runs[m["parent"]]
            run = self.client.create_run(self.experiment, start_time=m["time"], tags=tags, run_name=m["name"])
            self.runs[ref] = run.info.run_id
            self.open.append(ref)
            return
        run_id = self.runs[ref]
        if op == "params":
            params = [Param(k, v) for k, v in m["values"].items()]
            for start in range(0, len(params), 100):  # MLflow takes at most 100 params per batch
                self.client.log_batch(run_id, params=params[start : start + 100], synchronous=True)
        elif op in ("metrics", "curve"):
            if op == "metrics":
                points = [Metric(k, float(v), m["time"], m.get("step") or 0) for k, v in m["values"].items()]
            else:
                points = [Metric(k, float(v), m["time"], step) for k, values in m["series"].items()
                          for step, v in enumerate(values)]
            for start in range(0, len(points), BATCH):
                self.client.log_batch(run_id, metrics=points[start : start + BATCH], synchronous=True)
        elif op == "artifact":
            self.client.log_artifact(run_id, m["path"], artifact_path=m.get("folder"))
        elif op == "table":
            self.client.log_table(run_id, data=m["data"], artifact_file=m["name"])
        elif op == "end":
            self.client.set_terminated(run_id, status=m["status"], end_time=m["time"])
            self.open.remove(ref)
        else:
            raise ValueError(f"unknown message {op!r}")

    def close_open(self, status: str = "KILLED") -> None:
        """End every run still open, children first: KILLED when the stage stopped without saying so."""
        now = int(time.time() * 1000)
        for ref in reversed(self.open):
            self.client.set_terminated(self.runs[ref], status=status, end_time=now)
        self.open.clear()


class _Store:
    """The MLflow client, opened once (in the background, while the first stage already sends)."""

    def __init__(self, uri: str) -> None:
        self.uri = uri
        self.ready = threading.Event()
        self.lock = threading.Lock()  # one write at a time: SQLite takes one writer
        self.client: Any = None
        self.experiment = ""
        self.error: str | None = None

    def open(self) -> None:
        try:
            from mlflow.tracking import MlflowClient

            self.client = MlflowClient(tracking_uri=self.uri)
            exp = self.client.get_experiment_by_name(EXPERIMENT)
            if exp is not None:
                self.experiment = exp.experiment_id
            else:
                artifacts = None
                if self.uri.startswith("sqlite:///"):
                    artifacts = (Path(self.uri[len("sqlite:///") :]).parent / "mlartifacts").resolve().as_uri()
                self.experiment = self.client.create_experiment(EXPERIMENT, artifact_location=artifacts,
                                                                tags=EXPERIMENT_KIND)
        except Exception as err:  # every stage that connects is told
            self.error = f"MLflow store {self.uri}: {type(err).__name__}: {err}"
        finally:
            self.ready.set()


class _Server:
    def __init__(self, uri: str) -> None:
        self.store = _Store(uri)
        self.active = 0
        self.last = time.monotonic()
        self.guard = threading.Lock()

    def serve_connection(self, conn: socket.socket) -> None:
        """One stage's session; the accepting loop has counted it in `active`."""
        try:
            self._session(conn)
        finally:
            conn.close()
            with self.guard:
                self.active -= 1
                self.last = time.monotonic()

    def _session(self, conn: socket.socket) -> None:
        stream = conn.makefile("rwb")
        stream.write(b"ready\n")  # the stage sends nothing before this: it is served to the end
        stream.flush()
        self.store.ready.wait()
        writer = None if self.store.error else RunWriter(self.store.client, self.store.experiment)
        error = self.store.error
        closed = False
        for line in stream:
            m = json.loads(line)
            if m["op"] == "close":
                closed = True
                break
            if error is None:
                try:
                    with self.store.lock:
                        writer.apply(m)
                except Exception as err:
                    error = f"MLflow store {self.store.uri}: {type(err).__name__}: {err}"
        if writer is not None:
            try:
                with self.store.lock:
                    writer.close_open("KILLED" if error is None else "FAILED")
            except Exception as err:
                error = error or f"MLflow store {self.store.uri}: {type(err).__name__}: {err}"
        if closed:
            stream.write(b"ok\n" if error is None else f"error: {error}\n".encode())
            stream.flush()


def serve(uri: str) -> int:
    """Serve stages for `uri` until none has come for `IDLE` seconds; 0 at once if another writer serves it."""
    path = address(uri)
    lock = open(path.with_suffix(".lock"), "w")  # noqa: SIM115 - held for the writer's whole life
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return 0  # another writer holds this store: the stage connects to it
    path.unlink(missing_ok=True)  # left by a writer that was killed
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    listener.bind(str(path))
    listener.listen(64)
    listener.settimeout(0.5)
    server = _Server(uri)
    threading.Thread(target=server.store.open, daemon=True).start()
    while True:
        try:
            conn, _ = listener.accept()
        except TimeoutError:
            with server.guard:
                if server.active == 0 and time.monotonic() - server.last > IDLE:
                    break
            continue
        conn.settimeout(None)
        with server.guard:  # counted here, before the idle check can run again
            server.active += 1
        threading.Thread(target=server.serve_connection, args=(conn,), daemon=True).start()
    path.unlink(missing_ok=True)  # under the lock: a stage arriving now starts a new writer
    listener.close()
    return 0


class Connection:
    """A stage's line to the writer of its store; starts the writer when there is none."""

    def __init__(self, uri: str, wait: float = 60.0) -> None:
        path = address(uri)
        started, spawned = None, 0.0
        deadline = time.monotonic() + wait
        while True:
            sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            try:
                sock.connect(str(path))
                stream = sock.makefile("rwb")
                ready = stream.readline() == b"ready\n"
            except (FileNotFoundError, ConnectionRefusedError, ConnectionResetError, BrokenPipeError):
                ready = False  # no writer yet, or one that was leaving as this stage came
            if ready:
                self.sock, self.stream = sock, stream
                return
            sock.close()
            # none listens yet: start one (again, should the last one have found the store taken and left)
            if (started is None or started.poll() is not None) and time.monotonic() - spawned > 0.5:
                started, spawned = _start_writer(uri), time.monotonic()
            if time.monotonic() > deadline:
                raise ConnectionError(f"no MLflow writer answered on {path} within {wait:g} s")
            time.sleep(0.02)

    def send(self, line: bytes) -> None:
        self.stream.write(line)
        self.stream.flush()

    def close(self) -> str:
        """Wait until everything sent is written; returns `ok` or the writer's error line."""
        self.send(b'{"op": "close", "run": null}\n')
        reply = self.stream.readline().decode().strip() or "error: the MLflow writer closed the connection"
        self.sock.close()
        return reply


def _start_writer(uri: str):
    import subprocess

    # the writer runs this very package, wherever it was imported from
    root = str(Path(__file__).resolve().parents[2])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH")) if p)}
    return subprocess.Popen([sys.executable, "-m", "taskseq.track.writer", uri], env=env,
                            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)


def main(argv: list[str] | None = None) -> int:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the stages handle the signals and say how their runs end
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    (uri,) = argv if argv is not None else sys.argv[1:]
    return serve(uri)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
