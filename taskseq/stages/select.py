"""Stage `select`: rank the MRF methods, each at the C the development world chose for it, into selection.json.

Each method's C is chosen by its own `choose_C` stage, which writes
`NAME.json` into the choices folder; this stage reads the choice of every
method whose entry of params.yaml's `methods` names select, checks that they
were made with today's grid on one development world, and ranks them. Every
reported figure then uses each method's chosen C, and the `train` stage ships
the method ranked first.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

from ..experiments.selection import CRITERION, rank_methods
from ..methods import PAPER_MODEL, Lineup
from ..runtime.atomic import write_json_atomic
from ..settings import Methods, Params, Select
from ..track.mlflow_runs import NO_RUN, Tracker
from .options import SelectOptions


@dataclass(frozen=True)
class Settings:
    select: Select  # the grid and cap every choice must have been made with
    methods: Methods  # those whose experiments name select are ranked, ties going to the one listed first


def settings(params: Params, world_seed: int | None = None) -> Settings:
    return Settings(params.select, params.methods)


def _choice(options: SelectOptions, name: str, select: Select) -> dict[str, Any]:
    """Method `name`'s choice file, checked against the grid and cap of params.yaml."""
    path = options.choices / f"{name}.json"
    redo = (f"run `taskseq choose_C --method {name} --output {path}`, or `dvc repro choose_C@{name}` (for a method "
            "new to select, after `python scripts/stage_deps.py`, which adds its stage)")
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no choice of C for method {name}; {redo}") from None
    except ValueError as err:
        raise ValueError(f"{path}: not valid JSON ({err}); {redo}") from None
    if not isinstance(data, dict) or not isinstance(data.get("choice"), dict) or data.get("method") != name:
        raise ValueError(f"{path}: not a choice of C for method {name} (fields method and choice); {redo}")
    made = (data.get("grid"), data.get("max_extensions"))
    if made != (list(select.C), select.max_extensions):
        raise ValueError(f"{path}: chosen on the grid {made[0]} with {made[1]} extensions, but params.yaml's "
                         f"select has {list(select.C)} with {select.max_extensions}; {redo}")
    return data


def run(settings: Settings, options: SelectOptions, tracker: Tracker = NO_RUN) -> dict[str, Any]:
    select = settings.select
    names = Lineup(settings.methods).names("select")
    if PAPER_MODEL not in names:
        raise ValueError(f"params.yaml: methods.{PAPER_MODEL}.experiments must include select: its C is also the "
                         "paper's ablations' (only_edge, only_clique) and the people stage's")
    files = {name: _choice(options, name, select) for name in names}
    seeds = {data.get("dev_seed") for data in files.values()}
    if len(seeds) != 1:
        raise ValueError(f"{options.choices}: the choices were made on different development worlds (seeds "
                         f"{sorted(seeds, key=str)}); run `dvc repro` to choose every C on data/dev")
    chosen = {name: data["choice"] for name, data in files.items()}
    ranking = rank_methods(chosen)
    result = {"criterion": CRITERION, "dev_seed": seeds.pop(),
              "grid": list(select.C), "max_extensions": select.max_extensions, "settings": chosen,
              "method": ranking[0]["method"], "methods": ranking,
              # the order is now params.yaml's `methods` section's; the words stay, so the file stays the same bytes
              "method_criterion": "sequence_arg, then success, then the order of select.methods"}
    write_json_atomic(options.output, result)
    for r in ranking:
        print(f"{r['method']:<24} C={r['C']:<8g} sequence arg {r['sequence_arg']:5.1f}  success "
              f"{r['success']:5.1f}  step arg {r['average_arg']:5.1f}")
    tracker.params({"method": result["method"]})
    tracker.metrics({f"C.{name}": choice["C"] for name, choice in chosen.items()})
    print(f"ranked first: {result['method']} at C={ranking[0]['C']:g}; written to {options.output}")
    return result
