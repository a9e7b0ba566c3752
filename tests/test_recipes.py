"""Recipes: well formed, demonstrable, run on models that never saw their environments."""

import numpy as np

from taskseq.experiments.recipes import RECIPES, evaluate_recipes
from taskseq.learn.estimator import StepScorer
from taskseq.learn.mrf import StepMRF
from taskseq.sim.catalog import ENVIRONMENTS_BY_ID, build_environment
from taskseq.sim.demonstrator import demonstrate
from taskseq.sim.primitives import execute
from taskseq.sim.tasks import goal_reached


def test_four_recipes_in_three_environments_each():
    kinds = {}
    for r in RECIPES:
        kinds.setdefault(r.name, set()).add(r.env_id)
    assert sorted(kinds) == ["empty-and-throw-away", "serve-and-store", "serve-coffee-with-milk", "serve-sweet-tea"]
    assert all(len(envs) == 3 for envs in kinds.values()) and len(RECIPES) == 12


def test_every_recipe_can_be_demonstrated_program_after_program():
    for r in RECIPES:
        initial = state = build_environment(ENVIRONMENTS_BY_ID[r.env_id])
        for next_task in r.programs:
            task = next_task(initial, state)
            before = state
            for action in demonstrate(state, task)[0]:
                state = execute(state, action)
            assert goal_reached(task, before, state), (r.name, r.env_id, task)


class Fake:
    """Records what it was trained on; plans with zero weights."""

    seen: list = []
    policy = "greedy"

    def fit(self, contexts, meta, scenarios=None):
        Fake.seen.append({m.scenario_id.split("/")[0] for m in meta})
        self.planner_ = StepScorer.from_weights("full", np.zeros(StepMRF("full").size_joint_feature))
        return self


def test_recipes_run_on_models_trained_without_their_environments(benchmark_steps):
    contexts, meta = benchmark_steps
    Fake.seen = []
    outcomes = evaluate_recipes(Fake, contexts, meta, {}, max_steps=3)
    assert len(outcomes) == 24 and {o.feedback for o in outcomes} == {False, True}
    for seen, name in zip(Fake.seen, dict.fromkeys(r.name for r in RECIPES), strict=True):
        held_out = {r.env_id for r in RECIPES if r.name == name}
        assert seen and not seen & held_out
