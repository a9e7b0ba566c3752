"""Stage `report`: reports/summary.md, every result of the pipeline beside the paper's figure."""

from __future__ import annotations

from pathlib import Path

from ..evaluate.methods import METHOD_LABELS
from ..io import write_text_atomic
from ..report.summary import build_summary
from ..track.mlflow_runs import NO_RUN, Tracker


def run(reports: Path, output: Path, tracker: Tracker = NO_RUN) -> str:
    text = build_summary(reports, METHOD_LABELS)
    write_text_atomic(output, text + "\n")
    tracker.artifact(output)
    print(f"wrote {output}")
    return text
