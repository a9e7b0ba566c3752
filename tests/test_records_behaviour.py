"""A program's success as documented (`plan/records.py`): stopped by choice, goal reached and no safety rule broken,
on hand-made programs: the demonstrator's pour in env01 of world 0, its states arranged by hand."""

from __future__ import annotations

import pytest

from taskseq.plan import planner
from taskseq.plan.records import DONE, INFEASIBLE, STEP_CAP, PlanStep, Program, reached, succeeded, unbroken
from taskseq.serve.environments import world_environment
from taskseq.sim.demonstrator import demonstrate
from taskseq.sim.primitives import Action, execute
from taskseq.sim.tasks import Task

POUR = Task("pour", ("obj27",))  # env01: the water in its bottle, on the kitchen table


@pytest.fixture(scope="module")
def pour():
    """The demonstrator's steps of the pour and the world before each, then the world they leave."""
    state = world_environment(0, "env01").state
    actions = demonstrate(state, POUR)[0]
    states = [state]
    for action in actions:
        states.append(execute(states[-1], action))
    return actions, states


def steps(actions, unsafe=()):
    """Plan steps of the actions; those at the indices of `unsafe` break a (named) safety rule."""
    return [PlanStep(a, 1.0, [], ["rule"] if k in unsafe else []) for k, a in enumerate(actions)]


def test_the_statuses_are_the_documented_words():
    assert (DONE, STEP_CAP, INFEASIBLE) == ("done", "step_cap", "infeasible")
    assert (planner.DONE, planner.STEP_CAP, planner.INFEASIBLE) == (DONE, STEP_CAP, INFEASIBLE)
    assert planner.Program is Program and planner.PlanStep is PlanStep  # the planner's names are these


def test_a_program_that_stops_by_choice_with_the_goal_reached_and_every_step_safe_succeeds(pour):
    actions, states = pour
    program = Program(POUR, steps(actions) + [PlanStep(Action("done"), 1.0, [])], DONE, states + [states[-1]])
    assert program.goal_reached and program.safe and program.success
    assert reached(program) and unbroken(program) and succeeded(program)


@pytest.mark.parametrize("status", [STEP_CAP, INFEASIBLE, "", "Done"])
def test_a_program_stopped_any_other_way_fails_even_with_the_goal_reached(pour, status):
    actions, states = pour
    program = Program(POUR, steps(actions), status, states)
    assert program.goal_reached and program.safe
    assert not program.success and not succeeded(program)


@pytest.mark.parametrize("unsafe", [{0}, {3}, {0, 1, 2, 3}])
def test_a_program_with_any_unsafe_step_fails(pour, unsafe):
    actions, states = pour
    program = Program(POUR, steps(actions, unsafe), DONE, states)
    assert program.goal_reached
    assert not program.safe and not unbroken(program)
    assert not program.success and not succeeded(program)


def test_a_program_with_no_steps_is_safe_and_fails_only_by_its_goal(pour):
    _, states = pour
    program = Program(POUR, [], DONE, [states[0]])
    assert program.safe and not program.goal_reached and not program.success


def test_a_program_that_stops_by_choice_short_of_its_goal_fails(pour):
    actions, states = pour
    program = Program(POUR, steps(actions[:-1]), DONE, states[:-1])
    assert program.safe and not program.goal_reached and not program.success


def test_the_goal_is_judged_in_the_last_world_against_the_first(pour):
    """pour's goal is relative (the liquid left the container it started in): which states are compared matters."""
    actions, states = pour
    before, after = states[0], states[-1]
    assert Program(POUR, [], DONE, [before, before, after]).goal_reached  # the last world, not the one before
    assert not Program(POUR, [], DONE, [before, after, before]).goal_reached
    assert not Program(POUR, [], DONE, [after, before, after]).goal_reached  # against the first, not the second
    assert Program(POUR, [], DONE, [before, after, after, after]).success
    assert not Program(POUR, [], DONE, [after, after, before, after]).success
