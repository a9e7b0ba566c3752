"""Rerun recordings of programs being executed: boxes over a `step` timeline, the robot, the
gripper, the chosen primitive with its score and alternatives, and the demonstration beside it.

Each recording carries its layout: the 3D view opens framed on the furniture,
and only the furniture, the task's objects, the held object and the current
step's arguments are labelled (hovering any box names it).

Recordings are execution records, like MLflow runs: Rerun stamps chunks with
fresh ids, so the bytes differ between runs and DVC does not track them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from ..plan.planner import Program
from ..sim.primitives import Action
from ..sim.state import WorldState

COLORS = {
    "floor": (200, 200, 200), "table": (160, 120, 80), "shelf": (120, 90, 60), "bin": (90, 90, 90),
    "liquid": (60, 140, 230), "stirrer": (230, 180, 40),
}
ROBOT_SIZE = (0.5, 0.5, 1.3)


def _color(state: WorldState, obj: str) -> tuple[int, int, int]:
    cat = state.specs[obj].category
    return COLORS.get(cat, (220, 90, 90) if state.specs[obj].has("container") else (120, 200, 120))


FURNITURE = ("table", "shelf", "bin")


def framing(state: WorldState) -> tuple[np.ndarray, np.ndarray]:
    """Camera position and look target of the 3D view: in front of and above the furniture, all of it in view.

    The floor is many times larger than the furniture, so a view fitted to the
    whole scene shows the objects as specks.
    """
    boxes = np.array([state.box(o) for o in state.specs if state.specs[o].category in FURNITURE]
                     or [state.box(o) for o in state.specs])
    low, high = boxes[:, :3].min(axis=0), boxes[:, 3:].max(axis=0)
    target = (low + high) / 2
    reach = max(float(np.max(high[:2] - low[:2])), 1.0)
    return target + np.array([-0.25, -0.7, 0.5]) * reach, target


def blueprint(state: WorldState) -> rrb.Blueprint:
    """The 3D world framed on the furniture, beside the task, the plan's choices and the demonstration."""
    position, target = framing(state)
    world = rrb.Spatial3DView(origin="world", name="world", eye_controls=rrb.EyeControls3D(
        position=position.tolist(), look_target=target.tolist(), eye_up=[0.0, 0.0, 1.0]))
    return rrb.Blueprint(rrb.Horizontal(world, rrb.Vertical(
        rrb.TextDocumentView(origin="task", name="task"), rrb.TextLogView(origin="plan", name="plan"),
        rrb.TextLogView(origin="demonstration", name="demonstration")), column_shares=[3, 1]), collapse_panels=True)


def _log_state(rec: rr.RecordingStream, state: WorldState, named: frozenset[str]) -> None:
    """Every object as a box; labels only on the furniture and the `named` objects, so they stay readable."""
    for o in sorted(state.specs):
        x0, y0, z0, x1, y1, z1 = state.box(o)
        label = state.specs[o].name if state.specs[o].category in FURNITURE else f"{o} {state.specs[o].name}"
        rec.log(f"world/objects/{o}", rr.Boxes3D(
            centers=[[(x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2]],
            half_sizes=[[(x1 - x0) / 2, (y1 - y0) / 2, (z1 - z0) / 2]],
            labels=[label], colors=[_color(state, o)],
            # furniture see-through, objects solid so they stand out from what holds them
            fill_mode="TransparentFillMajorWireframe" if state.specs[o].category in (*FURNITURE, "floor") else "Solid",
            show_labels=o in named or state.specs[o].category in FURNITURE))
    rx, ry = state.robot
    rec.log("world/robot", rr.Boxes3D(centers=[[rx, ry, ROBOT_SIZE[2] / 2]], half_sizes=[np.array(ROBOT_SIZE) / 2],
                                      labels=["robot"], colors=[(80, 80, 200)],
                                      fill_mode="MajorWireframe"))  # an outline: it stands in front of the table
    if state.held is not None:
        x0, y0, z0, x1, y1, z1 = state.box(state.held)
        gripper = [[(x0 + x1) / 2, (y0 + y1) / 2, z1]]
    else:
        gripper = [[rx, ry, ROBOT_SIZE[2]]]
    rec.log("world/gripper", rr.Points3D(gripper, radii=[0.04], labels=[f"holds {state.held or 'nothing'}"]))


def record_program(path: Path | str, recording_id: str, program: Program,
                   demonstration: tuple[Action, ...] = ()) -> None:
    """Write one .rrd: the world before every step and after the last, with the plan's choices.

    The states are the ones the rollout visited (`Program.states`): nothing is executed again.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    rec = rr.RecordingStream("taskseq", recording_id=recording_id, send_properties=False)
    rec.save(path, default_blueprint=blueprint(program.initial))
    task, steps, status = program.task, program.steps, program.status
    rec.log("task", rr.TextDocument(f"{task}\nstatus: {status}\ndemonstration: "
                                    + " ".join(str(a) for a in demonstration)), static=True)
    for k, state in enumerate(program.states):
        rec.set_time("step", sequence=k)
        acting = steps[k].action.args if k < len(steps) else ()
        _log_state(rec, state, frozenset((*task.args, *acting, *([state.held] if state.held else []))))
        if k < len(demonstration):
            rec.log("demonstration/step", rr.TextLog(str(demonstration[k])))
        if k == len(steps):
            rec.log("plan/chosen", rr.TextLog(f"end: {status}"))
            break
        step = steps[k]
        alternatives = "; ".join(f"{a} {s:.2f}" for a, s in step.alternatives)
        warn = f" UNSAFE: {', '.join(step.unsafe)}" if step.unsafe else ""
        rec.log("plan/chosen", rr.TextLog(f"{step.action} score {step.score:.2f}{warn}"))
        rec.log("plan/alternatives", rr.TextLog(alternatives or "-"))
        if k == len(program.states) - 1:  # the last step was infeasible: no world after it
            rec.log("plan/chosen", rr.TextLog(f"infeasible: {program.error}", level=rr.TextLogLevel.ERROR))
    rec.flush()
    del rec
