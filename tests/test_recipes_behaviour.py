"""Recipes, judged on planners whose every step is known: the chained tasks, the feedback, the tables.

No model is fitted here: a scripted planner replays the demonstrator's steps (or offers `done` first at
the start of each program), so each recipe's outcome is known before it runs.
"""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_info

from taskseq.experiments.recipes import (  # the builders too: RECIPES is built when the module loads
    PROGRAM_COLUMNS,
    RECIPES,
    RecipeOutcome,
    _fixed,
    _pour,
    _pour_into_first,
    _pour_to_vessel_of,
    _sweet,
    _with_milk,
    evaluate_recipes,
    program_rows,
    recipe_report,
    recipe_training_sets,
    run_recipe,
)
from taskseq.features.context import NO_PRIM
from taskseq.features.dataset import StepMeta
from taskseq.sim.catalog import ENVIRONMENTS_BY_ID, build_environment
from taskseq.sim.demonstrator import choose_vessel, demonstrate
from taskseq.sim.primitives import Action, execute
from taskseq.sim.tasks import Task

DONE = Action("done")


def demonstrated(recipe) -> list[tuple[str, list[Action]]]:
    """Each program's task (as text) and the demonstrator's first sequence for it, run one after the other."""
    initial = state = build_environment(ENVIRONMENTS_BY_ID[recipe.env_id])
    out = []
    for next_task in recipe.programs:
        task = next_task(initial, state)
        actions = demonstrate(state, task)[0]
        for action in actions:
            state = execute(state, action)
        out.append((str(task), actions))
    return out


class Scripted:
    """A planner that offers the next step of a script; with `done_first`, `done` heads the offer at the
    first step of every program (only an observer's pick then keeps the right step)."""

    def __init__(self, script: list[Action], done_first: bool = False, done_at: tuple[int, ...] = ()) -> None:
        self.script = list(script)
        self.done_first = done_first
        self.done_at = done_at  # calls (counted from 0) at which `done` heads the offer too
        self.asked: list[int] = []  # the k of every call

    def ranked(self, ctx):  # the whole ranking, which a policy walking down it reads
        return iter(self.top_k(ctx, 1_000_000))

    def top_k(self, ctx, k):
        call = len(self.asked)
        self.asked.append(k)
        right = self.script.pop(0)
        offer = [right]
        first = self.done_first and ctx.prev_prims == (NO_PRIM, NO_PRIM)
        if (first or call in self.done_at) and right != DONE:
            offer = [DONE, right]
        return [(ctx.encode(a), float(-i)) for i, a in enumerate(offer)][:k]


class Method:
    def __init__(self, planner, policy: str = "greedy") -> None:
        self.planner_ = planner
        self.policy = policy


class ReleaseFirst:
    """Offers `release` of the task's first object (nothing is held: it cannot run) first, then `done`."""

    def ranked(self, ctx):  # the whole ranking, which a policy walking down it reads
        return iter(self.top_k(ctx, 1_000_000))

    def top_k(self, ctx, k):
        offer = [Action("release", (ctx.object_ids[int(np.argmax(ctx.task_rel[:, 0]))],)), DONE]
        return [(ctx.encode(a), float(-i)) for i, a in enumerate(offer)][:k]


def test_a_recipe_picks_steps_with_the_methods_policy():
    recipe = RECIPES[0]
    greedy = run_recipe(Method(ReleaseFirst()), recipe, feedback=False)
    feasible = run_recipe(Method(ReleaseFirst(), "feasible"), recipe, feedback=False)
    assert greedy.programs[0][1] == "infeasible"  # the release was sent
    assert feasible.programs[0][1] == "done"  # the release was refused before it was sent: `done` is next


def script_of(recipe) -> list[Action]:
    return [a for _, actions in demonstrated(recipe) for a in (*actions, DONE)]


@pytest.mark.parametrize("recipe", RECIPES, ids=lambda r: f"{r.name}-{r.env_id}")
def test_a_planner_that_follows_the_demonstrator_completes_every_recipe(recipe):
    expected = demonstrated(recipe)
    planner = Scripted(script_of(recipe))
    out = run_recipe(Method(planner), recipe, feedback=False)
    assert out == RecipeOutcome(recipe.name, recipe.env_id, False, True,
                                [(task, "done", True) for task, _ in expected])
    assert not planner.script  # every step and every `done` was asked for, nothing more
    assert set(planner.asked) == {3}  # the observer's k by default


def test_each_program_builds_the_methods_policy_for_its_own_task(monkeypatch):
    """A policy that imagines steps (the lookahead) needs the program's task and the world it begins in (where its
    goal is judged from): each program passes its own."""
    import taskseq.experiments.recipes as recipes_module

    built, starts, real = [], [], recipes_module.learned_policy

    def spy(name, planner, task, start, top_k=3, perceive=None):
        built.append((name, str(task), top_k))
        starts.append(start.key())
        return real(name, planner, task, start, top_k, perceive)

    monkeypatch.setattr(recipes_module, "learned_policy", spy)
    recipe = next(r for r in RECIPES if r.name == "serve-sweet-tea")
    out = run_recipe(Method(Scripted(script_of(recipe)), "feasible"), recipe, feedback=False, observer_k=2)
    assert out.success
    assert built == [("feasible", task, 2) for task, _ in demonstrated(recipe)]
    assert starts[0] == build_environment(ENVIRONMENTS_BY_ID[recipe.env_id]).key()
    assert len(set(starts)) == len(starts)  # each program from where the last one left the world


def test_each_program_of_a_recipe_starts_where_the_last_one_left_the_world():
    sweet = next(r for r in RECIPES if r.name == "serve-sweet-tea" and r.env_id == "env06")
    initial = build_environment(ENVIRONMENTS_BY_ID["env06"])
    state = initial
    for action in demonstrate(initial, sweet.programs[0](initial, initial))[0]:
        state = execute(state, action)
    cup = state.container_of("obj32")
    assert cup != initial.container_of("obj32")  # the coffee moved: the sugar follows it, not the pot
    assert [t for t, _ in demonstrated(sweet)] == ["pour(obj32)", f"pour_to(obj33,{cup})", "stir(obj32)"]

    milk = next(r for r in RECIPES if r.name == "serve-coffee-with-milk" and r.env_id == "env02")
    vessel = choose_vessel(build_environment(ENVIRONMENTS_BY_ID["env02"]), "obj29")
    assert [t for t, _ in demonstrated(milk)] == [f"pour_to(obj29,{vessel})", f"pour_to(obj28,{vessel})"]


@pytest.mark.parametrize("recipe", [RECIPES[0], RECIPES[3], RECIPES[6], RECIPES[9]], ids=lambda r: r.name)
def test_feedback_rescues_the_first_step_of_every_program(recipe):
    expected = demonstrated(recipe)
    alone = run_recipe(Method(Scripted(script_of(recipe), done_first=True)), recipe, feedback=False)
    # `done` at once: the first program stops without its goal, and the recipe stops with it
    assert alone == RecipeOutcome(recipe.name, recipe.env_id, False, False, [(expected[0][0], "done", False)])
    helped = run_recipe(Method(Scripted(script_of(recipe), done_first=True)), recipe, feedback=True)
    assert helped == RecipeOutcome(recipe.name, recipe.env_id, True, True,
                                   [(task, "done", True) for task, _ in expected])


def test_feedback_helps_at_the_first_step_of_a_program_only():
    recipe = RECIPES[0]
    expected = demonstrated(recipe)
    for feedback in (False, True):  # `done` offered first at the second step: no observer is there to help
        out = run_recipe(Method(Scripted(script_of(recipe), done_at=(1,))), recipe, feedback=feedback)
        assert out == RecipeOutcome(recipe.name, recipe.env_id, feedback, False, [(expected[0][0], "done", False)])


class Wander:
    """A planner that never stops: it moves close to the task's first object, again and again."""

    def __init__(self) -> None:
        self.asked: list[int] = []

    def ranked(self, ctx):  # the whole ranking, which a policy walking down it reads
        return iter(self.top_k(ctx, 1_000_000))

    def top_k(self, ctx, k):
        self.asked.append(k)
        target = ctx.object_ids[int(np.flatnonzero(ctx.task_rel[:, 0])[0])]
        return [(ctx.encode(Action("move_close", (target,))), 0.0), (ctx.encode(DONE), -1.0)][:k]


def test_a_program_that_never_stops_is_cut_after_twenty_steps():
    planner = Wander()
    out = run_recipe(Method(planner), RECIPES[0], feedback=False)
    assert out.programs == [("pour(obj32)", "step_cap", False)] and not out.success
    assert len(planner.asked) == 21  # twenty steps taken, the twenty-first refused


def test_feedback_picks_only_among_the_offered_candidates():
    recipe = RECIPES[0]
    # with one candidate offered, the observer has only `done` to pick
    out = run_recipe(Method(Scripted(script_of(recipe), done_first=True)), recipe, feedback=True, observer_k=1)
    assert out.programs == [(demonstrated(recipe)[0][0], "done", False)] and not out.success


def test_a_program_cut_at_max_steps_ends_the_recipe():
    recipe = RECIPES[0]
    planner = Scripted(script_of(recipe))
    n = len(demonstrated(recipe)[0][1])
    out = run_recipe(Method(planner), recipe, feedback=False, max_steps=n - 1, observer_k=2)
    assert out == RecipeOutcome(recipe.name, recipe.env_id, False, False, [("pour(obj32)", "step_cap", False)])
    assert set(planner.asked) == {2}


def test_feedback_without_a_demonstration_leaves_the_planner_alone():
    # stir before anything was poured: the demonstrator has no sequence, so the observer keeps the robot's pick
    recipe = next(r for r in RECIPES if r.name == "serve-sweet-tea")
    stir_first = type(recipe)(recipe.name, recipe.env_id, recipe.programs[2:], recipe.description)
    out = run_recipe(Method(Scripted([DONE], done_first=True)), stir_first, feedback=True)
    assert out == RecipeOutcome(recipe.name, recipe.env_id, True, False, [("stir(obj32)", "done", False)])


def meta_in(envs: list[str]) -> list[StepMeta]:
    return [StepMeta(f"seq{i}", f"{env}/task{i}", 0) for i, env in enumerate(envs)]


def test_each_recipe_kind_trains_on_every_step_outside_its_three_environments():
    envs = ["env01", "env02", "env03", "env04", "env06", "env06", "env07", "env13"]
    sets = recipe_training_sets(meta_in(envs))
    assert list(sets) == ["serve-sweet-tea", "serve-coffee-with-milk", "empty-and-throw-away", "serve-and-store"]
    assert sets == {"serve-sweet-tea": [0, 1, 2, 3, 6, 7],  # not env06, env08, env10
                    "serve-coffee-with-milk": [0, 2, 3, 6],  # not env02, env06, env13
                    "empty-and-throw-away": [0, 1, 3, 4, 5, 6, 7],  # not env03, env05, env11
                    "serve-and-store": [0, 1, 2, 4, 5, 6, 7]}  # not env04, env09, env12


class Recorder:
    """A method whose planner says `done` at once; records what each fit was given."""

    fits: list = []
    made: list = []
    policy = "greedy"

    def fit(self, contexts, meta, scenarios):
        self.blas_threads = {pool["num_threads"] for pool in threadpool_info()}
        Recorder.made.append(self)
        Recorder.fits.append((list(contexts), [m.scenario_id for m in meta], scenarios))
        self.planner_ = Wander()
        return self


def test_evaluate_recipes_fits_once_per_kind_and_runs_each_recipe_without_then_with_feedback():
    envs = ["env01", "env02", "env03", "env04", "env06", "env07", "env13"]
    meta = meta_in(envs)
    contexts = [f"ctx{i}" for i in range(len(envs))]
    scenarios = {"x": "scenario"}
    Recorder.fits, Recorder.made = [], []
    out = evaluate_recipes(Recorder, contexts, meta, scenarios, max_steps=4, observer_k=2)
    sets = recipe_training_sets(meta)
    assert [f[0] for f in Recorder.fits] == [[contexts[i] for i in s] for s in sets.values()]
    assert [f[1] for f in Recorder.fits] == [[meta[i].scenario_id for i in s] for s in sets.values()]
    assert all(f[2] is scenarios for f in Recorder.fits)
    order = [r for name in sets for r in RECIPES if r.name == name]
    assert [(o.recipe, o.env_id, o.feedback) for o in out] == [
        (r.name, r.env_id, fb) for r in order for fb in (False, True)]
    assert not any(o.success for o in out)
    assert all(o.programs == [(o.programs[0][0], "step_cap", False)] for o in out)
    # each run asked its planner max_steps + 1 times, for the observer's k candidates
    assert [len(f.planner_.asked) for f in Recorder.made] == [5 * 2 * 3] * 4
    assert {k for f in Recorder.made for k in f.planner_.asked} == {2}
    assert all(f.blas_threads == {1} for f in Recorder.made)  # one BLAS thread: the same sums in any process


def test_evaluate_recipes_cuts_programs_at_twenty_steps_and_offers_three_by_default():
    Recorder.fits, Recorder.made = [], []
    evaluate_recipes(Recorder, ["ctx"], meta_in(["env01"]), {})
    assert [len(f.planner_.asked) for f in Recorder.made] == [21 * 2 * 3] * 4
    assert {k for f in Recorder.made for k in f.planner_.asked} == {3}


def outcomes() -> list[RecipeOutcome]:
    return [RecipeOutcome("serve-sweet-tea", "env06", False, False, [("pour(obj32)", "infeasible", False)]),
            RecipeOutcome("serve-sweet-tea", "env06", True, True,
                          [("pour(obj32)", "done", True), ("pour_to(obj33,obj05)", "done", True),
                           ("stir(obj32)", "done", True)]),
            RecipeOutcome("serve-and-store", "env12", False, True,
                          [("pour(obj31)", "done", True), ("pick_and_place(obj24,obj09)", "done", True)]),
            RecipeOutcome("serve-and-store", "env12", True, False, [("pour(obj31)", "step_cap", False)]),
            RecipeOutcome("serve-and-store", "env04", False, True,
                          [("pour(obj28)", "done", True), ("pick_and_place(obj21,obj08)", "done", True)])]


def test_the_report_counts_successes_with_and_without_feedback_and_lists_every_program():
    report = recipe_report(outcomes())
    assert report["totals"] == {"no_feedback": 2, "feedback_first_step": 1, "recipes": 12}
    assert report["runs"][0] == {
        "recipe": "serve-sweet-tea", "env_id": "env06",
        "description": "pour(coffee) -> pour_to(sugar, its cup) -> stir(coffee)", "feedback": False,
        "success": False, "programs": [{"task": "pour(obj32)", "status": "infeasible", "success": False}]}
    assert report["runs"][2]["description"] == "pour(tea) -> pick_and_place(kettle, cabinet)"
    assert [r["feedback"] for r in report["runs"]] == [False, True, False, True, False]
    assert [r["success"] for r in report["runs"]] == [False, True, True, False, True]
    assert [len(r["programs"]) for r in report["runs"]] == [1, 3, 2, 1, 2]
    assert report["runs"][1]["programs"][1] == {"task": "pour_to(obj33,obj05)", "status": "done", "success": True}


def test_program_rows_are_one_per_program_in_order():
    rows = program_rows(outcomes())
    assert len(rows) == 9 and all(tuple(r) == PROGRAM_COLUMNS for r in rows)
    assert rows[0] == {"recipe": "serve-sweet-tea", "env_id": "env06", "feedback": False, "position": 0,
                       "task": "pour(obj32)", "status": "infeasible", "success": False, "recipe_success": False}
    assert [r["position"] for r in rows] == [0, 0, 1, 2, 0, 1, 0, 0, 1]
    assert rows[3] == {"recipe": "serve-sweet-tea", "env_id": "env06", "feedback": True, "position": 2,
                       "task": "stir(obj32)", "status": "done", "success": True, "recipe_success": True}
    assert [r["recipe_success"] for r in rows] == [False, True, True, True, True, True, False, True, True]
    assert [r["env_id"] for r in rows[4:]] == ["env12"] * 3 + ["env04"] * 2
    assert rows[8]["task"] == "pick_and_place(obj21,obj08)" and rows[6]["status"] == "step_cap"


def test_every_recipe_has_its_kind_environment_and_description():
    assert [(r.name, r.env_id, len(r.programs)) for r in RECIPES] == [
        ("serve-sweet-tea", "env06", 3), ("serve-sweet-tea", "env08", 3), ("serve-sweet-tea", "env10", 3),
        ("serve-coffee-with-milk", "env02", 2), ("serve-coffee-with-milk", "env06", 2),
        ("serve-coffee-with-milk", "env13", 2),
        ("empty-and-throw-away", "env03", 2), ("empty-and-throw-away", "env05", 2),
        ("empty-and-throw-away", "env11", 2),
        ("serve-and-store", "env04", 2), ("serve-and-store", "env09", 2), ("serve-and-store", "env12", 2)]
    assert [r.description for r in RECIPES[:7:3]] == [
        "pour(coffee) -> pour_to(sugar, its cup) -> stir(coffee)", "pour_to(juice, cup) -> pour_to(milk, the cup)",
        "pour(soda) -> throw_away(soda can)"]
    assert RECIPES[1].description == "pour(tea) -> pour_to(sugar, its cup) -> stir(tea)"
    assert RECIPES[2].description == "pour(milk) -> pour_to(sugar, its cup) -> stir(milk)"
    assert RECIPES[4].description == RECIPES[5].description == "pour_to(coffee, cup) -> pour_to(milk, the cup)"
    assert RECIPES[9].description == "pour(milk) -> pick_and_place(milk carton, shelf)"
    assert RECIPES[10].description == "pour(coffee) -> pick_and_place(coffee pot, cabinet)"


def test_the_recipe_builders_chain_their_programs():
    env06 = build_environment(ENVIRONMENTS_BY_ID["env06"])
    after = env06
    for action in demonstrate(env06, Task("pour", ("obj32",)))[0]:
        after = execute(after, action)
    cup = after.container_of("obj32")
    sweet = _sweet("env06", "obj32", "obj33", "coffee")
    assert (sweet.name, sweet.env_id) == ("serve-sweet-tea", "env06")
    assert sweet.description == "pour(coffee) -> pour_to(sugar, its cup) -> stir(coffee)"
    assert [p(env06, after) for p in sweet.programs] == [
        Task("pour", ("obj32",)), Task("pour_to", ("obj33", cup)), Task("stir", ("obj32",))]
    milk = _with_milk("env06", "obj32", "coffee")
    assert (milk.name, milk.env_id) == ("serve-coffee-with-milk", "env06")
    assert milk.description == "pour_to(coffee, cup) -> pour_to(milk, the cup)"
    vessel = choose_vessel(env06, "obj32")
    # the vessel is chosen in the initial world; the milk follows the coffee wherever it went
    assert [p(env06, after) for p in milk.programs] == [Task("pour_to", ("obj32", vessel)),
                                                        Task("pour_to", ("obj28", cup))]
    assert _pour("obj30")(env06, after) == Task("pour", ("obj30",))
    assert _fixed("pick_and_place", "obj21", "obj08")(env06, after) == Task("pick_and_place", ("obj21", "obj08"))
    assert _pour_into_first("obj33", "obj32")(after, env06) == Task("pour_to", ("obj33", env06.container_of("obj32")))
    assert _pour_to_vessel_of("obj28", "obj32")(env06, after) == Task("pour_to", ("obj28", vessel))
