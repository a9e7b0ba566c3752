"""Stage `report`: reports/summary.md, every result of the pipeline beside the paper's figure.

With `plots_template`, also the page `dvc plots show` fills, with its JavaScript inline so it works offline.
"""

from __future__ import annotations

from ..methods import method_labels
from ..report.plots_page import offline_template
from ..report.summary import build_summary
from ..runtime.atomic import write_text_atomic
from ..settings import Params
from ..track.mlflow_runs import NO_RUN, Tracker
from .options import ReportOptions


def settings(params: Params, world_seed: int | None = None) -> None:
    """The summary reads no setting: it reports what the other stages wrote."""


def run(settings: None, options: ReportOptions, tracker: Tracker = NO_RUN) -> str:
    output, plots_template = options.output, options.plots_template
    text = build_summary(options.reports, method_labels())
    write_text_atomic(output, text + "\n")
    tracker.artifact(output)
    print(f"wrote {output}")
    if plots_template is not None:
        write_text_atomic(plots_template, offline_template())
        print(f"wrote {plots_template}")
    return text
