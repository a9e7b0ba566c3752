"""Rerun recordings of closed-loop runs in VEIL environments: the objects, the robot and the steps over time.

The release gives each object a position (Unity units, y up) and no size, so
an object is drawn as a box whose size stands for its kind: small for what the
robot can grasp, large for the rest (furniture, appliances). The robot stands
beside the object it last moved to; what it grasps is drawn in its hand. Beside
the 3D view: the objective, the run's steps as they are taken, and the people's
sequence the run is compared with.

Like the paper world's recordings (`taskseq.track.recordings`), these are
execution records: Rerun stamps fresh ids, so their bytes differ between runs
and DVC does not track them.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import rerun as rr
import rerun.blueprint as rrb

from .grounding import Step
from .state import ROBOT, State

SMALL, LARGE = 6.0, 30.0  # box edges, in the release's units, of graspable objects and of the rest
ROBOT_HEIGHT = 120.0
COLORS = {"grasped": (230, 120, 40), "graspable": (120, 200, 120), "fixed": (150, 150, 170)}


def _position(state: State, name: str) -> tuple[float, float, float]:
    return state.world.objects[name].position


def _log_state(rec: rr.RecordingStream, state: State, acting: frozenset[str]) -> None:
    grasped = set(state.grasped())
    near = [f[2] for f in sorted(state.facts) if f[0] == "Near" and f[1] == ROBOT and f[2] in state.world.objects]
    robot = _position(state, near[-1]) if near else (0.0, 0.0, 0.0)
    robot_at = (robot[0] - LARGE, ROBOT_HEIGHT / 2, robot[2])
    for name, info in state.world.objects.items():
        small = "IsGraspable" in info.affordances
        edge = SMALL if small else LARGE
        center = (robot_at[0] + SMALL, ROBOT_HEIGHT * 0.8, robot_at[2]) if name in grasped else info.position
        kind = "grasped" if name in grasped else "graspable" if small else "fixed"
        rec.log(f"world/objects/{name}", rr.Boxes3D(
            centers=[center], half_sizes=[[edge / 2] * 3], labels=[name], colors=[COLORS[kind]],
            fill_mode="Solid" if small else "MajorWireframe", show_labels=name in acting or name in grasped))
    rec.log("world/robot", rr.Boxes3D(centers=[robot_at], half_sizes=[[LARGE / 3, ROBOT_HEIGHT / 2, LARGE / 3]],
                                      labels=["robot"], colors=[(80, 80, 200)], fill_mode="MajorWireframe"))


def record_run(path: Path | str, recording_id: str, states: Sequence[State], steps: Sequence[Step],
               objective: str, people: Sequence[Step] = (), status: str = "") -> None:
    """One .rrd: the state before every step and after the last (`states` has one more entry than `steps`)."""
    if len(states) != len(steps) + 1:
        raise ValueError(f"record_run: {len(states)} states for {len(steps)} steps (expected one more)")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    rec = rr.RecordingStream("taskseq-veil", recording_id=recording_id, send_properties=False)
    rec.save(path, default_blueprint=rrb.Blueprint(rrb.Horizontal(
        rrb.Spatial3DView(origin="world", name=states[0].world.env_id),
        rrb.Vertical(rrb.TextDocumentView(origin="objective", name="objective"),
                     rrb.TextLogView(origin="run", name="run"), rrb.TextLogView(origin="people", name="people")),
        column_shares=[3, 1]), collapse_panels=True))
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Y_UP, static=True)
    rec.log("objective", rr.TextDocument(f"{objective}\n{status}\npeople: " + " ".join(map(str, people))),
            static=True)
    for k, state in enumerate(states):
        rec.set_time("step", sequence=k)
        acting = frozenset(a for a in ((steps[k].a1, steps[k].a2) if k < len(steps) else ()) if a is not None)
        _log_state(rec, state, acting)
        if k < len(people):
            rec.log("people/step", rr.TextLog(str(people[k])))
        rec.log("run/step", rr.TextLog(str(steps[k]) if k < len(steps) else f"end: {status}"))
    rec.flush()
    del rec
