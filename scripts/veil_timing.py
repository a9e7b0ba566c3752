"""Where the VEIL pipeline's time goes, read from its last MLflow runs: `reports/veil_timing.json`.

Run after `dvc repro veil/dvc.yaml` on a quiet machine:

    python scripts/veil_timing.py --output reports/veil_timing.json

Each stage's wall time is its MLflow run's (`veil-import`, `veil-evaluate`, `veil-train`, the latest of
each); the evaluation's child runs give each method's seconds summed over its folds, which run in
parallel, so they add up to more than the stage's wall time. The docs render the file (`docs/hooks.py`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from taskseq.bench.machine import machine
from taskseq.runtime.atomic import write_json_atomic

STAGES = ("veil-import", "veil-evaluate", "veil-train")


def latest(client, experiments: list[str], name: str):
    runs = client.search_runs(experiments, f"tags.mlflow.runName = '{name}' and attributes.status = 'FINISHED'",
                              order_by=["attributes.start_time DESC"], max_results=1)
    if not runs:
        raise SystemExit(f"error: no finished MLflow run named {name!r}: run `dvc repro veil/dvc.yaml` first")
    return runs[0]


def timing(tracking_uri: str) -> dict:
    from mlflow.tracking import MlflowClient

    client = MlflowClient(tracking_uri)
    experiments = [e.experiment_id for e in client.search_experiments()]
    stages, methods = {}, {}
    for name in STAGES:
        run = latest(client, experiments, name)
        stages[name.removeprefix("veil-")] = (run.info.end_time - run.info.start_time) / 1000
        if name == "veil-evaluate":
            children = client.search_runs(experiments, f"tags.mlflow.parentRunId = '{run.info.run_id}'")
            methods = {c.info.run_name: c.data.metrics["seconds"] for c in children if "seconds" in c.data.metrics}
    return {"command": "dvc repro veil/dvc.yaml", "stages": stages, "total": sum(stages.values()),
            "evaluate_methods": dict(sorted(methods.items(), key=lambda kv: -kv[1])),
            "machine": machine()}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--tracking-uri", default="sqlite:///mlflow.db", help="the MLflow store (default: the "
                        "pipeline's, sqlite:///mlflow.db)")
    parser.add_argument("--output", type=Path, required=True, help="JSON file to write (replaced)")
    args = parser.parse_args()
    report = timing(args.tracking_uri)
    write_json_atomic(args.output, report)
    stages = ", ".join(f"{k} {v:.0f} s" for k, v in report["stages"].items())
    print(f"{args.output}: {report['total']:.0f} s in all ({stages})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
