"""Stage `stats`: Table I's figures with confidence intervals over worlds and scenarios, and paired comparisons.

Reads every world's programs and teacher-forced steps (`crossval_sequences.csv`,
`crossval_steps.csv` in `reports/worlds/<seed>/`) and writes, beside the
tables over worlds, `table1_ci.csv`/`.md` (every figure of every method with
its interval) and `comparisons.csv`/`.md` (each added method against the
paper's model, against the best baseline and, given `--selection`, against
the method ranked first there: the shipped planner). Run on the `scenes`
stage's drawn worlds it gives the same for whole drawn rooms held out, and
on its transfer programs (paper-shaped rooms to drawn ones, where no
baseline runs) for the transfer. The tables it adds to change
none of the others.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..methods import BASELINES, PAPER_METHODS, PAPER_MODEL, method_labels
from ..report.csvs import read_csv_rows
from ..report.seeds import world_dirs
from ..report.stats import best_baseline, confidence_intervals, paired_comparisons, world_outcomes
from ..report.stats_tables import (
    bootstrap_text,
    comparisons_csv,
    comparisons_markdown,
    intervals_csv,
    intervals_markdown,
    test_text,
)
from ..runtime.atomic import write_text_atomic
from ..selection import read_selection
from ..settings import Params, Stats, World
from ..track.mlflow_runs import NO_RUN, Tracker
from .options import StatsOptions


@dataclass(frozen=True)
class Settings:
    world: World
    stats: Stats


def settings(params: Params, world_seed: int | None = None) -> Settings:
    return Settings(params.world, params.stats)


def run(settings: Settings, options: StatsOptions, tracker: Tracker = NO_RUN) -> dict[str, str]:
    stats, out = settings.stats, options.output
    worlds = [world_outcomes(read_csv_rows(d / "crossval_sequences.csv"), read_csv_rows(d / "crossval_steps.csv"),
                             f"{d}") for d in world_dirs(options.worlds, settings.world.seeds).values()]
    labels = method_labels()
    text = bootstrap_text(stats.resamples, stats.seed, stats.confidence, len(worlds))
    intervals = confidence_intervals(worlds, stats.resamples, stats.seed, stats.confidence)
    write_text_atomic(out / "table1_ci.csv", intervals_csv(intervals))
    write_text_atomic(out / "table1_ci.md", intervals_markdown(intervals, labels, text, stats.confidence))

    present = {r.method for r in intervals}
    baselines = [b for b in BASELINES if b in present]  # none where only MRF methods ran (the transfer)
    baseline = best_baseline(worlds, baselines) if baselines else None
    added = [m for m in labels if m in present and m not in PAPER_METHODS] + sorted(present - set(labels))
    shipped = read_selection(options.selection).method if options.selection else None
    against = [(PAPER_MODEL, "paper"), *([(baseline, "baseline")] if baseline else [])]
    against += [(shipped, "shipped")] if shipped in present and shipped not in (PAPER_MODEL, baseline) else []
    pairs = [(m, other, role) for m in added for other, role in against if other != m]
    comparisons = paired_comparisons(worlds, pairs, stats.resamples, stats.seed, stats.confidence)
    write_text_atomic(out / "comparisons.csv", comparisons_csv(comparisons))
    write_text_atomic(out / "comparisons.md", comparisons_markdown(comparisons, labels, test_text(stats.confidence)))
    tracker.metrics({f"{r.method}.{r.figure}.ci_{k}": getattr(r, k) for r in intervals for k in ("low", "high")})
    tracker.metrics({f"{r.method}.vs.{r.against}.{r.figure}.p": r.p_value for r in comparisons})
    for f in ("table1_ci.md", "comparisons.md"):
        tracker.artifact(out / f)
    print(intervals_markdown(intervals, labels, text, stats.confidence))
    print(comparisons_markdown(comparisons, labels, test_text(stats.confidence)))
    return {"best_baseline": baseline}
