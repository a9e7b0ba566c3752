"""One MLflow run per stage execution, child runs per method, noise rate or condition.

The embedded default is a SQLite store, `mlflow.db` at the repository root,
with artifacts in `mlartifacts/` beside it. The root is DVC's `DVC_ROOT` when
DVC runs the stage (queued experiments run in temporary copies of the
repository, and DVC points `DVC_ROOT` back at the original, so their runs land
in the same store), else the working folder. `MLFLOW_TRACKING_URI` points the
runs at a team's server instead.

DVC's lock file records what produced the files; a run records one execution:
its parameters, metrics, artifacts and tags (git commit and whether the tree
had uncommitted changes, the `dvc.lock` it started from, DVC stage, input
hash). A stage that fails leaves its run FAILED; one stopped by Ctrl-C or
SIGTERM leaves it KILLED. Every write to the store is made whole
(`stopping.held`): a signal that lands while a run is being opened, logged to
or closed takes effect once that write is done.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import yaml

from ..stopping import held

EXPERIMENT = "taskseq"


# The experiment shows its runs table when opened, not the GenAI traces page (MLflow 3 infers a kind otherwise).
EXPERIMENT_KIND = {"mlflow.experimentKind": "custom_model_development"}


def repository_root() -> Path:
    """Where the store lives: DVC's repository root while DVC runs a stage, else the working folder."""
    return Path(os.environ.get("DVC_ROOT") or ".").resolve()


def tracking_uri() -> str:
    return os.environ.get("MLFLOW_TRACKING_URI") or f"sqlite:///{repository_root() / 'mlflow.db'}"


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
    lock = Path("dvc.lock")
    return {"git.commit": git_commit(), "git.dirty": "unknown" if status is None else str(bool(status.strip())).lower(),
            "dvc.lock.md5": hashlib.md5(lock.read_bytes()).hexdigest() if lock.exists() else "none",
            "dvc.stage": os.environ.get("DVC_STAGE") or stage, "data.hash": hash_inputs(inputs)}


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


def params_yaml(path: Path = Path("params.yaml")) -> dict[str, Any]:
    return flatten(yaml.safe_load(path.read_text())) if path.exists() else {}


def _experiment_id(client) -> str:
    exp = client.get_experiment_by_name(EXPERIMENT)
    if exp is not None:
        return exp.experiment_id
    artifacts = None
    if tracking_uri().startswith("sqlite:///"):
        artifacts = (Path(tracking_uri()[len("sqlite:///") :]).parent / "mlartifacts").resolve().as_uri()
    return client.create_experiment(EXPERIMENT, artifact_location=artifacts, tags=EXPERIMENT_KIND)


class StageRun:
    """What a stage logs into its run; `labels` (e.g. the world seed) go to every child run as params."""

    def __init__(self, mlflow_module, labels: dict[str, Any] | None = None) -> None:
        self._mlflow = mlflow_module
        self._labels = labels or {}

    def metrics(self, values: dict[str, float | None], step: int | None = None) -> None:
        clean = {k.replace("/", "_"): float(v) for k, v in values.items() if v is not None}
        if clean:
            with held():
                self._mlflow.log_metrics(clean, step=step)

    def params(self, values: dict[str, Any]) -> None:
        if values:
            with held():
                self._mlflow.log_params({k: str(v)[:500] for k, v in values.items()})

    def artifact(self, path: Path | str, folder: str | None = None) -> None:
        if Path(path).exists():
            with held():
                self._mlflow.log_artifact(str(path), artifact_path=folder)

    def table(self, rows: list[dict[str, Any]], name: str) -> None:
        """Rows as an MLflow table artifact (`name`.json), which the UI's artifact view shows as a table."""
        if rows:
            columns = list(rows[0])
            with held():
                self._mlflow.log_table({c: [r.get(c) for r in rows] for c in columns}, artifact_file=f"{name}.json")

    def curve(self, series: dict[str, list[float]]) -> None:
        """Per-step values (e.g. the SSVM's objective and gap per iteration) as metric histories."""
        from mlflow.entities import Metric

        now = int(time.time() * 1000)
        points = [Metric(k, float(v), now, step) for k, values in series.items() for step, v in enumerate(values)]
        client, run_id = self._mlflow.MlflowClient(), self._mlflow.active_run().info.run_id
        for start in range(0, len(points), 1000):  # MLflow takes at most 1000 metrics per batch
            with held():
                client.log_batch(run_id, metrics=points[start : start + 1000], synchronous=True)

    @contextmanager
    def child(self, name: str, params: dict[str, Any] | None = None) -> Iterator[StageRun]:
        with _ending(self._mlflow, every=False):
            with held():  # a signal held here is raised inside `_ending`, which marks the run KILLED
                self._mlflow.start_run(run_name=name, nested=True, tags={"taskseq.child": name})
                child = StageRun(self._mlflow, self._labels)
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


@contextmanager
def stage_run(stage: str, params: dict[str, Any], inputs: list[Path] | None = None,
              labels: dict[str, Any] | None = None) -> Iterator[StageRun]:
    """Open the stage's run; parameters from params.yaml and the command line, tags for provenance."""
    import mlflow

    mlflow.set_tracking_uri(tracking_uri())
    client = mlflow.MlflowClient()
    experiment = _experiment_id(client)
    mlflow.set_experiment(experiment_id=experiment)  # child runs land in the same experiment
    with _ending(mlflow, every=True):
        with held():  # a signal held here is raised inside `_ending`, which marks the run KILLED
            mlflow.start_run(experiment_id=experiment, run_name=stage, tags=provenance(stage, inputs or []))
            run = StageRun(mlflow, labels)
            run.params({**params_yaml(), **{f"cli.{k}": v for k, v in params.items()}})
        yield run


@contextmanager
def _ending(mlflow_module, every: bool) -> Iterator[None]:
    """End the active run as its block ends: FINISHED, FAILED on an error, KILLED on Ctrl-C or SIGTERM.

    `every` ends the open child runs too (a stage's run, stopped while a child was open).
    """
    try:
        yield
    except KeyboardInterrupt:  # Ctrl-C, or SIGTERM (`stopping.Stopped`)
        with held():
            while mlflow_module.active_run() is not None:  # children first, then the stage's own run
                mlflow_module.end_run("KILLED")
                if not every:
                    break
        raise
    except BaseException:
        with held():
            mlflow_module.end_run("FAILED")
        raise
    with held():
        mlflow_module.end_run()
