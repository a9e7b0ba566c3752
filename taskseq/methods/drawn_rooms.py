"""ours + relations + choice cues + safety lookahead + drawn rooms: the shipped kind of planner, trained also in
rooms the simulator draws.

In a room it never saw the choice-cue planner still reaches the goal, but
often by another route than a person takes: it sets a vessel down on the
floor or on the wrong table, or walks to the table rather than to the
stirrer standing on it. These are habits of rooms, and one world has few
rooms to learn them from. This method adds to its training steps those of
`rooms` rooms drawn from the world's own distribution (params.yaml's
`procedural`) with their own seed `rooms_seed`, demonstrated by the same
scripted demonstrator (`features.drawn_rooms`): never a room of a reported
or development world. How many rooms was chosen on the development world's
drawn rooms held out (`scripts/drawn_rooms.py`, docs/model.md); C by
`select` as for every MRF method.
"""

from __future__ import annotations

from dataclasses import dataclass

from taskseq.evaluate.methods import ScorerMethod
from taskseq.methods.spec import Build, MethodSpec, register


@dataclass(frozen=True)
class DrawnRooms:
    """The rooms added to every fit: how many (chosen on the development world, docs/model.md) and their seed."""

    rooms: int = 52
    rooms_seed: int = 1000  # no world's seed: params.yaml's world seeds and dev_seed are below 1000

    def __post_init__(self) -> None:
        if self.rooms < 1:
            raise ValueError(f"rooms must be at least 1 (drawn rooms added to the training steps), got {self.rooms}")


def make(b: Build) -> ScorerMethod:
    return b.mrf("choice", training_rooms=b.settings.rooms, rooms_seed=b.settings.rooms_seed,
                 rooms_from=b.procedural)


SPEC = register(MethodSpec("drawn_rooms", "ours + relations + choice cues + safety lookahead + drawn rooms", make,
                           policy="lookahead", settings=DrawnRooms))
