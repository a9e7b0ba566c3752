"""Training steps from rooms the simulator draws: more varied rooms than any one world has.

A model trained on the rooms of one world meets, in a room it never saw,
furniture, objects and sizes it has few examples of: trained on 11 drawn
rooms and run in 2 held out, the shipped planner's programs match the
demonstration in about three of four scenarios. The world's own distribution
of rooms (`sim.procedural`, params.yaml's `procedural`) can draw as many
rooms as one likes, and the scripted demonstrator shows every task in them:
`drawn_room_steps` turns such a draw into teacher-forced training steps, as
`taskseq generate`, `ingest` and `features` would, without files.

The rooms come from their own seed, so they are other rooms than any world's
(a world draws its rooms from `[world seed, rooms]`, these from
`[rooms_seed, rooms]`); a test in `tests/test_drawn_rooms.py` checks that no
drawn room of the repository's worlds is among them.
"""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache

from ..demonstrations.records import scenario_records
from ..settings import Generate, Procedural
from ..sim.scenarios import world_scenarios
from .context import StepContext
from .dataset import build_steps


@lru_cache(maxsize=4)
def drawn_room_steps(rooms: int, seed: int, distribution: Procedural) -> tuple[StepContext, ...]:
    """Every demonstrated step of a world of `rooms` rooms drawn from `distribution` with `seed`: its scenarios as
    a drawn world's (`sim.scenarios.world_scenarios`), each demonstration's steps, its `done` included.

    Kept per process (a fold job's methods fit one after another on the same draw); never changed by a caller.
    """
    if rooms < 1:
        raise ValueError(f"drawn rooms: the number of rooms must be at least 1, got {rooms}")
    world = Generate(seed=seed, family="procedural", procedural=replace(distribution, environments=rooms))
    return tuple(build_steps(scenario_records(world_scenarios(world)[0]))[0])
