"""Shared fixtures: small hand-built worlds and the generated benchmark."""

from __future__ import annotations

from pathlib import Path

import pytest

import taskseq.methods  # noqa: F401  (the built-in methods; an added one registers when a test asks for it)
from taskseq.demonstrations.generate import generate
from taskseq.demonstrations.ingest import load_logs
from taskseq.settings import Generate
from taskseq.sim.catalog import EnvironmentSpec, Placement, build_environment
from taskseq.sim.state import WorldState

# The test files that take longest (each tens of seconds on 2 idle cores, `--durations`), slowest first. They are
# collected first, and pytest-xdist hands files to its workers in collection order (`--no-loadscope-reorder` in
# pyproject.toml): the long files start at once and the short ones fill in around them, so the workers end
# together. Only the order changes, never what runs.
SLOWEST_FIRST = ("test_scenes.py", "test_track.py", "test_scaling.py", "test_sweeps.py", "test_stage_runs.py",
                 "test_fold_models.py", "test_ingest.py", "test_signals.py", "test_stages.py", "test_lookahead.py",
                 "test_lockstep.py", "test_processor_independence.py", "test_serve_browser.py", "test_extending.py",
                 "test_feasible.py")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    rank = {name: i for i, name in enumerate(SLOWEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: a file's tests keep their order


def world(furniture: dict[int, float], items: list[tuple], robot_x: float = 0.0) -> WorldState:
    """A hand-built environment from catalog objects: items are (obj, on, level, dx[, back])."""
    placements = tuple(
        Placement(f"obj{i[0]:02d}", f"obj{i[1]:02d}", *(i[2:] if len(i) > 2 else ())) for i in items
    )
    spec = EnvironmentSpec("test", tuple((f"obj{k:02d}", x) for k, x in furniture.items()), placements, robot_x)
    return build_environment(spec)


@pytest.fixture(scope="session", autouse=True)
def mlflow_store(tmp_path_factory: pytest.TempPathFactory):
    """Stages run by tests record into a throwaway MLflow store, never the repository's."""
    import os

    store = tmp_path_factory.mktemp("mlflow") / "mlflow.db"
    old = os.environ.get("MLFLOW_TRACKING_URI")
    os.environ["MLFLOW_TRACKING_URI"] = f"sqlite:///{store}"
    yield os.environ["MLFLOW_TRACKING_URI"]
    if old is None:
        del os.environ["MLFLOW_TRACKING_URI"]
    else:
        os.environ["MLFLOW_TRACKING_URI"] = old


@pytest.fixture(scope="session")
def benchmark_logs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("bench") / "raw"
    generate(Generate(seed=0), out)
    return out


@pytest.fixture(scope="session")
def benchmark_tables(benchmark_logs: Path):
    return load_logs(benchmark_logs)


@pytest.fixture(scope="session")
def benchmark_steps(benchmark_tables):
    """Teacher-forced steps (StepContext, StepMeta) of the whole benchmark."""
    from taskseq.features.dataset import build_steps

    return build_steps([item.record for item in benchmark_tables[1]])
