"""Rerun recordings read back with Rerun's own API."""

from rerun.chunk import RrdReader

from taskseq.plan.planner import Program, run_loop
from taskseq.sim.primitives import Action
from taskseq.sim.tasks import Task
from taskseq.track.recordings import record_program
from tests.conftest import world


def rollout(state, task: Task, actions: list[Action]) -> Program:
    """The rollout loop run by a policy that takes `actions` in turn, then `done`."""
    taken: list[Action] = []

    def policy(ctx, now):
        step = len(taken)
        action = actions[step] if step < len(actions) else Action("done")
        taken.append(action)
        return [(ctx.encode(action), 1.5 - step), (ctx.encode(Action.parse("grasp(obj14)")), 0.5 - step)]

    return run_loop(policy, state, task)


def test_a_recording_holds_the_objects_robot_plan_and_demonstration_per_step(tmp_path):
    state = world({2: 0.0}, [(14, 2, 0, 0.3), (20, 2, 0, -0.3), (27, 20)])
    actions = [Action.parse(a) for a in ("move_close(obj20)", "grasp(obj20)", "hold_above(obj20,obj14)",
                                         "follow_traj_pour(obj20,obj14)")]
    program = rollout(state, Task("pour_to", ("obj27", "obj14")), actions)
    assert program.status == "done" and len(program.states) == len(actions) + 1
    path = tmp_path / "rec.rrd"
    record_program(path, "env/pour", program, tuple(actions))
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


def test_a_recording_opens_framed_on_the_furniture_with_few_labels(tmp_path):
    from taskseq.track.recordings import FURNITURE, framing

    state = world({2: 0.0}, [(14, 2, 0, 0.3), (20, 2, 0, -0.3), (27, 20)])
    position, target = framing(state)
    boxes = [state.box(o) for o in state.specs if state.specs[o].category in FURNITURE]
    low = [min(b[i] for b in boxes) for i in range(3)]
    high = [max(b[i + 3] for b in boxes) for i in range(3)]
    assert all(lo <= t <= hi for lo, t, hi in zip(low, target, high, strict=True))  # looks at the furniture
    assert 1.0 < float(((position - target) ** 2).sum() ** 0.5) < 10.0  # from near it, not from across the floor
    action = Action.parse("move_close(obj20)")
    path = tmp_path / "rec.rrd"
    record_program(path, "env/pour", rollout(state, Task("pour", ("obj27",)), [action]), (action,))
    shown = {}
    for chunk in RrdReader(path).store().stream().to_chunks():
        batch = chunk.to_record_batch()
        for name in batch.schema.names:
            if name.endswith("show_labels"):
                shown.setdefault(chunk.entity_path, []).extend(batch.column(name).to_pylist())
    flat = {e.rsplit("/", 1)[-1]: any(v[0] if isinstance(v, list) else v for v in vals) for e, vals in shown.items()
            if e.startswith("/world/objects/")}
    assert flat["obj27"] and flat["obj20"]  # the task's object and the step's argument
    assert not flat["obj14"]  # an object the program does not touch
