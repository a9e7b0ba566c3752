"""One MLflow run per stage execution, child runs per method, noise rate or condition.

The embedded default is a SQLite store, `sqlite:///mlflow.db` in the working
folder (the repository root under DVC), with artifacts in `mlartifacts/`
beside it; `MLFLOW_TRACKING_URI` points the runs at a team's server instead.
DVC's lock file records what produced the files; a run records one execution:
its parameters, metrics, artifacts and tags (git commit, DVC stage, input hash).
A stage that fails leaves its run marked FAILED.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import yaml

EXPERIMENT = "taskseq"


def tracking_uri() -> str:
    return os.environ.get("MLFLOW_TRACKING_URI") or f"sqlite:///{Path('mlflow.db').resolve()}"


def git_commit() -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=True, timeout=10)
        return out.stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"


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
    return client.create_experiment(EXPERIMENT, artifact_location=artifacts)


class StageRun:
    """What a stage logs into its run."""

    def __init__(self, mlflow_module) -> None:
        self._mlflow = mlflow_module

    def metrics(self, values: dict[str, float | None], step: int | None = None) -> None:
        clean = {k.replace("/", "_"): float(v) for k, v in values.items() if v is not None}
        if clean:
            self._mlflow.log_metrics(clean, step=step)

    def params(self, values: dict[str, Any]) -> None:
        self._mlflow.log_params({k: str(v)[:500] for k, v in values.items()})

    def artifact(self, path: Path | str, folder: str | None = None) -> None:
        if Path(path).exists():
            self._mlflow.log_artifact(str(path), artifact_path=folder)

    @contextmanager
    def child(self, name: str, params: dict[str, Any] | None = None) -> Iterator[StageRun]:
        with self._mlflow.start_run(run_name=name, nested=True, tags={"taskseq.child": name}):
            child = StageRun(self._mlflow)
            if params:
                child.params(params)
            yield child


class NoRun:
    """What a stage logs when nothing is recorded (`--no-mlflow`, or library use): it is dropped."""

    def metrics(self, values: dict[str, float | None], step: int | None = None) -> None:
        """Metrics are dropped."""

    def params(self, values: dict[str, Any]) -> None:
        """Parameters are dropped."""

    def artifact(self, path: Path | str, folder: str | None = None) -> None:
        """The file stays where the stage wrote it; nothing is copied."""

    @contextmanager
    def child(self, name: str, params: dict[str, Any] | None = None) -> Iterator[NoRun]:
        yield self


Tracker = StageRun | NoRun
NO_RUN = NoRun()


@contextmanager
def stage_run(stage: str, params: dict[str, Any], inputs: list[Path] | None = None) -> Iterator[StageRun]:
    """Open the stage's run; parameters from params.yaml and the command line, tags for provenance."""
    import mlflow

    mlflow.set_tracking_uri(tracking_uri())
    client = mlflow.MlflowClient()
    tags = {"git.commit": git_commit(), "dvc.stage": stage, "data.hash": hash_inputs(inputs or [])}
    experiment = _experiment_id(client)
    mlflow.set_experiment(experiment_id=experiment)  # child runs land in the same experiment
    with mlflow.start_run(experiment_id=experiment, run_name=stage, tags=tags):
        run = StageRun(mlflow)
        run.params({**params_yaml(), **{f"cli.{k}": v for k, v in params.items()}})
        yield run
