"""Stage `report`: reports/summary.md, every result of the pipeline beside the paper's figure.

With `plots_template`, also the page `dvc plots show` fills, with its JavaScript inline so it works offline.
"""

from __future__ import annotations

from pathlib import Path

from ..evaluate.labels import METHOD_LABELS
from ..io import write_text_atomic
from ..report.plots_page import offline_template
from ..report.summary import build_summary
from ..track.mlflow_runs import NO_RUN, Tracker


def run(reports: Path, output: Path, plots_template: Path | None = None, tracker: Tracker = NO_RUN) -> str:
    text = build_summary(reports, METHOD_LABELS)
    write_text_atomic(output, text + "\n")
    tracker.artifact(output)
    print(f"wrote {output}")
    if plots_template is not None:
        write_text_atomic(plots_template, offline_template())
        print(f"wrote {plots_template}")
    return text
