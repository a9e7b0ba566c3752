"""The process that writes a stage's MLflow runs, beside the stage rather than inside it.

Importing MLflow and opening its SQLite store take about 2.5 s, longer than
most stages' own work, and a pipeline runs a dozen stages. So a stage starts
this process first thing and sends it what to record, one JSON message per
line on its standard input, and goes on with its work; the import and the
store's start-up run on the other core meanwhile. The stage waits for it at
the end, so a stage that has finished has its run written.

Messages name a run by a number the stage chose (0 is the stage's own run)
and carry the times the stage saw, so the runs' times are the stage's, not
this process's. The process ignores Ctrl-C and SIGTERM: the stage handles
them and sends the ends of its runs as KILLED. Should the stage die without
sending them (SIGKILL, a crash), the end of its input closes every run still
open as KILLED, so no run is left RUNNING.

Run as `python -m pipeline.track.writer TRACKING_URI`; exits 1 with one line
on standard error if the store refuses a write.
"""

from __future__ import annotations

import contextlib
import json
import queue
import signal
import sys
import threading
from pathlib import Path
from typing import Any

EXPERIMENT = "taskseq"
# The experiment shows its runs table when opened, not the GenAI traces page (MLflow 3 infers a kind otherwise).
EXPERIMENT_KIND = {"mlflow.experimentKind": "custom_model_development"}
BATCH = 1000  # MLflow takes at most 1000 metrics per batch


class RunWriter:
    """Applies the stage's messages to an MLflow store, in order."""

    def __init__(self, uri: str) -> None:
        from mlflow.tracking import MlflowClient

        self.client = MlflowClient(tracking_uri=uri)
        self.uri = uri
        self.runs: dict[int, str] = {}  # the stage's number of a run -> MLflow's run id
        self.open: list[int] = []  # runs started and not ended, oldest first
        self._experiment: str | None = None

    def experiment(self) -> str:
        if self._experiment is None:
            exp = self.client.get_experiment_by_name(EXPERIMENT)
            if exp is not None:
                self._experiment = exp.experiment_id
            else:
                artifacts = None
                if self.uri.startswith("sqlite:///"):
                    artifacts = (Path(self.uri[len("sqlite:///") :]).parent / "mlartifacts").resolve().as_uri()
                self._experiment = self.client.create_experiment(EXPERIMENT, artifact_location=artifacts,
                                                                 tags=EXPERIMENT_KIND)
        return self._experiment

    def apply(self, m: dict[str, Any]) -> None:
        from mlflow.entities import Metric, Param

        op, ref = m["op"], m["run"]
        if op == "start":
            tags = dict(m["tags"])
            if m.get("parent") is not None:
                tags["mlflow.parentRunId"] = self.runs[m["parent"]]
            run = self.client.create_run(self.experiment(), start_time=m["time"], tags=tags, run_name=m["name"])
            self.runs[ref] = run.info.run_id
            self.open.append(ref)
            return
        run_id = self.runs[ref]
        if op == "params":
            params = [Param(k, v) for k, v in m["values"].items()]
            for start in range(0, len(params), 100):  # MLflow takes at most 100 params per batch
                self.client.log_batch(run_id, params=params[start : start + 100], synchronous=True)
        elif op == "metrics":
            points = [Metric(k, float(v), m["time"], m.get("step") or 0) for k, v in m["values"].items()]
            self._metrics(run_id, points)
        elif op == "curve":
            points = [Metric(k, float(v), m["time"], step) for k, values in m["series"].items()
                      for step, v in enumerate(values)]
            self._metrics(run_id, points)
        elif op == "artifact":
            self.client.log_artifact(run_id, m["path"], artifact_path=m.get("folder"))
        elif op == "table":
            self.client.log_table(run_id, data=m["data"], artifact_file=m["name"])
        elif op == "end":
            self.client.set_terminated(run_id, status=m["status"], end_time=m["time"])
            self.open.remove(ref)
        else:
            raise ValueError(f"unknown message {op!r}")

    def _metrics(self, run_id: str, points: list) -> None:
        for start in range(0, len(points), BATCH):
            self.client.log_batch(run_id, metrics=points[start : start + BATCH], synchronous=True)

    def close_open(self, end_time: int, status: str = "KILLED") -> None:
        """End every run still open, children first: KILLED when the stage stopped without saying so."""
        for ref in reversed(self.open):
            self.client.set_terminated(self.runs[ref], status=status, end_time=end_time)
        self.open.clear()


def _read(stream, lines: queue.Queue) -> None:
    for line in stream:
        lines.put(line)
    lines.put(None)


def main(argv: list[str] | None = None) -> int:
    import time

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the stage handles the signals and says how its runs end
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    (uri,) = argv if argv is not None else sys.argv[1:]
    lines: queue.Queue = queue.Queue()
    # read from the start, while MLflow is imported, so the stage never waits on a full pipe
    threading.Thread(target=_read, args=(sys.stdin, lines), daemon=True).start()
    writer = None
    try:
        writer = RunWriter(uri)
        while (line := lines.get()) is not None:
            writer.apply(json.loads(line))
        writer.close_open(int(time.time() * 1000))
    except Exception as err:  # one line for the stage to show; the store's own message says why
        print(f"error: MLflow store {uri}: {type(err).__name__}: {err}", file=sys.stderr)
        if writer is not None:
            with contextlib.suppress(Exception):  # the store is what failed: leave it
                writer.close_open(int(time.time() * 1000), "FAILED")
        return 1
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
