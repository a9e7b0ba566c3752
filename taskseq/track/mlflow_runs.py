"""One MLflow run per stage execution, child runs per method, noise rate or condition.

The embedded default is a SQLite store, `mlflow.db` at the repository root,
with artifacts in `mlartifacts/` beside it. The root is DVC's `DVC_ROOT` when
DVC runs the stage (queued experiments run in temporary copies of the
repository, and DVC points `DVC_ROOT` back at the original, so their runs land
in the same store), else the nearest folder at or above the working folder
that holds a `.dvc` folder. Outside such a project a stage run by hand records
nothing and says so, since a command run by hand writes only where it is told.
`MLFLOW_TRACKING_URI` points the runs at a team's server instead.

DVC's lock file records what produced the files; a run records one execution:
its parameters, metrics, artifacts and tags (git commit and whether the tree
had uncommitted changes, the lock files it started from, DVC stage, input
hash). A stage that fails leaves its run FAILED; one stopped by Ctrl-C or
SIGTERM leaves it KILLED.

A separate process writes the store (`track.writer`), and stays for the
next stage: a stage sends it messages and waits for it only at its end, so
MLflow's start-up (about 2.5 s) is paid once per pipeline, not per stage.
Sending a message is never broken off half way (`stopping.held`), and the
writer ignores the signals, so a stopped stage's records are whole and its
runs end KILLED.
"""

from __future__ import annotations

import getpass
import hashlib
import json
import os
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from ..runtime.dvc_deps import pipeline_files
from ..runtime.stopping import held
from .writer import EXPERIMENT, Connection

__all__ = ["EXPERIMENT", "NO_RUN", "StageRun", "Tracker", "TrackingFailed", "stage_run", "tracked", "tracking_uri"]


def project_folder() -> Path | None:
    """The DVC project the working folder is in: its nearest folder, at or above it, that holds `.dvc`."""
    here = Path.cwd().resolve()
    return next((folder for folder in (here, *here.parents) if (folder / ".dvc").is_dir()), None)


def repository_root() -> Path | None:
    """Where the store lives: DVC's repository root while DVC runs a stage (the original repository, for a queued
    experiment run in a copy), else the project the working folder is in (`project_folder`), else None."""
    if os.environ.get("DVC_ROOT"):
        return Path(os.environ["DVC_ROOT"]).resolve()
    return project_folder()


def tracking_uri() -> str | None:
    """The store runs go to: `MLFLOW_TRACKING_URI`, else `mlflow.db` at the repository root, else None."""
    if os.environ.get("MLFLOW_TRACKING_URI"):
        return os.environ["MLFLOW_TRACKING_URI"]
    root = repository_root()
    return None if root is None else f"sqlite:///{root / 'mlflow.db'}"


def _git(*args: str) -> str | None:
    try:
        out = subprocess.run(["git", *args], capture_output=True, text=True, check=True, timeout=10)
        return out.stdout
    except (OSError, subprocess.SubprocessError):
        return None


def git_commit() -> str:
    out = _git("rev-parse", "HEAD")
    return out.strip() if out else "unknown"


def provenance(stage: str, inputs: list[Path]) -> dict[str, str]:
    """Tags that say what a run started from: commit, uncommitted changes, lock file, stage, inputs."""
    status = _git("status", "--porcelain", "--untracked-files=no")
    return {"git.commit": git_commit(), "git.dirty": "unknown" if status is None else str(bool(status.strip())).lower(),
            # the locks of the project the stage runs in (a queued experiment's copy has its own)
            "dvc.lock.md5": locks_md5(project_folder() or Path(".")),
            "dvc.stage": os.environ.get("DVC_STAGE") or stage, "data.hash": hash_inputs(inputs)}


def locks_md5(root: Path = Path(".")) -> str:
    """md5 of the pipeline's lock files under `root`: dvc.lock's bytes, then the path and bytes of the lock beside
    each part's dvc.yaml (`dvc_deps.pipeline_files`), so with no parts it is dvc.lock's own md5; "none" without
    dvc.lock."""
    lock, *parts = (f.with_name("dvc.lock") for f in pipeline_files(root))
    if not lock.exists():
        return "none"
    h = hashlib.md5(lock.read_bytes())
    for part in (p for p in parts if p.exists()):
        h.update(b"\0" + part.relative_to(root).as_posix().encode() + b"\0" + part.read_bytes())
    return h.hexdigest()


def hash_inputs(paths: list[Path]) -> str:
    """md5 over the names and bytes of every file under the given paths (what the stage read)."""
    h = hashlib.md5()
    for root in sorted(Path(p) for p in paths):
        files = sorted(f for f in root.rglob("*") if f.is_file()) if root.is_dir() else [root]
        for f in files:
            if f.exists():
                h.update(str(f.relative_to(root.parent)).encode())
                h.update(f.read_bytes())
    return h.hexdigest()


def flatten(d: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flatten(v, f"{key}."))
        else:
            out[key] = v
    return out


class TrackingFailed(RuntimeError):
    """The writer could not record the stage's runs; the message carries the store's reason."""


def _plain(value: Any) -> Any:
    """JSON for what stages log besides plain Python values: NumPy scalars and arrays, paths."""
    if hasattr(value, "tolist"):
        return value.tolist()
    return str(value)


class _Channel:
    """A stage's connection to the writer of its store (`track.writer`), and the runs opened through it."""

    def __init__(self, uri: str) -> None:
        try:
            self._conn = Connection(uri)
        except (ConnectionError, OSError) as err:
            raise TrackingFailed(f"its MLflow run cannot be recorded: {err}") from None
        self._refs = 0
        self._broken = False

    def new_ref(self) -> int:
        ref, self._refs = self._refs, self._refs + 1
        return ref

    def send(self, message: dict[str, Any]) -> None:
        if self._broken:
            return
        line = (json.dumps(message, default=_plain) + "\n").encode()
        with held():
            try:
                self._conn.send(line)
            except OSError:  # the writer is gone; `close` says so
                self._broken = True

    def close(self) -> None:
        """Wait until the writer has recorded everything sent; raises `TrackingFailed` if it could not."""
        with held():
            try:
                reply = self._conn.close()
            except OSError as err:
                reply = f"error: the MLflow writer's connection broke ({err})"
        if reply != "ok":
            raise TrackingFailed(f"{reply.removeprefix('error: ')}; its run is not recorded whole")


def _now() -> int:
    return int(time.time() * 1000)


class StageRun:
    """What a stage logs into its run; `labels` (e.g. the world seed) go to every child run as params.

    Each call sends one message to the writer process and returns at once.
    """

    def __init__(self, channel: _Channel, ref: int, labels: dict[str, Any] | None = None) -> None:
        self._channel = channel
        self._ref = ref
        self._labels = labels or {}

    def _send(self, op: str, **fields: Any) -> None:
        self._channel.send({"op": op, "run": self._ref, **fields})

    def metrics(self, values: dict[str, float | None], step: int | None = None) -> None:
        clean = {k.replace("/", "_"): float(v) for k, v in values.items() if v is not None}
        if clean:
            self._send("metrics", values=clean, step=step, time=_now())

    def params(self, values: dict[str, Any]) -> None:
        if values:
            self._send("params", values={k: str(v)[:500] for k, v in values.items()})

    def artifact(self, path: Path | str, folder: str | None = None) -> None:
        if Path(path).exists():
            self._send("artifact", path=str(Path(path).resolve()), folder=folder)

    def table(self, rows: list[dict[str, Any]], name: str) -> None:
        """Rows as an MLflow table artifact (`name`.json), which the UI's artifact view shows as a table."""
        if rows:
            columns = list(rows[0])
            self._send("table", data={c: [r.get(c) for r in rows] for c in columns}, name=f"{name}.json")

    def curve(self, series: dict[str, list[float]]) -> None:
        """Per-step values (e.g. the SSVM's objective and gap per iteration) as metric histories."""
        self._send("curve", series={k: [float(v) for v in values] for k, values in series.items()}, time=_now())

    def _start(self, name: str, tags: dict[str, str], parent: int | None) -> None:
        self._send("start", name=name, tags={**_source_tags(name), **tags}, parent=parent, time=_now())

    @contextmanager
    def child(self, name: str, params: dict[str, Any] | None = None) -> Iterator[StageRun]:
        child = StageRun(self._channel, self._channel.new_ref(), self._labels)
        # a signal that lands here leaves the child open, and the writer closes it as KILLED
        child._start(name, {"taskseq.child": name}, parent=self._ref)
        with _ending(child):
            child.params({**self._labels, **(params or {})})
            yield child


class NoRun:
    """What a stage logs when nothing is recorded (`--no-mlflow`, or library use): it is dropped."""

    def metrics(self, values: dict[str, float | None], step: int | None = None) -> None:
        """Metrics are dropped."""

    def params(self, values: dict[str, Any]) -> None:
        """Parameters are dropped."""

    def artifact(self, path: Path | str, folder: str | None = None) -> None:
        """The file stays where the stage wrote it; nothing is copied."""

    def table(self, rows: list[dict[str, Any]], name: str) -> None:
        """The table is dropped."""

    def curve(self, series: dict[str, list[float]]) -> None:
        """The curve is dropped."""

    @contextmanager
    def child(self, name: str, params: dict[str, Any] | None = None) -> Iterator[NoRun]:
        yield self


Tracker = StageRun | NoRun
NO_RUN = NoRun()


def _source_tags(name: str) -> dict[str, str]:
    """What MLflow's own runs say of where they came from, so the UI's User and Source columns are filled."""
    return {"mlflow.user": getpass.getuser(), "mlflow.source.name": f"taskseq {name}",
            "mlflow.source.type": "LOCAL"}


@contextmanager
def stage_run(stage: str, params: dict[str, Any], inputs: list[Path] | None = None,
              labels: dict[str, Any] | None = None) -> Iterator[StageRun]:
    """Open the stage's run with the settings in force and its command line as parameters, tags for provenance.

    The run goes through the store's writer process (started if there is
    none); leaving the block waits until every record is written.
    """
    channel, failed = None, True
    try:
        # opened whole; a signal held here leaves the run open, which the writer then closes as KILLED
        with held():
            uri = tracking_uri()
            if uri is None:
                raise TrackingFailed("no store to record into: not inside a DVC project and MLFLOW_TRACKING_URI "
                                     "is not set")
            channel = _Channel(uri)
            run = StageRun(channel, channel.new_ref(), labels)
            tags = provenance(stage, inputs or [])
            run._start(stage, {**tags, "mlflow.source.git.commit": tags["git.commit"]}, parent=None)
        with _ending(run):
            run.params(params)
            yield run
        failed = False
    finally:
        try:
            if channel is not None:
                channel.close()
        except TrackingFailed:
            if not failed:  # a stage that failed or was stopped says so itself
                raise


@contextmanager
def _ending(run: StageRun) -> Iterator[None]:
    """End the run as its block ends: FINISHED, FAILED on an error, KILLED on Ctrl-C or SIGTERM."""
    try:
        yield
    except KeyboardInterrupt:  # Ctrl-C, or SIGTERM (`stopping.Stopped`)
        run._send("end", status="KILLED", time=_now())  # sending is held whole (`_Channel.send`)
        raise
    except BaseException:
        run._send("end", status="FAILED", time=_now())
        raise
    run._send("end", status="FINISHED", time=_now())


class _StageFailed(Exception):
    def __init__(self, code: int) -> None:
        super().__init__(f"stage ended with exit code {code}")
        self.code = code


def tracked(stage: str, params: dict[str, Any], inputs: list[Path], labels: dict[str, Any] | None,
            body: Callable[[Tracker], int]) -> int:
    """Run `body` inside the stage's MLflow run: its exit code, the run FAILED when that is not 0.

    When the store cannot record the run, the outputs are written all the
    same, and the stage says so and exits with 1. Outside a DVC project, with
    no `MLFLOW_TRACKING_URI`, there is no store: `body` runs unrecorded, and the
    stage says so before it starts.
    """
    if tracking_uri() is None:
        print("note: this run is not recorded in MLflow: no DVC project here or above (no .dvc folder) and "
              "MLFLOW_TRACKING_URI is not set", file=sys.stderr)
        return body(NO_RUN)
    try:
        with stage_run(stage, params, inputs, labels) as run:
            code = body(run)
            if code:
                raise _StageFailed(code)  # the run is marked FAILED on the way out
    except _StageFailed as failed:
        return failed.code
    except TrackingFailed as err:
        print(f"error: taskseq {stage}: {err}", file=sys.stderr)
        return 1
    return 0
