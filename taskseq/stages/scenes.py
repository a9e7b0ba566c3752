"""Stage `scenes`: generalisation to rooms never seen in training, over the world seeds, beside the paper-shaped
results.

Each reported seed's `scenes_world` stage wrote its results with whole rooms
held out, in the paper-shaped world and in the seed's drawn world, and the
transfer from one to the other; this stage writes the tables over seeds
(mean ± sd) as the `aggregate` stage writes the paper-shaped ones, what
drawing the rooms cost (`drawn/worlds.json`, `drawn/dataset.json`, from the
drawn worlds' manifests) and the transfer's table.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from ..methods import method_labels
from ..report.csvs import TRANSFER_COLUMNS as TRANSFER
from ..report.csvs import csv_text
from ..report.seeds import curve_over_seeds, json_over_seeds, world_dirs
from ..runtime.atomic import write_json_atomic, write_text_atomic
from ..settings import Params, World
from ..track.mlflow_runs import NO_RUN, Tracker
from . import aggregate
from .options import AggregateOptions, ScenesOptions

# the reported worlds are drawn (world.family procedural): the drawn world of a seed is then the reported world
# itself, scenario for scenario, so nothing is trained on one and tested on the other
NO_TRANSFER = ("Not measured: the reported worlds are drawn (`world.family: procedural`), so a seed's drawn world "
               "is its reported world and no paper-shaped world is there to train on.\n")


@dataclass(frozen=True)
class Settings:
    seeds: tuple[int, ...]
    paper_shaped: bool = True  # the reported worlds are the paper's rooms; drawn ones leave no transfer to measure


def settings(params: Params, world_seed: int | None = None) -> Settings:
    return Settings(seeds=params.world.seeds, paper_shaped=params.world.family == "paper")


def run(settings: Settings, options: ScenesOptions, tracker: Tracker = NO_RUN) -> dict[str, Any]:
    results, out = options.results, options.output
    world = World(seeds=settings.seeds)
    aggregate.run(world, AggregateOptions(worlds=results / "paper", output=out / "paper"), tracker)
    aggregate.run(replace(world, family="procedural"), AggregateOptions(worlds=results / "drawn", output=out / "drawn"),
                  tracker)
    drawn = world_dirs(options.worlds, settings.seeds)
    for manifest, name in (("world.json", "worlds.json"), ("dataset.json", "dataset.json")):
        write_json_atomic(out / "drawn" / name, {str(s): d for s, d in json_over_seeds(drawn, manifest).items()})
    dirs = world_dirs(results / "drawn", settings.seeds)
    per_seed, over_seeds = curve_over_seeds(dirs, "transfer.csv", ["method"], TRANSFER) if settings.paper_shaped \
        else ([], [])
    write_text_atomic(out / "transfer_seeds.csv",
                      csv_text(["world_seed", "method", *TRANSFER], per_seed, dict.fromkeys(TRANSFER, 2)))
    columns = ["method"] + [c for v in TRANSFER for c in (v, f"{v}_sd")]
    write_text_atomic(out / "transfer.csv", csv_text(columns, over_seeds, dict.fromkeys(columns[1:], 2)))
    # unrounded, for what formats the means again (the summary): a figure rounded twice can differ from transfer.md
    write_json_atomic(out / "transfer.json", {r["method"]: {c: r[c] for c in columns[1:]} for r in over_seeds})
    table = transfer_markdown(over_seeds, len(settings.seeds)) if settings.paper_shaped else NO_TRANSFER
    write_text_atomic(out / "transfer.md", table)
    tracker.metrics({f"transfer.{r['method']}.{k}": r[k] for r in over_seeds for k in TRANSFER})
    print(table)
    return {"transfer": over_seeds}


def transfer_markdown(rows: list[dict[str, Any]], n_seeds: int) -> str:
    """The transfer table: each method trained on the paper-shaped rooms, run in drawn ones."""
    labels = method_labels()
    lines = [f"Trained on every step of the paper-shaped world, run on every scenario of the drawn world of the same "
             f"seed: % of programs, mean ± sd over {n_seeds} world seeds.", "",
             "| method | " + " | ".join(k.replace("_", " ") for k in TRANSFER) + " |",
             "|---|" + "---:|" * len(TRANSFER)]
    lines += [f"| {labels.get(r['method'], r['method'])} | "
              + " | ".join(f"{r[k]:.1f} ± {r[f'{k}_sd']:.1f}" for k in TRANSFER) + " |" for r in rows]
    return "\n".join(lines) + "\n"
