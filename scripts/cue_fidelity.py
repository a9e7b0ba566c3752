"""How often each choice cue marks exactly the object the demonstrator chooses, on worlds that are never reported.

The choice cues (`taskseq.features.cues`) are read off what perception
reports; the demonstrator chooses by the world's semantics (the smallest empty
vessel that holds the liquid, the shortest stirrer that sticks out of the
cup, the bin nearest the object). This script draws each world seed's
scenarios, computes the cues of the first step of every pour, stir and
throw-away scenario, and counts, per cue column, the scenarios whose cue marks
the demonstrator's object and no other (for bins, `nearest_of_kind` marks one
object of every kind: whether the demonstrator's bin is among those marked).
It refuses the reported world seeds of
`params.yaml`: a cue is designed on the development worlds only.

    python scripts/cue_fidelity.py --seeds 100 101 102 103 104

docs/model.md ("Choice cues") shows its table.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from taskseq.features.context import step_context  # noqa: E402
from taskseq.features.cues import CUE_COLUMNS, choice_cues  # noqa: E402
from taskseq.settings import Generate, Params  # noqa: E402
from taskseq.sim.demonstrator import choose_bin, choose_stirrer, choose_vessel  # noqa: E402
from taskseq.sim.scenarios import Scenario, world_scenarios  # noqa: E402

FAMILIES = {"pour": "smallest_empty", "stir": "shortest_over", "throw_away": "nearest_of_kind"}


def chosen(s: Scenario) -> str | None:
    """The object the demonstrator chooses for the open argument of the scenario's task."""
    state, arg = s.initial, s.task.args[0]
    if s.task.name == "pour":
        return choose_vessel(state, arg)
    if s.task.name == "stir":
        return choose_stirrer(state, state.container_of(arg))
    return choose_bin(state, arg)


def tally(scenarios: list[Scenario]) -> tuple[Counter, Counter]:
    """Per cue column, scenarios whose cue marks only the demonstrator's object; per task, scenarios seen."""
    exact, seen = Counter(), Counter()
    for s in scenarios:
        if s.task.name not in FAMILIES:
            continue
        seen[s.task.name] += 1
        ctx = step_context(s.initial, s.task, [])
        cues = choice_cues(ctx.objects, ctx.relations)
        gold = chosen(s)
        for k, column in enumerate(CUE_COLUMNS):
            if not column.startswith(FAMILIES[s.task.name]):
                continue
            marked = [ctx.object_ids[i] for i in np.flatnonzero(cues[:, k])]
            if s.task.name == "throw_away":  # one object of every kind is marked: is the demonstrator's bin?
                exact[column] += gold in marked
            else:
                exact[column] += marked == [gold]
    return exact, seen


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[100, 101, 102, 103, 104],
                    help="world seeds to draw (never a reported one); default 100 101 102 103 104")
    ap.add_argument("--params", type=Path, default=ROOT / "params.yaml", help="the world family and its rooms")
    args = ap.parse_args(argv)
    params = Params.load(args.params)
    reported = sorted(set(args.seeds) & set(params.world.seeds))
    if reported:
        ap.error(f"--seeds {reported} are reported worlds (world.seeds in {args.params}); choose others")
    exact, seen = Counter(), Counter()
    for seed in args.seeds:
        scenarios, _ = world_scenarios(Generate(seed, params.world.family, params.procedural))
        e, n = tally(scenarios)
        exact.update(e)
        seen.update(n)
    print(f"world seeds {' '.join(map(str, args.seeds))} ({params.world.family}): scenarios per task "
          + ", ".join(f"{t} {seen[t]}" for t in FAMILIES))
    print("\n| cue | task | marks the demonstrator's choice |\n|---|---|---:|")
    for column in CUE_COLUMNS:
        task = next(t for t, prefix in FAMILIES.items() if column.startswith(prefix))
        print(f"| `{column}` | {task} | {exact[column]} of {seen[task]} |")


if __name__ == "__main__":
    main()
