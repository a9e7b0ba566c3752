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

Drawing and demonstrating 52 rooms takes about 2 s, and every process that
fits such a method needs them (to fit, or to key a fit the cache holds), a
few dozen processes a pipeline; with the cache on (`runtime.cache`), the
steps are kept in its `steps/` folder as `taskseq features` writes them, and
read back (in a twentieth of the time, the same bytes) while the code that
draws them is the same.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import replace
from functools import lru_cache

from ..demonstrations.records import scenario_records
from ..runtime.cache import Entries, versions
from ..runtime.sources import code_fingerprint
from ..settings import Generate, Procedural
from ..sim.scenarios import world_scenarios
from .context import StepContext
from .dataset import StepMeta, build_steps, read_features, write_features

FORMAT = "taskseq.drawn-rooms/1"


@lru_cache(maxsize=4)
def drawn_room_steps(rooms: int, seed: int, distribution: Procedural) -> tuple[StepContext, ...]:
    """Every demonstrated step of a world of `rooms` rooms drawn from `distribution` with `seed`: its scenarios as
    a drawn world's (`sim.scenarios.world_scenarios`), each demonstration's steps, its `done` included.

    Kept per process (a fold job's methods fit one after another on the same draw), and in the cache when it is
    on; never changed by a caller.
    """
    if rooms < 1:
        raise ValueError(f"drawn rooms: the number of rooms must be at least 1, got {rooms}")
    cache = StepsCache.active()
    if cache is None:
        return tuple(_drawn(rooms, seed, distribution)[0])
    key = _key(rooms, seed, distribution)
    kept = cache.load(key)
    if kept is None:
        contexts, meta = _drawn(rooms, seed, distribution)
        cache.save(key, contexts, meta)
        kept = tuple(contexts)
    return kept


def _drawn(rooms: int, seed: int, distribution: Procedural) -> tuple[list[StepContext], list[StepMeta]]:
    world = Generate(seed=seed, family="procedural", procedural=replace(distribution, environments=rooms))
    return build_steps(scenario_records(world_scenarios(world)[0]))


class StepsCache(Entries):
    """A folder of step sets, `<key>.steps/` each: the tables `taskseq features` writes (no pickles)."""

    kind = "steps"

    def load(self, key: str, redone: str = "drawn again") -> tuple[StepContext, ...] | None:
        """The steps stored under `key`, or None if there are none or they cannot be read (the warning then says
        what happens instead: `redone`)."""
        return self.read(key, lambda path: tuple(read_features(path)[0]), redone)

    def save(self, key: str, contexts: list[StepContext], meta: list[StepMeta]) -> None:
        """Store the steps under `key`, atomically (not one of the command's outputs)."""
        write_features(contexts, meta, self.path(key), is_output=False)


def _key(rooms: int, seed: int, distribution: Procedural) -> str:
    """sha256 of what decides the steps: the draw's settings, the code that draws, demonstrates and featurises
    them (this module's imports), and the libraries that write and read them."""
    decided = {"format": FORMAT, "rooms": rooms, "seed": seed, "distribution": repr(distribution),
               "code": code_fingerprint(__name__), **versions("numpy", "pyarrow")}
    return hashlib.sha256(json.dumps(decided, sort_keys=True).encode()).hexdigest()
