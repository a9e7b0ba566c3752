"""The VEIL reader's domain, states and grounding, on the invented fixture (tests/fixtures/veil/release)."""

from __future__ import annotations

from pathlib import Path

import pytest

from taskseq.veil.grounding import VERBS, ActionError, ActionIndex, Step, UnknownObject
from taskseq.veil.pddl import And, Atom, ForAll, Not, When, parse_domain, read_domain
from taskseq.veil.release import read_release
from taskseq.veil.state import MAX_GRASPED, State, StepRefused, apply, initial_state, refusal
from taskseq.veil.xmltree import VeilFormatError

RELEASE = Path(__file__).parent / "fixtures" / "veil" / "release"
KITCHEN = "kitchen_scenario_environment_number_1"
LIVING = "living_room_scenario_environment_number9"


@pytest.fixture(scope="module")
def release():
    return read_release(RELEASE)


@pytest.fixture(scope="module")
def index(release):
    return ActionIndex(release.domain)


def run(release, index, env_id: str, lines: list[str], state: State | None = None) -> State:
    """Apply each line in turn; a refused line fails the test (it raises)."""
    env = release.environments[env_id]
    state = state or initial_state(env, release.catalog)
    for line in lines:
        g = index.ground(line, env.names)
        state = apply(state, g.action, g.args)
    return state


def refused(release, index, env_id: str, setup: list[str], line: str) -> StepRefused | None:
    state = run(release, index, env_id, setup)
    g = index.ground(line, release.environments[env_id].names)
    return refusal(state, g.action, g.args)


# the pddl reader ------------------------------------------------------------------------------------------------
def test_the_domain_is_parsed_with_its_undeclared_constants_overloads_and_missing_parts():
    d = read_domain(RELEASE / "domainKnowledge.pddl")
    assert d.name == "fixture"
    assert d.predicates["Grasping"] == 2
    assert [a.arity for a in d.named("pour")] == [1, 2]
    moveto = d.action("moveto", 1)
    assert moveto.precondition is None
    assert isinstance(moveto.effect, And) and isinstance(moveto.effect.parts[1], ForAll)
    knob = d.action("turn_TubKnob", 0)
    assert knob.parameters == () and knob.precondition == Atom("Near", ("Robot", "Tub"))
    grasp = d.action("grasp", 1)
    assert Not(Atom("Grasping", ("Robot", "?o"))) in grasp.precondition.parts
    assert isinstance(d.action("keep_On_HotPlate1", 1).effect.parts[2], When)


@pytest.mark.parametrize("text, line, expected", [
    ("(define (domain d)\n(:action a :parameters (?x)\n:effect (P ?x)\n", 3, "a ')' closing the '(' of line 2"),
    ("(define (domain d)\n(:action a :parameters (?x)\n:effect (P ?x)))\n)", 4, "no ')' without"),
    ("(define (domain d)\n(:action a :parameters (x)\n:effect (P x)))", 2, "a variable such as ?x"),
    ("(define (domain d)\n\n(:action a :parameters (?x)\n :cost 3 :effect (P ?x)))", 4, ":parameters, :precondition"),
    ("(define (domain d)\n(:action a :parameters (?x)\n:precondition (P ?x)))", 2, "an :effect"),
    ("(define (domain d)\n(:action a :effect (when (P))))", 2, "(when CONDITION EFFECT)"),
    ("(define (domain d)\n; comment (\n(:action a :effect (P (Q))))", 3, "not a nested formula"),
])
def test_a_malformed_domain_names_the_file_the_line_and_what_was_expected(text, line, expected):
    with pytest.raises(VeilFormatError) as err:
        parse_domain(text, "bad.pddl")
    assert err.value.path == "bad.pddl" and err.value.line == line
    assert expected in err.value.message
    assert str(err.value).startswith(f"bad.pddl:{line}:")


# the initial state ----------------------------------------------------------------------------------------------
def test_initial_facts_come_from_true_states_and_category_defaults_and_other_values_stay_attributes(release):
    s = initial_state(release.environments[KITCHEN], release.catalog)
    assert s.holds("state", "Beaker_2", "Tea")  # `1` is true
    assert not s.holds("state", "Teapot_1", "Tea")
    assert s.holds("state", "Honey_1", "Honey")  # the category's default
    assert s.holds("state", "Sorbet_1", "ServingsLeft")  # a count of 2: it holds while any is left
    assert not any(f[0] in ("Near", "On", "In", "Grasping") for f in s.facts)
    beaker = s.world.objects["Beaker_2"]
    assert beaker.category == "Beaker" and beaker.catalogued
    assert beaker.affordances == {"IsGraspable", "IsPourable"}
    assert dict(beaker.attributes) == {"Shade": "Blue"}
    assert beaker.position == (14.0, 40.0, -3.0)
    crate = s.world.objects["Crate_1"]  # no category Crate in Objects.xml
    assert (crate.category, crate.catalogued, crate.affordances) == ("Crate", False, frozenset())
    assert dict(crate.attributes) == {"Weight": "Heavy"}
    teapot = release.catalog.categories["teapot"]  # declared twice: merged
    assert dict(teapot.defaults)["Hot"] is None and "IsPourable" in teapot.affordances
    living = initial_state(release.environments[LIVING], release.catalog)
    assert not living.holds("state", "radio_1", "IsOn")  # `0` is false
    assert living.holds("state", "tape_1", "Tape")  # <state> directly under <object>
    assert living.world.objects["tape_1"].affordances == {"IsGraspable"}  # <affordances> beside <attributes>


# one refused step per action with a precondition -----------------------------------------------------------------
PRECONDITIONS = {
    ("grasp", 1): (KITCHEN, [], "grasp Teapot_1", "grasp(Teapot_1): the robot is not near Teapot_1"),
    ("release", 1): (KITCHEN, [], "release Teapot_1", "the robot is not grasping Teapot_1"),
    ("turn_TubKnob", 0): (KITCHEN, ["moveto Teapot_1"], "turn TubKnob", "the robot is not near Tub"),
    ("turn_HotPlateKnob_1", 0): (KITCHEN, [], "turn HotPlateKnob_1", "the robot is not near HotPlate"),
    ("press_Radio_1PowerButton", 0): (LIVING, ["moveto Tape_1"], "press Radio_1PowerButton",
                                      "the robot is not near radio_1"),
    ("open_IceboxLid", 0): (KITCHEN, ["moveto Icebox", "open IceboxLid"], "open IceboxLid",
                            "Icebox is already LidIsOpen"),
    ("close_IceboxLid", 0): (KITCHEN, ["moveto Icebox"], "close IceboxLid", "Icebox is not LidIsOpen"),
    ("keep_On_HotPlate1", 1): (KITCHEN, ["moveto Teapot_1", "grasp Teapot_1"], "keep Teapot_1 On HotPlate_1",
                               "the robot is not near HotPlate"),
    ("keep_In_Icebox", 1): (KITCHEN, ["moveto Beaker_1", "grasp Beaker_1", "moveto Icebox"],
                            "keep Beaker_1 Inside Icebox", "Icebox is not LidIsOpen"),
    ("keep", 3): (KITCHEN, ["moveto Teapot_1", "grasp Teapot_1"], "keep Teapot_1 On Tub",
                  "the robot is not near Tub"),
    ("pour", 1): (KITCHEN, ["moveto Beaker_2"], "pour Beaker_2", "the robot is not grasping Beaker_2"),
    ("pour", 2): (KITCHEN, ["moveto Beaker_2", "grasp Beaker_2"], "pour Beaker_2 Teapot_1",
                  "the robot is not grasping Teapot_1"),
    ("add_Cocoa_1", 1): (KITCHEN, ["moveto Beaker_1", "grasp Beaker_1"], "add Cocoa_1 Beaker_1",
                         "the robot is not grasping Cocoa_1"),
    ("squeeze", 2): (KITCHEN, ["moveto Beaker_1", "grasp Beaker_1", "moveto Teapot_1", "grasp Teapot_1"],
                     "squeeze Beaker_1 Teapot_1", "Beaker_1 is not IsSqueezeable"),
    ("scoop", 2): (KITCHEN, ["moveto Dipper_1", "grasp Dipper_1", "moveto Teapot_1", "grasp Teapot_1"],
                   "scoop Dipper_1 Teapot_1", "Teapot_1 is not ServingsLeft"),
    ("insert", 2): (LIVING, ["moveto Player_1", "grasp Player_1", "moveto Lantern_1", "grasp Lantern_1"],
                    "insert Lantern_1 Player_1", "lantern_1 is not Tape"),
}


def test_the_table_holds_every_action_of_the_fixture_with_a_precondition(release):
    with_pre = {(a.name, a.arity) for a in release.domain.actions if a.precondition is not None}
    assert set(PRECONDITIONS) == with_pre
    assert {(a.name, a.arity) for a in release.domain.actions} - with_pre == {("moveto", 1)}


@pytest.mark.parametrize("key", list(PRECONDITIONS), ids=lambda k: f"{k[0]}/{k[1]}")
def test_a_precondition_refuses_a_step_that_breaks_it(release, index, key):
    env_id, setup, line, words = PRECONDITIONS[key]
    why = refused(release, index, env_id, setup, line)
    assert why is not None and words in why.reason
    g = index.ground(line, release.environments[env_id].names)
    assert (g.action.name, g.action.arity) == key
    with pytest.raises(StepRefused):
        apply(run(release, index, env_id, setup), g.action, g.args)


def test_moveto_has_no_precondition_and_is_never_refused(release, index):
    s = run(release, index, KITCHEN, ["moveto Teapot_1", "moveto Teapot_1", "moveto Crate_1"])
    assert s.holds("Near", "Robot", "Crate_1") and not s.holds("Near", "Robot", "Teapot_1")


def test_the_robot_grasps_at_most_two_objects(release, index):
    assert MAX_GRASPED == 2
    two = ["moveto Beaker_1", "grasp Beaker_1", "moveto Beaker_2", "grasp Beaker_2"]
    why = refused(release, index, KITCHEN, two + ["moveto Teapot_1"], "grasp Teapot_1")
    assert why is not None and why.code == "hands full"
    assert "already grasps 2 objects (Beaker_1, Beaker_2)" in why.reason
    s = run(release, index, KITCHEN, two + ["release Beaker_1", "moveto Teapot_1", "grasp Teapot_1"])
    assert s.grasped() == ("Beaker_2", "Teapot_1")


# when and forall -------------------------------------------------------------------------------------------------
def test_a_forall_when_effect_fills_what_stands_in_the_tub_and_only_that(release, index):
    s = run(release, index, KITCHEN, ["moveto Teapot_1", "grasp Teapot_1", "moveto Tub", "keep Teapot_1 On Tub",
                                      "turn TubKnob"])
    assert s.holds("On", "Teapot_1", "Tub")
    assert s.holds("state", "TubKnob", "TubRuns") and s.holds("state", "Teapot_1", "Tea")
    assert not s.holds("state", "Beaker_1", "Tea")
    off = run(release, index, KITCHEN, ["turn TubKnob"], s)  # both whens read the state before the step
    assert not off.holds("state", "TubKnob", "TubRuns") and off.holds("state", "Teapot_1", "Tea")
    lifted = run(release, index, KITCHEN, ["moveto Teapot_1", "grasp Teapot_1"], off)
    assert not lifted.holds("On", "Teapot_1", "Tub")  # grasp's forall clears what it stood on


def test_an_object_specific_action_names_its_object_without_the_underscore_and_heats_it(release, index):
    s = run(release, index, KITCHEN, ["moveto HotPlate", "turn HotPlateKnob_1", "moveto Teapot_1",
                                      "grasp Teapot_1", "moveto HotPlate"])
    assert s.holds("state", "HotPlate", "Burner1") and not s.holds("state", "Teapot_1", "Hot")
    s = run(release, index, KITCHEN, ["keep Teapot_1 On HotPlate_1"], s)
    assert s.holds("On", "Teapot_1", "HotPlate_1")  # the domain's constant HotPlate1 is the object HotPlate_1
    assert s.holds("state", "Teapot_1", "Hot") and not s.holds("Grasping", "Robot", "Teapot_1")


def test_moveto_keeps_the_robot_near_what_it_holds_only(release, index):
    s = run(release, index, KITCHEN, ["moveto Beaker_1", "grasp Beaker_1", "moveto Teapot_1", "moveto Tub"])
    assert s.holds("Near", "Robot", "Tub") and s.holds("Near", "Robot", "Beaker_1")
    assert not s.holds("Near", "Robot", "Teapot_1")


def test_deletes_come_before_adds_and_conditions_read_the_state_before_the_step(release):
    d = parse_domain("(define (domain t) (:action flip :parameters (?o)\n"
                     ":effect (and (not (state ?o A)) (state ?o A)\n"
                     "             (when (state ?o B) (not (state ?o B))) (when (not (state ?o B)) (state ?o B)))))")
    s = initial_state(release.environments[KITCHEN], release.catalog)
    after = apply(s, d.action("flip", 1), ["Crate_1"])
    assert after.holds("state", "Crate_1", "A") and after.holds("state", "Crate_1", "B")
    assert not apply(after, d.action("flip", 1), ["Crate_1"]).holds("state", "Crate_1", "B")


def test_a_generic_keep_uses_the_domain_relation_word(release, index):
    s = run(release, index, KITCHEN, ["moveto Teapot_1", "grasp Teapot_1", "moveto Crate_1",
                                      "keep Teapot_1 Inside Crate_1"])
    assert s.holds("In", "Teapot_1", "Crate_1")


# grounding -------------------------------------------------------------------------------------------------------
def test_lines_ground_to_specific_or_generic_actions_and_to_learner_steps(release, index):
    names = release.environments[KITCHEN].names
    cases = {
        "moveto teapot_1": ("moveto", (("Teapot_1",)), Step("moveto", "Teapot_1")),
        "keep Teapot_1 On HotPlate_1": ("keep_On_HotPlate1", ("Teapot_1",), Step("keep_on", "Teapot_1", "HotPlate_1")),
        "keep Teapot_1 On Tub": ("keep", ("Teapot_1", "On", "Tub"), Step("keep_on", "Teapot_1", "Tub")),
        "keep Beaker_1 Inside Icebox": ("keep_In_Icebox", ("Beaker_1",), Step("keep_inside", "Beaker_1", "Icebox")),
        "turn HotPlateKnob_1": ("turn_HotPlateKnob_1", (), Step("turn", "HotPlateKnob_1")),
        "add Cocoa_1 Beaker_1": ("add_Cocoa_1", ("Beaker_1",), Step("add", "Cocoa_1", "Beaker_1")),
        "pour Beaker_2": ("pour", ("Beaker_2",), Step("pour", "Beaker_2")),
        "pour Beaker_2 Teapot_1": ("pour", ("Beaker_2", "Teapot_1"), Step("pour", "Beaker_2", "Teapot_1")),
        "wait": ("wait", (), Step("wait")),
        "wait 10": ("wait", (), Step("wait")),
    }
    for line, (action, args, step) in cases.items():
        g = index.ground(line, names)
        assert (g.action.name, g.args, g.step) == (action, args, step), line
        assert g.step.verb in VERBS


@pytest.mark.parametrize("line, words", [
    ("fly Teapot_1", "unknown action 'fly'"), ("grasp", "grasp takes one argument, not 0"),
    ("keep Teapot_1 Under Tub", "unknown relation 'Under'"), ("wait long", "whole number"),
    ("open Teapot_1", "no action of the domain executes 'open Teapot_1'"),
])
def test_a_line_of_no_domain_action_is_an_action_error(release, index, line, words):
    with pytest.raises(ActionError, match=words):
        index.ground(line, release.environments[KITCHEN].names)


def test_an_object_absent_from_the_environment_is_an_unknown_object(release, index):
    with pytest.raises(UnknownObject) as err:
        index.ground("grasp Radio_1", release.environments[KITCHEN].names)
    assert err.value.name == "Radio_1"
    assert index.ground("grasp Radio_1", release.environments[LIVING].names).step == Step("grasp", "radio_1")
