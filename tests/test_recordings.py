"""Rerun recordings read back with Rerun's own API."""

from rerun.chunk import RrdReader

from pipeline.plan.planner import PlanStep
from pipeline.sim.primitives import Action
from pipeline.sim.tasks import Task
from pipeline.track.recordings import record_program
from tests.conftest import world


def test_a_recording_holds_the_objects_robot_plan_and_demonstration_per_step(tmp_path):
    state = world({2: 0.0}, [(14, 2, 0, 0.3), (20, 2, 0, -0.3), (27, 20)])
    actions = [Action.parse(a) for a in ("move_close(obj20)", "grasp(obj20)", "hold_above(obj20,obj14)",
                                         "follow_traj_pour(obj20,obj14)")]
    steps = [PlanStep(a, 1.5 - k, [(Action.parse("grasp(obj14)"), 0.5 - k)]) for k, a in enumerate(actions)]
    path = tmp_path / "rec.rrd"
    record_program(path, "env/pour", state, Task("pour_to", ("obj27", "obj14")), steps, "done", tuple(actions))
    store = RrdReader(path).store()
    entities = set(store.schema().entity_paths())
    assert {f"/world/objects/{o}" for o in state.specs} <= entities
    assert {"/world/robot", "/world/gripper", "/plan/chosen", "/plan/alternatives", "/demonstration/step",
            "/task"} <= entities
    steps_seen: dict[str, set[int]] = {}
    texts = []
    for chunk in store.stream().to_chunks():
        batch = chunk.to_record_batch()
        if "step" in batch.schema.names:
            steps_seen.setdefault(chunk.entity_path, set()).update(batch.column("step").to_pylist())
        if chunk.entity_path == "/plan/chosen":
            texts += batch.column("TextLog:text").to_pylist()
    assert steps_seen["/world/objects/obj14"] == {0, 1, 2, 3, 4}  # before each step and after the last
    assert steps_seen["/plan/chosen"] == {0, 1, 2, 3, 4}
    flat = [t[0] if isinstance(t, list) else t for t in texts]
    assert "move_close(obj20) score 1.50" in flat and "end: done" in flat
