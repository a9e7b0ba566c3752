"""A scripted demonstrator that plays the paper's human participants.

It knows the world's semantics (which object is a bin, a stirrer, a cup) and
follows the kitchen's rules: liquids are handled through their containers,
nothing is poured or stirred over a shelf, and whatever rests on an object is
cleared before the object is grasped. Where two loads must be cleared, either
order is acceptable, and the demonstrator returns both sequences.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .objects import POURERS, VESSELS
from .primitives import Action, execute, has_room
from .state import WorldState
from .tasks import Task

LOW_BIN = 0.4  # a bin no taller than this (m) can have things set down inside, not only dropped
STIRRER_MARGIN = 0.04  # a stirrer sticks out of the container by at least this much (m)
FILL = 0.6  # share of a vessel's box volume that can hold liquid


class NoDemonstration(ValueError):
    """The task cannot be done in this environment (no vessel, no stirrer, no bin)."""


def capacity(state: WorldState, obj: str) -> float:
    s = state.specs[obj]
    return FILL * s.w * s.l * s.h


def choose_vessel(state: WorldState, liquid: str) -> str | None:
    """The smallest empty drinking or serving vessel that holds the liquid."""
    need = state.specs[liquid].attributes()["volume"]
    source = state.container_of(liquid)
    fits = [
        o
        for o, s in state.specs.items()
        if s.category in VESSELS and o != source and not state.liquids_in(o) and capacity(state, o) >= need
    ]
    return min(fits, key=lambda o: (capacity(state, o), o)) if fits else None


def choose_stirrer(state: WorldState, container: str) -> str | None:
    """The shortest stirrer that sticks out of the container."""
    need = state.specs[container].h + STIRRER_MARGIN
    long_enough = [
        o for o, s in state.specs.items() if s.category == "stirrer" and max(s.w, s.l) >= need
    ]
    return min(long_enough, key=lambda o: (max(state.specs[o].w, state.specs[o].l), o)) if long_enough else None


def choose_bin(state: WorldState, obj: str) -> str | None:
    """The bin nearest to the object to throw away."""
    ox, oy, _ = state.poses[obj]
    bins = [o for o, s in state.specs.items() if s.category == "bin" and o != obj]

    def dist(b: str) -> tuple[float, str]:
        bx, by, _ = state.poses[b]
        return ((bx - ox) ** 2 + (by - oy) ** 2, b)

    return min(bins, key=dist) if bins else None


@dataclass
class _Recorder:
    """Executes the script's steps; `variant` picks a branch at each free choice."""

    state: WorldState
    variant: int
    actions: list[Action] = field(default_factory=list)
    n_choices: int = 0

    def choose(self) -> bool:
        bit = bool((self.variant >> self.n_choices) & 1)
        self.n_choices += 1
        return bit

    def do(self, primitive: str, *args: str) -> None:
        action = Action(primitive, tuple(args))
        self.state = execute(self.state, action)
        self.actions.append(action)

    def reach(self, obj: str) -> None:
        if not self.state.reachable(obj):
            self.do("move_close", obj)

    def fetch(self, obj: str) -> None:
        """Go to `obj`, clear whatever rests on it, grasp it (setting down first what is in hand)."""
        if self.state.held == obj:
            if obj in self.state.support:
                self.do("release", obj)
                self.do("grasp", obj)
            return
        if self.state.held is not None:
            self.set_down(self.state.held)
        self.reach(obj)
        loads = self.state.loads(obj)
        if len(loads) > 1 and self.choose():
            loads = loads[::-1]
        for load in loads:
            self.clear(load, obj)
        self.reach(obj)
        self.do("grasp", obj)

    def clear(self, load: str, under: str) -> None:
        """Move `load` off `under`, onto the furniture `under` stands on."""
        dest = self.state.furniture_under(under)
        self.fetch(load)
        if dest is None or not self._has_room(load, dest):
            dest = self.nearest_table(load)
        self.reach(dest)
        self.do("place_above", load, dest)
        self.do("release", load)

    def _has_room(self, obj: str, dest: str) -> bool:
        return has_room(self.state, obj, dest)

    def nearest_table(self, obj: str) -> str:
        """The table with room for `obj` nearest the robot."""
        tables = [o for o, s in self.state.specs.items() if s.category == "table" and self._has_room(obj, o)]
        if not tables:
            raise NoDemonstration(f"no table has room for {obj}")
        return min(tables, key=lambda t: (self.state.reach_distance(t), t))

    def set_down(self, obj: str) -> None:
        """Put the held `obj` on the nearest table with room (chained tasks start with a full hand)."""
        table = self.nearest_table(obj)
        self.reach(table)
        self.do("place_above", obj, table)
        self.do("release", obj)

    def set_down_near(self, obj: str, anchor: str) -> None:
        """Carry the held `obj` off a shelf to the table where `anchor` is (else the nearest)."""
        table = self.state.furniture_under(anchor)
        if table is not None and self.state.specs[table].category == "table" and self._has_room(obj, table):
            self.reach(anchor)
        else:
            table = self.nearest_table(obj)
        self.reach(table)
        self.do("place_above", obj, table)
        self.do("release", obj)


def demonstrate(state: WorldState, task: Task) -> list[list[Action]]:
    """Every acceptable sequence for `task` from `state`.

    There is more than one where the script meets a free choice: the order in
    which two loads are cleared, or setting an object down in a low bin
    rather than dropping it in.
    """
    task.check_objects(state)
    first = _run(state, task, 0)
    return [first.actions] + [_run(state, task, v).actions for v in range(1, 2**first.n_choices)]


def _run(state: WorldState, task: Task, variant: int) -> _Recorder:
    rec = _Recorder(state, variant)
    a = task.args[0]
    if task.name == "pick_and_place":
        b = task.args[1]
        rec.fetch(a)
        rec.reach(b)
        rec.do("place_above", a, b)
        rec.do("release", a)
    elif task.name == "throw_away":
        bin_ = choose_bin(state, a)
        if bin_ is None:
            raise NoDemonstration(f"{task}: no bin in this environment")
        rec.fetch(a)
        rec.reach(bin_)
        set_down = state.specs[bin_].h <= LOW_BIN and rec.choose()
        rec.do("place_above" if set_down else "hold_above", a, bin_)
        rec.do("release", a)
    elif task.name in ("pour", "pour_to"):
        source = state.container_of(a)
        if source is None or state.specs[source].category not in POURERS:
            raise NoDemonstration(f"{task}: {a} is not in a container one pours from")
        target = task.args[1] if task.name == "pour_to" else choose_vessel(state, a)
        if target is None:
            raise NoDemonstration(f"{task}: no empty vessel holds {a}")
        if state.over_shelf(target):
            rec.fetch(target)
            rec.set_down_near(target, source)
        rec.fetch(source)
        rec.reach(target)
        rec.do("hold_above", source, target)
        rec.do("follow_traj_pour", source, target)
    elif task.name == "stir":
        vessel = state.container_of(a)
        if vessel is None or state.specs[vessel].category not in VESSELS:
            raise NoDemonstration(f"{task}: {a} is not in a vessel one can stir")
        stirrer = choose_stirrer(state, vessel)
        if stirrer is None:
            raise NoDemonstration(f"{task}: no stirrer is long enough for {vessel}")
        if state.over_shelf(vessel):
            rec.fetch(vessel)
            rec.set_down_near(vessel, stirrer)
        rec.fetch(stirrer)
        rec.reach(vessel)
        rec.do("hold_above", stirrer, vessel)
        rec.do("follow_traj_circle", stirrer)
    else:  # pragma: no cover - Task validates names
        raise AssertionError(task.name)
    return rec
