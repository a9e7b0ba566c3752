"""The product: the shipped planner on one task in an environment, as `taskseq plan` and the web app use it.

An environment file read and checked field by field, a task parsed and
checked against it, the trained model's recorded policy with only the steps
the simulator would take offered first (`runnable_first`), and the program
it plans, printed or as JSON. The pipeline's experiments do not use this
module: Table I's policies keep their own rules (`plan.planner`).
"""

from __future__ import annotations

import json
import sys
from collections import Counter
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from jsonschema import Draft202012Validator

from .demonstrations.records import load_schema, spec_from_dict, state_from_dict
from .demonstrations.validate import LogError, check_references, check_schema, read_records
from .demonstrations.validate import _field as field_name  # the log checks' way of writing a field's path
from .features.context import StepContext
from .learn.estimator import StepScorer
from .learn.persist import describe, policy_of
from .plan.planner import (
    DONE,
    POLICIES,
    Abstain,
    LeadsBack,
    LoopAware,
    Policy,
    Program,
    Ranked,
    learned_policy,
    leaves_loops,
    run_loop,
)
from .sim.objects import ObjectSpec
from .sim.primitives import Action, try_execute
from .sim.safety import violations
from .sim.state import INSIDE, WorldState
from .sim.tasks import Task, goal_reached


def load_environment(path: Path, record: int) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """(objects, state) from a JSON environment file or a record of a JSON Lines log."""
    if path.suffix == ".jsonl":
        items = list(read_records(path))
        if not 1 <= record <= len(items):
            raise ValueError(f"{path}: has {len(items)} records, no record {record}")
        item = items[record - 1]
        check_schema(item)
        check_references(item)
        state = item.record["steps"][0]["state"]
        _check_support(path, item.line, state["objects"])
        return item.record["objects"], state
    _not_a_layout(path)
    try:
        text = path.read_text()
    except OSError as err:
        raise ValueError(f"{path}: cannot read the environment: {err}") from None
    return parse_environment(path, text)


def parse_environment(path: Path | str, text: str) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """(objects, state) of an environment file's text, checked field by field; `path` names it in errors."""
    _not_a_layout(Path(path))
    try:
        env = json.loads(text)
    except ValueError as err:
        raise ValueError(f"{path}: cannot read the environment: {err}") from None
    _check_environment(path, env)
    return env["objects"], env["state"]


def _not_a_layout(path: Path) -> None:
    """A layout (`taskseq layout`'s YAML input) given where an environment file is wanted is named as such."""
    if path.suffix in (".yaml", ".yml"):
        raise ValueError(f"{path}: a layout, not an environment; write the environment from it first: "
                         f"taskseq layout {path} --output {path.with_suffix('.json')}")


def _environment_validator() -> Draft202012Validator:
    """The log schema's rules for `objects` and a step's `state`, applied to an environment file."""
    log = load_schema()
    schema = {"type": "object", "required": ["objects", "state"],
              "properties": {"objects": log["properties"]["objects"], "state": {"$ref": "#/$defs/state"}},
              "$defs": log["$defs"]}
    return Draft202012Validator(schema)


def _check_environment(path: Path, env: Any) -> None:
    """Schema, then references: every error names the file and the field."""
    errors = sorted(_environment_validator().iter_errors(env), key=lambda e: list(e.absolute_path))
    if errors:
        raise LogError(path, 1, field_name(errors[0].absolute_path), errors[0].message)
    known: set[str] = set()
    for k, o in enumerate(env["objects"]):
        if o["id"] in known:
            raise LogError(path, 1, f"objects[{k}].id", f"object {o['id']!r} is listed twice")
        known.add(o["id"])
    state = env["state"]
    for field in sorted(known - set(state["objects"])):
        raise LogError(path, 1, f"state.objects.{field}", "object listed in 'objects' has no state")
    for obj, entry in state["objects"].items():
        if obj not in known:
            raise LogError(path, 1, f"state.objects.{obj}", f"unknown object {obj!r} (not in 'objects')")
        if entry["support"] is not None and entry["support"] not in known:
            raise LogError(path, 1, f"state.objects.{obj}.support", f"unknown object {entry['support']!r}")
    for key in ("held", "held_above"):
        if state[key] is not None and state[key] not in known:
            raise LogError(path, 1, f"state.{key}", f"unknown object {state[key]!r}")
    _check_support(path, 1, state["objects"])
    _check_physical(path, env)


def name_and_id(name: str, obj: str) -> str:
    """An object as an error names it: a person's word first, the records' id after it where the two differ."""
    return name if name == obj else f"{name} ({obj})"


def _check_physical(path: Path | str, env: dict[str, Any]) -> None:
    """What the simulator never makes, refused in a hand-written file: the robot holding what cannot be moved or a
    liquid itself, and a liquid anywhere but in a container (the planner would plan from a world that cannot be)."""
    specs = {o["id"]: o for o in env["objects"]}
    state = env["state"]

    def called(obj: str) -> str:
        return name_and_id(specs[obj]["name"], obj)

    held = state["held"]
    if held is not None and specs[held]["attributes"]["liquid"]:
        raise LogError(path, 1, "state.held", f"{called(held)} is a liquid: the robot holds the container it is in, "
                       "never the liquid")
    if held is not None and not specs[held]["attributes"]["movable"]:
        raise LogError(path, 1, "state.held", f"{called(held)} cannot be held: it is not movable")
    for obj, entry in state["objects"].items():
        support = entry["support"]
        if specs[obj]["attributes"]["liquid"] and not (entry["relation"] == INSIDE and support is not None
                                                       and specs[support]["attributes"]["container"]):
            where = "resting on nothing" if support is None else f"{entry['relation']} {called(support)}"
            raise LogError(path, 1, f"state.objects.{obj}", f"{called(obj)} is a liquid: it must be inside a "
                           f"container (relation '{INSIDE}', support a container), not {where}")


def _check_support(path: Path | str, line: int, objects: dict[str, Any]) -> None:
    """What rests on what must end at something resting on nothing: a loop would send every query of the world
    round it for ever (the planner's memory grows until it fails)."""
    for obj in objects:
        seen, cur = {obj}, obj
        while (cur := objects[cur]["support"]) is not None:
            if cur in seen:
                raise LogError(path, line, f"state.objects.{obj}.support",
                               f"the objects it rests on form a loop through {cur}")
            seen.add(cur)


LIQUID_TASKS = ("pour", "pour_to", "stir")  # tasks whose first argument is a liquid


def recorded_policy(planner: StepScorer, model_path: Path, top_k: int) -> Callable[[Task, WorldState], Policy]:
    """The loaded model as the policy its file records (greedy when it records none), for a task begun in a
    state, offering `top_k` candidates that can run (`runnable_first`); a policy this version does not know is
    refused with the file's name, at once."""
    name = policy_of(planner.meta_)
    if name not in POLICIES:
        raise ValueError(f"{model_path}: policy {name!r} is not one this version plans with ({', '.join(POLICIES)})")
    return lambda task, initial: runnable_first(learned_policy(name, planner, task, initial, top_k), planner, task,
                                                initial, top_k)


def runnable_first(policy: Policy, planner: StepScorer, task: Task, initial: WorldState, top_k: int) -> Policy:
    """`policy`'s proposals without those the simulator refuses, filled up to `top_k` from further down the model's
    ranking; `Abstain` when no candidate of the step can run.

    Refused: a step whose preconditions fail, a step that breaks a safety rule (the web page refuses it), and `done`
    before the task's goal holds. A person correcting the planner, or a robot running `taskseq plan`, is never
    offered first a step that cannot be taken. This is the product's filter, not a method's: Table I's policies
    (`plan.planner`, `evaluate.methods`) keep their rules, and their results with them."""

    def runs(state: WorldState, action: Action) -> bool:
        if action.primitive == DONE:
            return goal_reached(task, initial, state)
        return try_execute(state, action) is not None and not violations(state, action)

    def checked(ctx: StepContext, state: WorldState) -> Ranked:
        return filled(ctx, state, policy(ctx, state))

    def filled(ctx: StepContext, state: WorldState, ranked: Ranked) -> Ranked:
        out = [(y, score) for y, score in ranked if runs(state, ctx.action(y))]
        offered = {y for y, _ in ranked}
        more = planner.ranked(ctx)
        while len(out) < top_k:
            y, score = next(more, (None, 0.0))
            if y is None:
                break
            if y not in offered and runs(state, ctx.action(y)):
                out.append((y, score))
        if not out:
            raise Abstain("the planner has no step that can run here: the simulator refuses every candidate (a check "
                          "fails, a safety rule would be broken, or it is done before the goal holds)")
        return out

    if leaves_loops(policy):  # the lookahead's rule against loops, through the same filter
        def without_revisits(ctx: StepContext, state: WorldState, leads_back: LeadsBack) -> Ranked | None:
            """The lookahead's way out, filtered; none when it has none. Where its way out is `done` before the
            goal holds, which the simulator refuses, the next filtered proposal that leads out comes first: the
            lookahead ranked it, but did not check what it leads to."""
            ranked = policy.without_revisits(ctx, state, leads_back)
            if ranked is None:
                return None
            out = filled(ctx, state, ranked)
            new = next((i for i, (y, _) in enumerate(out)
                        if ctx.action(y).primitive == DONE or not leads_back(ctx.action(y))), None)
            return None if new is None else [out[new]] + out[:new] + out[new + 1:]

        return LoopAware(checked, without_revisits)
    return checked


def in_names(item: Action | Task, specs: Mapping[str, ObjectSpec], told: Mapping[str, str] | None = None) -> str:
    """A step or task as a person reads it, `pour(milk)`: the objects' names where the records write their ids, or
    the words `told` gives each (`told_apart`: `stir(cocoa in mug)` where two objects are called cocoa); a step of
    no object is its primitive's name alone (`done`)."""
    head = item.primitive if isinstance(item, Action) else item.name
    words = [told[a] if told is not None else specs[a].name for a in item.args]
    return f"{head}({', '.join(words)})" if item.args else head


def where(state: WorldState, obj: str) -> str:
    """Where an object is, in words: `in mug`, `on kitchen_table`, `held`."""
    if obj == state.held:
        return "held"
    parent = state.support.get(obj)
    if parent is None:
        return "on its own"
    return f"{'in' if parent[1] == INSIDE else 'on'} {state.specs[parent[0]].name}"


def told_apart(state: WorldState) -> dict[str, str]:
    """Every object's name as a list of objects shows it: where several objects here share a name, each says where
    it is (`cocoa in mug`, `cocoa in milk_carton`, `cup held`), and where that still leaves two alike, its id too
    (`cup on kitchen_table [obj14]`, bracketed as `taskseq plan` prints ids). A person tells objects apart by what
    the picture shows, not by ids."""
    sharing = Counter(spec.name for spec in state.specs.values())
    shown = {o: spec.name if sharing[spec.name] < 2 else f"{spec.name} {where(state, o)}"
             for o, spec in state.specs.items()}
    alike = Counter(shown.values())
    return {o: f"{text} [{o}]" if alike[text] > 1 else text for o, text in shown.items()}


def ids_hint(item: Action | Task, specs: Mapping[str, ObjectSpec]) -> str | None:
    """The step or task as the records write it (`pour(obj27)`), to show beside its names only where they differ."""
    return str(item) if any(specs[o].name != o for o in item.args) else None


def with_ids(item: Action | Task, specs: Mapping[str, ObjectSpec]) -> str:
    """`in_names`, then the objects' ids in brackets where they differ from the names: `pour(milk)  [obj27]`."""
    return in_names(item, specs) + (f"  [{', '.join(item.args)}]" if ids_hint(item, specs) else "")


def plan_task(model_path: Path, env: Path, record: int, task_text: str, max_steps: int,
              top_k: int) -> tuple[Program, dict[str, ObjectSpec], str]:
    """The program the model plans for the task in that environment, its objects, and what the model is
    (its method, settings and policy, `persist.describe`); the program is planned with the policy the file
    records (greedy when it records none)."""
    planner = StepScorer.load(model_path)
    policy_for = recorded_policy(planner, model_path, top_k)
    objects, state_dict = load_environment(env, record)
    specs = {o["id"]: spec_from_dict(o) for o in objects}
    state = state_from_dict(specs, state_dict)
    task = parse_task(task_text, state)
    program = run_loop(policy_for(task, state), state, task, max_steps)
    return program, specs, describe(planner.meta_)


def parse_task(task_text: str, state: WorldState) -> Task:
    """The task a user typed, checked against the environment: its objects exist, a liquid task names a liquid,
    an object to move or throw away is a movable thing (not a liquid, not a bin to throw away) going somewhere
    else than itself or what rests on it, and the goal does not hold already. Every task the benchmark's worlds
    pose passes; the refused ones are tasks of no kind it poses, which the planner took to its step cap or could
    do only by breaking a safety rule (grasping the water to throw it away), or which have nothing to do. A refusal
    names the task and its objects by their names, each object's id after it where the two differ."""
    task = _by_ids(Task.parse(task_text), state)
    task.check_objects(state)
    specs = state.specs

    def named(obj: str) -> str:
        return name_and_id(specs[obj].name, obj)

    said = in_names(task, specs)

    first = task.args[0]
    if task.name in LIQUID_TASKS and not specs[first].has("liquid"):
        inside = [specs[o].name for o in state.liquids_in(first)]
        raise ValueError(f"task {said}: {named(first)} is not a liquid; {task.name} names "
                         + (f"the liquid in it: {' or '.join(inside)}" if inside else "a liquid"))
    source = state.container_of(first)
    if task.name in LIQUID_TASKS and source is None:
        raise ValueError(f"task {said}: {named(first)} is in no container, so nothing can {task.name.split('_')[0]} "
                         "it; a liquid stands in its bottle, cup or pot")
    if task.name == "pour" and not any(s.has("container") and s.category != "bin" and not s.has("liquid")
                                       for o, s in specs.items() if o != source):
        raise ValueError(f"task {said}: {named(source)} is the only container here, so {specs[first].name} has "
                         "nowhere to be poured; pour needs a cup, a bowl or another container to pour into")
    if task.name == "pour_to" and not specs[task.args[1]].has("container"):
        raise ValueError(f"task {said}: {named(task.args[1])} is not a container; pour_to pours into a cup, a bowl "
                         "or another container")
    if len(task.args) == 2 and task.args[1] == first:
        raise ValueError(f"task {said}: names {named(first)} twice; the second argument is where it goes")
    if task.name == "throw_away" and specs[first].category == "bin":
        raise ValueError(f"task {said}: {named(first)} is a bin itself")
    if task.name in ("pick_and_place", "throw_away"):
        if specs[first].has("liquid"):
            raise ValueError(f"task {said}: {named(first)} is a liquid; {task.name} takes the object that holds it")
        if not specs[first].has("movable"):
            raise ValueError(f"task {said}: {named(first)} cannot be moved")
    if task.name == "pick_and_place" and task.args[1] in state.descendants(first):
        raise ValueError(f"task {said}: {named(task.args[1])} rests on {named(first)}, so it cannot be put there")
    if goal_reached(task, state, state):
        raise ValueError(f"the goal of {with_ids(task, specs)} already holds here; choose another task")
    return task


def _by_ids(task: Task, state: WorldState) -> Task:
    """The task with each argument that is no object's id but the name of one object here (`stir(coffee)`) replaced
    by that object's id; a name several objects share is refused with their ids."""
    called: dict[str, list[str]] = {}
    for o, spec in state.specs.items():
        called.setdefault(spec.name, []).append(o)
    args = []
    for a in task.args:
        if a not in state.specs and len(called.get(a, ())) > 1:
            each = ", ".join(f"{o} {where(state, o)}" for o in called[a])
            raise ValueError(f"task {task}: {len(called[a])} objects here are called {a} ({each}); "
                             "name one by its id")
        args.append(a if a in state.specs or a not in called else called[a][0])
    return Task(task.name, tuple(args))


def program_json(program: Program, specs: Mapping[str, ObjectSpec]) -> str:
    """The program for a machine: steps and tasks as the records write them, and `names` giving the name of every
    object they mention (names may repeat in a room; ids do not)."""
    items = [program.task, *(s.action for s in program.steps), *(a for s in program.steps for a, _ in s.alternatives)]
    return json.dumps({
        "task": str(program.task), "status": program.status, "goal_reached": program.goal_reached,
        "steps": [{"action": str(s.action), "score": s.score, "unsafe": s.unsafe,
                   "alternatives": [[str(a), sc] for a, sc in s.alternatives]} for s in program.steps],
        "error": program.error,
        "names": {o: specs[o].name for o in sorted({o for item in items for o in item.args})},
    }, indent=2)


def print_program(program: Program, specs: Mapping[str, ObjectSpec], out=None) -> None:
    """The program as a person reads it: each step in the objects' names (their ids, which the records write, after
    it where they differ), its score, the next best steps and any safety rule it broke."""
    out = out or sys.stdout

    print(f"program for {with_ids(program.task, specs)}:", file=out)
    labels = [with_ids(s.action, specs) for s in program.steps]
    width = max(map(len, labels), default=0)
    counts = Counter(spec.name for spec in specs.values())

    def alternative(a: Action) -> str:
        """In names, with the ids where a name is shared: `grasp(cup) [obj14]; grasp(cup) [obj13]` tells them apart."""
        shared = any(counts[specs[o].name] > 1 for o in a.args)
        return in_names(a, specs) + (f" [{', '.join(a.args)}]" if shared else "")

    for k, (s, text) in enumerate(zip(program.steps, labels, strict=True), start=1):
        alts = "; ".join(f"{alternative(a)} {sc:.2f}" for a, sc in s.alternatives)
        warn = f"  UNSAFE: {', '.join(s.unsafe)}" if s.unsafe else ""
        print(f"{k:3d}. {text:{width}s}  score {s.score:6.2f}   next best: {alts}{warn}", file=out)
    print(f"status: {program.status}; goal {'reached' if program.goal_reached else 'not reached'}"
          + (f"; {program.error}" if program.error else ""), file=out)
