"""Chained tasks (recipes) in environments held out from training.

A recipe is a list of programs run one after the other in the simulator, each
from the state the previous one left. It succeeds when every program stops
with `done`, reaches its goal and breaks no safety rule. With feedback, an
observer picks among the top 3 candidates at the first step of each program,
following what the demonstrator would do from that state.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from threadpoolctl import threadpool_limits

from ..evaluate.methods import ScorerMethod
from ..features.context import StepContext
from ..features.dataset import StepMeta
from ..plan.planner import learned_policy, run_loop
from ..settings import Recipes
from ..sim.catalog import ENVIRONMENTS_BY_ID, build_environment
from ..sim.demonstrator import NoDemonstration, choose_vessel, demonstrate
from ..sim.primitives import PreconditionError
from ..sim.scenarios import Scenario
from ..sim.state import WorldState
from ..sim.tasks import Task
from .robustness import observer

NextTask = Callable[[WorldState, WorldState], Task]  # (initial, current) -> the next program's task


def _pour(liquid: str) -> NextTask:
    return lambda initial, state: Task("pour", (liquid,))


def _pour_into_first(liquid: str, first: str) -> NextTask:
    """Pour `liquid` where the recipe's first liquid went."""
    return lambda initial, state: Task("pour_to", (liquid, state.container_of(first)))


def _pour_to_vessel_of(liquid: str, first: str) -> NextTask:
    """Pour `liquid` into the vessel the demonstrator would choose for the recipe's first liquid."""
    return lambda initial, state: Task("pour_to", (liquid, choose_vessel(initial, first)))


def _fixed(name: str, *args: str) -> NextTask:
    return lambda initial, state: Task(name, args)


@dataclass(frozen=True)
class Recipe:
    name: str
    env_id: str
    programs: tuple[NextTask, ...]
    description: str


def _sweet(env: str, drink: str, sugar: str, label: str) -> Recipe:
    return Recipe("serve-sweet-tea", env, (_pour(drink), _pour_into_first(sugar, drink), _fixed("stir", drink)),
                  f"pour({label}) -> pour_to(sugar, its cup) -> stir({label})")


def _with_milk(env: str, drink: str, label: str) -> Recipe:
    return Recipe("serve-coffee-with-milk", env, (_pour_to_vessel_of(drink, drink), _pour_into_first("obj28", drink)),
                  f"pour_to({label}, cup) -> pour_to(milk, the cup)")


RECIPES: tuple[Recipe, ...] = (
    _sweet("env06", "obj32", "obj33", "coffee"),
    _sweet("env08", "obj31", "obj33", "tea"),
    _sweet("env10", "obj28", "obj33", "milk"),
    _with_milk("env02", "obj29", "juice"),
    _with_milk("env06", "obj32", "coffee"),
    _with_milk("env13", "obj32", "coffee"),
    *(Recipe("empty-and-throw-away", env, (_pour("obj30"), _fixed("throw_away", "obj23")),
             "pour(soda) -> throw_away(soda can)") for env in ("env03", "env05", "env11")),
    Recipe("serve-and-store", "env04", (_pour("obj28"), _fixed("pick_and_place", "obj21", "obj08")),
           "pour(milk) -> pick_and_place(milk carton, shelf)"),
    Recipe("serve-and-store", "env09", (_pour("obj32"), _fixed("pick_and_place", "obj25", "obj09")),
           "pour(coffee) -> pick_and_place(coffee pot, cabinet)"),
    Recipe("serve-and-store", "env12", (_pour("obj31"), _fixed("pick_and_place", "obj24", "obj09")),
           "pour(tea) -> pick_and_place(kettle, cabinet)"),
)


@dataclass
class RecipeOutcome:
    recipe: str
    env_id: str
    feedback: bool
    success: bool
    programs: list[tuple[str, str, bool]]  # task, status, program success


def run_recipe(method: ScorerMethod, recipe: Recipe, feedback: bool, max_steps: int = 20,
               observer_k: int = Recipes.observer_k) -> RecipeOutcome:
    """Each program from where the last one left the world, its steps picked by the method's policy; with
    `feedback`, the observer picks the demonstrator's step among the planner's `observer_k` best at the start
    of each program."""
    initial = state = build_environment(ENVIRONMENTS_BY_ID[recipe.env_id])
    programs = []
    for next_task in recipe.programs:
        task = next_task(initial, state)
        choose = None
        if feedback:
            try:
                demos = tuple(tuple(d) for d in demonstrate(state, task))
            except (NoDemonstration, PreconditionError):
                demos = ()
            choose = observer(demos, 1)
        policy = learned_policy(method.policy, method.planner_, task, state, observer_k)
        program = run_loop(policy, state, task, max_steps, choose=choose)
        programs.append((str(task), program.status, program.success))
        state = program.final
        if not program.success:
            break
    ok = len(programs) == len(recipe.programs) and all(p[2] for p in programs)
    return RecipeOutcome(recipe.name, recipe.env_id, feedback, ok, programs)


def recipe_training_sets(meta: list[StepMeta]) -> dict[str, list[int]]:
    """Per recipe kind, the training steps: every step outside the kind's environments."""
    out = {}
    for name in dict.fromkeys(r.name for r in RECIPES):
        held_out = {r.env_id for r in RECIPES if r.name == name}
        out[name] = [i for i, m in enumerate(meta) if m.scenario_id.split("/")[0] not in held_out]
    return out


def evaluate_recipes(make: Callable[[], ScorerMethod], contexts: list[StepContext], meta: list[StepMeta],
                     scenarios: Mapping[str, Scenario], max_steps: int = 20,
                     observer_k: int = Recipes.observer_k) -> list[RecipeOutcome]:
    """Train (or load) once per recipe kind, without the kind's three environments, and run each recipe.

    `scenarios` are the benchmark's (methods that consult the demonstrator read the training ones).
    """
    out = []
    with threadpool_limits(limits=1):  # the same sums, so the same bytes, in any process (see learn/estimator.py)
        for name, train in recipe_training_sets(meta).items():
            method = make().fit([contexts[i] for i in train], [meta[i] for i in train], scenarios)
            for recipe in (r for r in RECIPES if r.name == name):
                for feedback in (False, True):
                    out.append(run_recipe(method, recipe, feedback, max_steps, observer_k))
    return out


def recipe_report(outcomes: list[RecipeOutcome]) -> dict[str, Any]:
    """Totals with and without feedback, and every run with its programs (reports/recipes.json)."""
    descriptions = {(r.name, r.env_id): r.description for r in RECIPES}
    rows = [{"recipe": o.recipe, "env_id": o.env_id, "description": descriptions[(o.recipe, o.env_id)],
             "feedback": o.feedback, "success": o.success,
             "programs": [{"task": t, "status": st, "success": ok} for t, st, ok in o.programs]} for o in outcomes]
    totals = {"no_feedback": sum(o.success for o in outcomes if not o.feedback),
              "feedback_first_step": sum(o.success for o in outcomes if o.feedback), "recipes": len(RECIPES)}
    return {"totals": totals, "runs": rows}


PROGRAM_COLUMNS = ("recipe", "env_id", "feedback", "position", "task", "status", "success", "recipe_success")


def program_rows(outcomes: list[RecipeOutcome]) -> list[dict[str, Any]]:
    """Every program a recipe ran, in order, one row each (a failed program is a recipe's last)."""
    return [{"recipe": o.recipe, "env_id": o.env_id, "feedback": o.feedback, "position": i, "task": task,
             "status": status, "success": ok, "recipe_success": o.success}
            for o in outcomes for i, (task, status, ok) in enumerate(o.programs)]
