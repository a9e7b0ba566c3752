"""Stage `aggregate`: every figure over the reported world seeds, as mean ± sd, per-seed values kept.

Reads each world's results (`reports/worlds/<seed>/`) and writes the tables a
paper quotes: Table I, the headline metrics, why programs fail, the noise and
feedback curves and the recipes, each with its spread over world seeds.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..methods import method_labels
from ..report import paper
from ..report.breakdown import breakdown_markdown, group_outcomes
from ..report.csvs import RATE_DECIMALS, SEQUENCE_COLUMNS, csv_text, read_csv_rows
from ..report.figures import line_plot_png
from ..report.seeds import (
    crossval_over_seeds,
    curve_over_seeds,
    failures_markdown,
    failures_over_seeds,
    headline_groups,
    headline_over_seeds,
    json_over_seeds,
    plot_columns,
    recipes_over_seeds,
    table1_over_seeds,
    world_dirs,
)
from ..report.tables import to_latex, to_markdown
from ..runtime.atomic import write_json_atomic, write_text_atomic
from ..settings import Params, World
from ..track.mlflow_runs import NO_RUN, Tracker
from .options import AggregateOptions

RATES = ("sequence_arg", "sequence_prim", "success")


def settings(params: Params, world_seed: int | None = None) -> World:
    return params.world


def run(settings: World, options: AggregateOptions, tracker: Tracker = NO_RUN) -> dict[str, Any]:
    world, out = settings, options.output
    dirs = world_dirs(options.worlds, world.seeds)
    per_seed, table = table1_over_seeds(dirs)
    write_text_atomic(out / "table1_seeds.csv", csv_text(["world_seed", "method", "column", "prim", "arg"], per_seed,
                                                         {"prim": 2, "arg": 2}))
    write_text_atomic(out / "table1.csv", csv_text(["method", "column", "prim", "prim_sd", "arg", "arg_sd"], table,
                                                   {"prim": 2, "prim_sd": 2, "arg": 2, "arg_sd": 2}))
    write_text_atomic(out / "table1.md", to_markdown(table))
    seeds_text = ", ".join(map(str, world.seeds))
    write_text_atomic(out / "table1.tex", to_latex(table, (
        f"Mean $\\pm$ sample standard deviation over {len(world.seeds)} world seeds ({seeds_text}), each a 6-fold "
        "cross-validation: percentage of primitives (prim) and of primitives with arguments (arg) right, "
        "teacher-forced, and of closed-loop sequences equal to a demonstration.")))

    summaries = crossval_over_seeds(dirs)
    rows, means = headline_over_seeds(summaries)
    write_text_atomic(out / "crossval_seeds.csv", csv_text(["world_seed", "method"] + [k for k in rows[0]
                                                           if k not in ("world_seed", "method")], rows))
    write_json_atomic(out / "crossval_means.json", means)
    for r in rows:
        with tracker.child(f"{r['method']} seed={r['world_seed']}",
                           {"method": r["method"], "world_seed": r["world_seed"]}) as child:
            child.metrics({k: v for k, v in r.items() if k not in ("method", "world_seed")})
    tracker.metrics({f"{m}.{k}": v for m, figures in means.items() for k, v in figures.items()})

    failures = failures_over_seeds(summaries)
    write_text_atomic(out / "failures.csv", csv_text(["world_seed", "method", "task", "kind", "programs"], failures))
    present = {r["method"] for r in failures}  # in Table I's order, the paper's rows first
    methods = [m for m in method_labels() if m in present] + sorted(present - set(method_labels()))
    programs = {seed: read_csv_rows(d / "crossval_sequences.csv") for seed, d in dirs.items()}
    # a drawn world's rooms differ from seed to seed, so only the paper-shaped rooms compare per environment
    groups = ("environment", "task") if world.family == "paper" else ("task",)
    tables = [breakdown_markdown(group_outcomes(programs, "full", by), "The full model", by) for by in groups]
    write_text_atomic(out / "failures.md", "\n".join([failures_markdown(failures, methods, len(world.seeds)),
                                                      *filter(None, tables)]))

    noise, fb = [], []
    if _everywhere(dirs, "noise.csv"):  # worlds evaluated without noise or feedback runs have neither curve
        noise = _noise(dirs, out, world)
    if _everywhere(dirs, "feedback.csv"):
        fb = _feedback(dirs, out)

    # every program of every world in one table, for whoever reads programs rather than rates (DVC-cached)
    write_text_atomic(out / "crossval_sequences.csv", csv_text(["world_seed", *SEQUENCE_COLUMNS], [
        {"world_seed": seed, **r} for seed, rows in programs.items() for r in rows]))

    if _everywhere(dirs, "dataset.json"):  # the ingest stage's counts, where it ran into these folders
        write_json_atomic(out / "dataset.json", {str(s): d for s, d in json_over_seeds(dirs, "dataset.json").items()})

    # recipes name the paper-shaped rooms' objects: worlds of drawn rooms have none
    recipes = recipes_over_seeds(dirs) if _everywhere(dirs, "recipes.json") else {}
    if recipes:
        write_json_atomic(out / "recipes.json", recipes)
    write_json_atomic(out / "metrics.json", headline_groups(means, noise, fb, recipes))
    _plot_columns(noise, fb, out)
    for f in ("table1.md", "table1.tex", "metrics.json", "crossval_means.json", "failures.md", "noise.png",
              "feedback.png", "recipes.json"):
        tracker.artifact(out / f)
    print(to_markdown(table))
    print(f"over world seeds {seeds_text}; failure kinds in {out / 'failures.md'}")
    return means


def _noise(dirs: dict[int, Path], out: Path, world: World) -> list[dict[str, Any]]:
    """The noise curve over seeds: its tables and figure."""
    noise_seeds, noise = curve_over_seeds(dirs, "noise.csv", ["method", "rate"], RATES)
    write_text_atomic(out / "noise_seeds.csv", csv_text(["world_seed", "method", "rate", *RATES], noise_seeds,
                                                        dict.fromkeys(RATES, RATE_DECIMALS)))
    cols = ["method", "rate"] + [c for v in RATES for c in (v, f"{v}_sd")]
    write_text_atomic(out / "noise.csv", csv_text(cols, noise, dict.fromkeys(cols[2:], RATE_DECIMALS)))
    noise_methods = list(dict.fromkeys(r["method"] for r in noise))
    line_plot_png({f"{method_labels().get(m, m)} (mean, sd over {len(world.seeds)} world seeds)":
                   ([float(r["rate"]) for r in noise if r["method"] == m],
                    [r["sequence_arg"] for r in noise if r["method"] == m],
                    [r["sequence_arg_sd"] for r in noise if r["method"] == m]) for m in noise_methods},
                  str(out / "noise.png"), "Sequence accuracy (arg) with binary attributes flipped",
                  "probability of flipping each binary attribute", "% sequences correct",
                  reference={"paper": (list(paper.NOISE), list(paper.NOISE.values()))})
    return noise


def _feedback(dirs: dict[int, Path], out: Path) -> list[dict[str, Any]]:
    """The feedback curves over seeds: their tables and figure."""
    fb_seeds, fb = curve_over_seeds(dirs, "feedback.csv", ["method", "k", "n"], RATES)
    write_text_atomic(out / "feedback_seeds.csv", csv_text(["world_seed", "method", "k", "n", *RATES], fb_seeds,
                                                           dict.fromkeys(RATES, RATE_DECIMALS)))
    cols = ["method", "k", "n"] + [c for v in RATES for c in (v, f"{v}_sd")]
    write_text_atomic(out / "feedback.csv", csv_text(cols, fb, dict.fromkeys(cols[3:], RATE_DECIMALS)))
    ks = list(dict.fromkeys(r["k"] for r in fb))
    ns = list(dict.fromkeys(r["n"] for r in fb))
    fb_methods = list(dict.fromkeys(r["method"] for r in fb))
    line_plot_png({f"{method_labels().get(m, m)}, top {k}":
                   (list(range(len(ns))), [r["sequence_arg"] for r in fb if r["k"] == k and r["method"] == m],
                    [r["sequence_arg_sd"] for r in fb if r["k"] == k and r["method"] == m])
                   for m in fb_methods for k in ks},
                  str(out / "feedback.png"), "Sequence accuracy (arg) with an observer's feedback",
                  "steps with feedback", "% sequences correct", xticks=list(range(len(ns))), xticklabels=ns)
    return fb


def _plot_columns(noise: list[dict[str, Any]], fb: list[dict[str, Any]], out: Path) -> None:
    """The curves again, one column per line, for `dvc plots show` (it draws one line per column)."""
    plot_labels = {**method_labels(), **{str(r["k"]): f"top {r['k']}" for r in fb}}
    for name, rows, x, series in (("noise", noise, "rate", ["method"]), ("feedback", fb, "n", ["method", "k"])):
        if not rows:
            continue
        columns, wide = plot_columns(rows, x, series, "sequence_arg", plot_labels)
        write_text_atomic(out / "plots" / f"{name}.csv", csv_text(columns, wide, dict.fromkeys(columns[1:], 2)))


def _everywhere(dirs: dict[int, Path], name: str) -> bool:
    """Whether the worlds have `name`: all of them (True) or none (False). Recipes run in paper-shaped rooms only,
    and worlds evaluated again with other folds have Table I alone; a file only some worlds lack is an error."""
    missing = [seed for seed, d in dirs.items() if not (d / name).exists()]
    if missing and len(missing) < len(dirs):
        raise FileNotFoundError(f"{dirs[missing[0]] / name}: missing; run the stage that writes it for world seed "
                                f"{missing[0]} (the other worlds have it)")
    return not missing
