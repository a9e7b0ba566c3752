"""Server-side sessions: one per browser (a random id in a cookie), each with its own environment and steps.

Nothing a person does is kept in the browser but the session id: the steps,
the state and the planner's offers live here, so a tampered form can name a
step but never rewrite the history. Each session has a lock, so two requests
of one browser (a double click) change it one after the other.
"""

from __future__ import annotations

import itertools
import secrets
import threading
from collections import OrderedDict
from dataclasses import dataclass, field

from ..sim.primitives import Action, execute
from ..sim.state import WorldState
from ..sim.tasks import Task, goal_reached
from .environments import Environment
from .rules import UnsafeStep, unsafe_reason

DEMONSTRATE, ASSIST = "demonstrate", "assist"
MODES = (DEMONSTRATE, ASSIST)
MAX_STEPS = 40  # a demonstration longer than this is refused: the benchmark's longest has 10
MAX_SESSIONS = 1000  # the least recently used session is dropped beyond this
_ACTIVITY_IDS = itertools.count(1)  # CPython hands out each number once, whatever thread asks


@dataclass
class Activity:
    """A task under way: the steps taken so far and the world before each and after the last."""

    env: Environment
    task: Task
    mode: str
    participant: str | None
    actions: list[Action] = field(default_factory=list)
    states: list[WorldState] = field(default_factory=list)
    corrected: list[int] = field(default_factory=list)  # assist: steps where the person overrode the planner
    offers: dict = field(default_factory=dict)  # assist: the planner's proposals after each history, made once
    # Which start of a task this is: a page's forms carry it, so that a form drawn for a task that another tab of the
    # browser has since dropped or finished is refused instead of acting on the task under way now. The step count
    # alone cannot tell: two tasks are often at the same step. Distinct, not secret: the session is the browser's own.
    id: int = field(default_factory=lambda: next(_ACTIVITY_IDS))

    def __post_init__(self) -> None:
        if not self.states:
            self.states.append(self.env.state)

    @property
    def state(self) -> WorldState:
        return self.states[-1]

    @property
    def goal_reached(self) -> bool:
        return goal_reached(self.task, self.states[0], self.state)

    def step(self, action: Action, overridden: bool = False) -> None:
        """Execute `action`; raises `PreconditionError` where the simulator cannot run it and `UnsafeStep` where it
        would break a safety rule (nothing changes). The simulator itself lets an unsafe step happen, so that a
        planner can be judged on safety; a person's record is training data, so an unsafe step never enters one."""
        if len(self.actions) >= MAX_STEPS:
            raise ValueError(f"a demonstration has at most {MAX_STEPS} steps; undo some or start again")
        after = execute(self.state, action)
        reason = unsafe_reason(self.state, action)
        if reason is not None:
            raise UnsafeStep(action, reason)
        self.states.append(after)
        if overridden:
            self.corrected.append(len(self.actions))
        self.actions.append(action)

    def undo(self) -> None:
        if not self.actions:
            raise ValueError("there is no step to undo")
        self.actions.pop()
        self.states.pop()
        self.corrected = [k for k in self.corrected if k < len(self.actions)]


@dataclass
class Session:
    lock: threading.Lock = field(default_factory=threading.Lock)
    env: Environment | None = None
    activity: Activity | None = None
    finished: dict | None = None  # what the last finished demonstration was written as
    pending_env: Environment | None = None  # chosen while steps were unsaved: used once the person confirms


class SessionStore:
    """Sessions by id, the least recently used dropped beyond `limit`."""

    def __init__(self, limit: int = MAX_SESSIONS) -> None:
        self._sessions: OrderedDict[str, Session] = OrderedDict()
        self._lock = threading.Lock()
        self.limit = limit

    def get(self, sid: str | None) -> tuple[str, Session]:
        """The session of this id, or a new one (with a new id) when the id is unknown or absent."""
        with self._lock:
            if sid is not None and sid in self._sessions:
                self._sessions.move_to_end(sid)
                return sid, self._sessions[sid]
            sid = secrets.token_urlsafe(24)
            self._sessions[sid] = session = Session()
            while len(self._sessions) > self.limit:
                self._sessions.popitem(last=False)
            return sid, session
