"""How params.yaml and selection.json are read, on hand-written files: each value type, every refusal's exact message.

The messages are compared whole, since a message that names the wrong key (or none) is the bug these tests are
for. The `settings` mutation group (scripts/mutation.py) is judged by these tests and tests/test_settings.py.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, replace
from pathlib import Path

import pytest

from taskseq.methods import Lineup, MethodSpec, specs
from taskseq.methods import spec as spec_module
from taskseq.selection import UNTUNED_C, Selection, read_selection
from taskseq.settings import (
    Crossval,
    Feedback,
    Generate,
    Learner,
    MethodEntry,
    Methods,
    Params,
    Procedural,
    Select,
    Stats,
    Train,
    World,
    parse_section,
)

KNOWN_SECTIONS = "world, procedural, select, train, pddl, crossval, noise, feedback, recipes, methods, people, " \
                 "teach, stats"


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "params.yaml"
    path.write_text(text)
    return path


def refused(call, *args, **kwargs) -> str:
    with pytest.raises(ValueError) as err:
        call(*args, **kwargs)
    return str(err.value)


# ---- values of each type, from a file and from --set --------------------------------------------------------------

def test_each_value_type_is_read_from_a_hand_written_file(tmp_path):
    path = write(tmp_path, "world:\n  family: procedural\n  seeds: 1 -2 3\n  dev_seed: '7'\n"
                           "train:\n  tol: 1e-4\n  max_iter: 5\n  method: 3\n"
                           "people:\n  train: 'TRUE'\n  logs: logs\n"
                           "noise:\n  rates: [0, 0.5]\n  draws: -3\n"
                           "feedback:\n  k: 4\n  n: 0 all\n"
                           "select:\n  C: [1, 2]\n")
    params = Params.load(path)
    assert params.world == World("procedural", (1, -2, 3), 7)
    assert params.train == Train(tol=1e-4, max_iter=5, n_slacks=0, method="3")
    assert type(params.train.tol) is float and type(params.train.max_iter) is int
    assert params.people.train is True and params.people.logs == "logs"
    assert params.noise.rates == (0.0, 0.5) and all(type(r) is float for r in params.noise.rates)
    assert params.noise.draws == -3
    assert params.feedback == Feedback((4,), ("0", "all"))
    assert params.select.C == (1.0, 2.0) and all(type(c) is float for c in params.select.C)
    assert params.crossval == Crossval()  # sections the file does not name keep their defaults


@pytest.mark.parametrize(("text", "value"), [("true", True), ("false", False), ("'True'", True), ("'FALSE'", False),
                                             ("'false'", False)])
def test_a_switch_takes_true_or_false_in_any_case(tmp_path, text, value):
    assert Params.load(write(tmp_path, f"people:\n  train: {text}\n")).people.train is value


def test_an_empty_file_or_empty_sections_give_the_defaults(tmp_path):
    assert Params.load(write(tmp_path, "")) == Params()
    assert Params.load(write(tmp_path, "train:\nmethods:\n")) == Params()


def test_no_path_reads_no_file_even_where_one_exists(tmp_path, monkeypatch):
    write(tmp_path, "train:\n  tol: 0.5\n")
    monkeypatch.chdir(tmp_path)
    assert Params.load(None) == Params()
    assert Params.load() == Params.load(tmp_path / "params.yaml")
    assert Params.load().train.tol == 0.5


def test_set_overrides_the_file_key_by_key(tmp_path):
    path = write(tmp_path, "train:\n  tol: 0.5\n  max_iter: 7\nmethods:\n  full: {experiments: select}\n"
                           "  dagger:\n  chance: 3\n")
    params = Params.load(path, [" train.tol = 0.25", "world.seeds=4", "methods.dagger.experiments=noise",
                                "methods.dagger.dagger_rounds=2", "methods.chance.experiments=select",
                                "methods.full.dagger_rounds=1"])
    assert params.train.tol == 0.25 and params.train.max_iter == 7 and params.world.seeds == (4,)
    assert params.methods.entry("dagger") == MethodEntry(("noise",), (("dagger_rounds", 2),))
    # an entry that was no mapping gives way to the key set
    assert params.methods.entry("chance") == MethodEntry(("select",))
    assert params.methods.entry("full") == MethodEntry(("select",), (("dagger_rounds", 1),))
    assert [name for name, _ in params.methods.entries] == ["full", "dagger", "chance"]


def test_a_whole_method_entry_can_be_set_as_yaml(tmp_path):
    params = Params.load(None, ["methods.full={experiments: noise}"])
    assert params.methods.entries == (("full", MethodEntry(("noise",))),)


def test_an_override_splits_at_the_first_equals_sign_and_a_methods_key_at_the_name(tmp_path):
    assert Params.load(None, ["train.method=a=b"]).train.method == "a=b"
    assert Params.load(None, ["methods.full.a.b=1"]).methods.entry("full") == MethodEntry((), (("a.b", 1),))


def test_an_override_changes_one_section_even_where_the_file_shares_its_keys_with_another(tmp_path):
    path = write(tmp_path, "noise: &seeded {seed: 4}\nstats: *seeded\n")  # a YAML alias: one mapping, two sections
    params = Params.load(path, ["noise.seed=5"])
    assert (params.noise.seed, params.stats.seed) == (5, 4)


def test_params_flat_names_every_key_with_its_section(tmp_path):
    path = write(tmp_path, "methods:\n  full: {experiments: select noise}\n"
                           "  noise_trained: {experiments: [select], noise_rate: 0.2}\n  chance:\n")
    flat = Params.load(path).flat()
    assert flat["train.tol"] == 1e-3 and flat["world.seeds"] == (0, 3, 7) and flat["stats.confidence"] == 0.95
    assert flat["procedural.environments"] == 13 and flat["crossval.chance_seed"] == 0
    assert {k: v for k, v in flat.items() if k.startswith("methods.")} == {
        "methods.full.experiments": "select noise", "methods.noise_trained.experiments": "select",
        "methods.noise_trained.noise_rate": 0.2, "methods.chance.experiments": ""}
    assert len(flat) == 46 + 4


# ---- refusals, each naming the file and the key ---------------------------------------------------------------

@pytest.mark.parametrize(("text", "message"), [
    ("train: [1, 2\n", None),
    ("- train\n", "expected sections such as 'train:', got list"),
    ("'text'\n", "expected sections such as 'train:', got str"),
    ("moon: {a: 1}\n", f"unknown sections ['moon']; known: {KNOWN_SECTIONS}"),
    ("train: 3\n", "section 'train' must hold keys, got 3"),
    ("train:\n  tl: 1\n  feature: x\n", "unknown setting train.feature, train.tl; train has tol, max_iter, n_slacks, "
                                       "method"),
    ("train:\n  tol: small\n", "train.tol must be a number, got 'small'"),
    ("train:\n  tol: null\n", "train.tol must be a number, got None"),
    ("train:\n  tol: [1]\n", "train.tol must be float, got [1]"),
    ("train:\n  max_iter: 2.0\n", "train.max_iter must be a whole number, got 2.0"),
    ("train:\n  max_iter: true\n", "train.max_iter must be int, got True"),
    ("train:\n  method: {a: 1}\n", "train.method must be str, got {'a': 1}"),
    ("world:\n  seeds: 1 1.5\n", "world.seeds must be a whole number, got '1.5'"),
    ("world:\n  seeds: 1 -2-\n", "world.seeds must be a whole number, got '-2-'"),
    ("world:\n  seeds: 1 --2\n", "world.seeds must be a whole number, got '--2'"),
    ("world:\n  seeds: []\n", "world.seeds must list at least one value"),
    ("world:\n  seeds: ''\n", "world.seeds must list at least one value"),
    ("world:\n  family: moon\n", "world.family must be one of paper, procedural, got 'moon'"),
    ("crossval:\n  group_by: world\n", "crossval.group_by must be one of scenario, environment, got 'world'"),
    ("people:\n  train: 1\n", "people.train must be true or false, got 1"),
    ("people:\n  train: yes please\n", "people.train must be true or false, got 'yes please'"),
    ("stats:\n  resamples: 0\n", "stats.resamples must be at least 1, got 0"),
    ("methods: 3\n", "section 'methods' must hold keys, got 3"),
    ("methods:\n  full: 3\n", "methods.full must hold keys (experiments and its own settings), got 3"),
    ("methods:\n  full: {experiments: 3}\n", "methods.full.experiments must list experiments, got 3"),
    ("methods:\n  full: {experiments: select nois}\n",
     "methods.full.experiments: unknown ['nois']; known: select, noise, feedback, recipes, transfer"),
])
def test_a_bad_file_is_refused_with_the_file_and_key_named(tmp_path, text, message):
    path = write(tmp_path, text)
    got = refused(Params.load, path)
    if message is None:
        assert got.startswith(f"{path}: not valid YAML (") and got.endswith(")")
    else:
        assert got == f"{path}: {message}"


@pytest.mark.parametrize(("override", "message"), [
    ("train=1", "--set 'train=1': expected section.key=value, e.g. train.tol=1e-4"),
    ("train.tol", "--set 'train.tol': expected section.key=value, e.g. train.tol=1e-4"),
    ("train.=1", "--set 'train.=1': expected section.key=value, e.g. train.tol=1e-4"),
    ("train.tol=", "params.yaml with --set train.tol=: train.tol must be a number, got ''"),
    ("train.tol= ", "params.yaml with --set train.tol= : train.tol must be a number, got ''"),
    ("noise.rates=", "params.yaml with --set noise.rates=: noise.rates must list at least one value"),
    (".tol=1", "params.yaml with --set .tol=1: unknown sections ['']; known: " + KNOWN_SECTIONS),
    ("select.C=1", "params.yaml with --set select.C=1: select.C must list at least two positive values (the grid's "
                   "spacing is how it is extended), got 1"),
    ("methods.full.experiments=nois", "params.yaml with --set methods.full.experiments=nois: "
                                      "methods.full.experiments: unknown ['nois']; known: select, noise, feedback, "
                                      "recipes, transfer"),
])
def test_a_bad_override_is_refused_with_what_was_set(override, message):
    assert refused(Params.load, None, [override]) == message


def test_an_override_into_a_section_that_holds_no_keys_is_refused(tmp_path):
    path = write(tmp_path, "train: 3\n")
    assert refused(Params.load, path, ["train.tol=1"]) == f"{path}: section 'train' must hold keys, got 3"
    path = write(tmp_path, "train:\n")
    assert refused(Params.load, path, ["train.tol=1"]) == f"{path}: section 'train' must hold keys, got None"
    assert refused(Params.load, path, ["a.b=1", "c.d=2"]) == (f"{path} with --set a.b=1 c.d=2: unknown sections "
                                                              f"['a', 'c']; known: {KNOWN_SECTIONS}")


# ---- each section's own checks, at their edges --------------------------------------------------------------------

def test_procedural_counts_and_shares_are_checked_at_their_edges():
    assert Procedural(environments=1, size_spread=0.0, new_objects=0.999, stacks=0.0, tables=(1, 1),
                      shelves=(0, 0), bins=(1, 5)).environments == 1
    assert refused(Procedural, environments=0) == "procedural.environments must be at least 1, got 0"
    for name in ("size_spread", "new_objects", "stacks"):
        assert refused(Procedural, **{name: 1.0}) == f"procedural.{name} must lie in [0, 1), got 1.0"
        assert refused(Procedural, **{name: -0.1}) == f"procedural.{name} must lie in [0, 1), got -0.1"
    for name in ("tables", "shelves", "bins", "pourers", "vessels", "filled_vessels", "stirrers", "items"):
        assert refused(Procedural, **{name: (2, 1)}) == f"procedural.{name} must be two counts, low then high, got 2 1"
        assert refused(Procedural, **{name: (-1, 2)}) == (f"procedural.{name} must be two counts, low then high, "
                                                          "got -1 2")
        assert refused(Procedural, **{name: (1, 2, 3)}) == (f"procedural.{name} must be two counts, low then high, "
                                                            "got 1 2 3")
        assert refused(Procedural, **{name: (1,)}) == f"procedural.{name} must be two counts, low then high, got 1"
        Procedural(**{name: (3, 3)})
    message = "procedural.tables and procedural.bins must start at 1: every task needs a table and throwing away " \
              "needs a bin"
    assert refused(Procedural, tables=(0, 1)) == message and refused(Procedural, bins=(0, 2)) == message
    assert Generate().procedural == Procedural()


def test_procedural_values_are_read_from_a_file(tmp_path):
    path = write(tmp_path, "procedural:\n  environments: 2\n  tables: 2 3\n  stacks: 0\n")
    assert Params.load(path).procedural == Procedural(environments=2, tables=(2, 3), stacks=0.0)
    path = write(tmp_path, "procedural:\n  tables: 0 3\n")
    assert refused(Params.load, path) == (f"{path}: procedural.tables and procedural.bins must start at 1: every task "
                                          "needs a table and throwing away needs a bin")


def test_select_grid_and_sizes_are_checked_at_their_edges():
    assert Select(C=(0.01, 1.0), max_extensions=0, environments=1).C == (0.01, 1.0)
    assert refused(Select, environments=0) == "select.environments must be at least 1, got 0"
    grid = "select.C must list at least two positive values (the grid's spacing is how it is extended), got "
    assert refused(Select, C=(3.0,)) == grid + "3"
    assert refused(Select, C=(0.0, 1.5)) == grid + "0 1.5"
    assert refused(Select, C=(2.0, -1.0)) == grid + "2 -1"
    assert refused(Select, max_extensions=-1) == "select.max_extensions must be at least 0, got -1"


def test_feedback_steps_are_whole_numbers_or_all():
    assert Feedback(n=("0", "12", "all")).n == ("0", "12", "all")
    assert refused(Feedback, n=("1", "-2", "x")) == "feedback.n must list whole numbers of steps or 'all', got '-2'"
    assert refused(Feedback, n=("All",)) == "feedback.n must list whole numbers of steps or 'all', got 'All'"


def test_stats_resamples_and_confidence_are_checked_at_their_edges():
    assert Stats(resamples=1, confidence=0.5).resamples == 1
    assert refused(Stats, resamples=0) == "stats.resamples must be at least 1, got 0"
    assert refused(Stats, confidence=0.0) == "stats.confidence must lie strictly between 0 and 1, got 0.0"
    assert refused(Stats, confidence=1.0) == "stats.confidence must lie strictly between 0 and 1, got 1.0"


@dataclass(frozen=True)
class Rates:
    """A method's own settings with a list of one value by default."""

    rates: tuple[float, ...] = (0.1,)


def test_parse_section_names_a_section_by_its_params_name_or_its_class():
    assert parse_section(Train, {"tol": "0.5"}) == Train(tol=0.5)
    assert refused(parse_section, Train, {"x": 1}) == ("params.yaml: unknown setting train.x; train has tol, "
                                                       "max_iter, n_slacks, method")
    assert refused(parse_section, Learner, {"tol": "x"}, None, "f.yaml") == "f.yaml: learner.tol must be a number, " \
                                                                            "got 'x'"
    assert parse_section(World, {"family": "x"}, "w") == World("x")  # the choices are those of world.family
    assert parse_section(Rates, {"rates": "0.2 1"}, "methods.x") == Rates((0.2, 1.0))
    assert parse_section(Rates, {"rates": 3}, "methods.x").rates == (3.0,)
    assert refused(parse_section, Stats, {"confidence": 2}, "stats", "g.yaml") == (
        "g.yaml: stats.confidence must lie strictly between 0 and 1, got 2.0")


# ---- the methods section --------------------------------------------------------------------------------------

def test_the_methods_section_is_parsed_entry_by_entry():
    methods = Methods.parse({"full": {"experiments": "noise select noise"}, 7: None,
                             "dagger": {"experiments": ["select"], "dagger_rounds": 2, "x": None}},
                            "f.yaml")
    assert methods.entries == (("full", MethodEntry(("noise", "select"))), ("7", MethodEntry()),
                               ("dagger", MethodEntry(("select",), (("dagger_rounds", 2), ("x", None)))))
    assert methods.entry("7") == MethodEntry() and methods.entry("chance") is None
    assert Methods.parse({}) == Methods()
    assert refused(Methods.parse, {"full": [1]}) == ("params.yaml: methods.full must hold keys (experiments and its "
                                                     "own settings), got [1]")
    assert refused(Methods.parse, {"full": {"experiments": None}}, "f") == ("f: methods.full.experiments must list "
                                                                            "experiments, got None")
    assert refused(Methods.parse, {"full": {"experiments": ["table1", "x"]}}) == (
        "params.yaml: methods.full.experiments: unknown ['table1', 'x']; known: select, noise, feedback, recipes, "
        "transfer")


# ---- selection.json ------------------------------------------------------------------------------------------

def write_json(tmp_path: Path, data) -> Path:
    path = tmp_path / "selection.json"
    path.write_text(data if isinstance(data, str) else json.dumps(data))
    return path


def test_selection_json_gives_each_methods_c_as_a_float_and_the_first_method(tmp_path):
    path = write_json(tmp_path, {"method": "full", "C": 9,
                                 "settings": {"full": {"C": 2, "x": 1}, "dagger": {"C": 0.5}}})
    selection = read_selection(path)
    assert selection == Selection({"full": 2.0, "dagger": 0.5}, "full", str(path))
    assert type(selection.C["full"]) is float and selection.of("dagger") == 0.5
    assert read_selection(str(path)) == selection
    assert read_selection(write_json(tmp_path, {"method": "", "settings": {}})) == Selection({}, None, str(path))
    assert read_selection(write_json(tmp_path, {"method": 3, "settings": {}})).method is None
    assert read_selection(write_json(tmp_path, {"settings": {}})).method is None
    assert read_selection(None) == Selection() and Selection().source is None


@pytest.mark.parametrize(("data", "message"), [
    ({"settings": {"full": {"C": 0}}}, "field 'settings.full.C' must be a positive number, got 0"),
    ({"settings": {"full": {"C": -1.5}}}, "field 'settings.full.C' must be a positive number, got -1.5"),
    ({"settings": {"full": {"C": True}}}, "field 'settings.full.C' must be a positive number, got True"),
    ({"settings": {"full": {"C": "3"}}}, "field 'settings.full.C' must be a positive number, got '3'"),
    ({"settings": {"full": {}}}, "field 'settings.full.C' must be a positive number, got None"),
    ({"settings": {"full": 3}}, "field 'settings.full.C' must be a positive number, got None"),
    ({"settings": [1]}, "field 'settings' must map each method to its choice, got [1]; run `taskseq select` again"),
    ({"C": 3}, "field 'settings' must map each method to its choice, got None; run `taskseq select` again"),
    ([1], "field 'settings' must map each method to its choice, got None; run `taskseq select` again"),
])
def test_a_bad_selection_file_names_the_file_and_field(tmp_path, data, message):
    path = write_json(tmp_path, data)
    assert refused(read_selection, path) == f"{path}: {message}"


def test_a_selection_file_that_is_no_json_or_absent_is_named(tmp_path):
    path = write_json(tmp_path, "{not json")
    got = refused(read_selection, path)
    assert got.startswith(f"{path}: not valid JSON: Expecting property name")
    with pytest.raises(FileNotFoundError) as err:
        read_selection(tmp_path / "none.json")
    assert str(err.value) == (f"{tmp_path / 'none.json'}: no selection file; run `dvc repro select` (each "
                              "method's `taskseq choose_C`, then `taskseq select`)")


def test_a_selection_gives_a_c_only_for_the_methods_it_holds():
    assert Selection().of("anything") == UNTUNED_C == 3.0
    selection = Selection({"full": 2.0}, source="s.json")
    assert selection.of("full") == 2.0
    assert refused(selection.of, "dagger") == ("s.json: no C for method dagger: add select to "
                                               "methods.dagger.experiments in params.yaml and run `dvc repro "
                                               "select` again (which first chooses its C: `taskseq choose_C "
                                               "--method dagger`)")
    uniform = Selection.uniform(0.25, ("full", "dagger"))
    assert uniform == Selection({"full": 0.25, "dagger": 0.25}, None, "C=0.25")
    assert Selection.uniform(1e-5, ()).source == "C=1e-05"


# ---- the methods as a run configures them (taskseq.methods.lineup) ------------------------------------------------

def lineup(text: str = "", selection: Selection | None = None, **kwargs) -> Lineup:
    methods = Methods.parse(json.loads(text or "{}"))
    return Lineup(methods, selection or Selection(), **kwargs)


def test_a_lineup_refuses_an_unknown_method_or_setting():
    known = ", ".join(specs())
    assert refused(lineup, '{"full": null, "fool": null, "bar": null}') == (
        f"params.yaml: methods.fool is no method of Table I; known: {known}")
    # a method's settings are checked when it is asked for, as every stage does for its methods before any work
    assert refused(lambda text: lineup(text).factories(), '{"dagger": {"dagger_rounds": "two"}}') == (
        "params.yaml: methods.dagger.dagger_rounds must be a whole number, got 'two'")
    assert refused(lambda text: lineup(text).factory("chance"), '{"chance": {"dagger_rounds": 1}}') == (
        "params.yaml: unknown setting methods.chance.dagger_rounds; methods.chance has ")
    assert refused(lineup().factories, ["full", "fool"]) == f"unknown methods ['fool']; known: {known}"


def test_a_lineup_gives_each_method_its_settings_c_and_learner():
    up = lineup('{"dagger": {"experiments": ["noise"], "dagger_rounds": 3}, "full": {"experiments": ["noise"]}}',
                Selection({"full": 2.0, "dagger": 5.0, "relations": 7.0}, source="s"),
                learner=Learner(0.5, 9, 1), crossval=Crossval(chance_seed=4), horizon=6, store="models")
    assert up.settings_of("dagger").dagger_rounds == 3 and up.settings_of("feasible").dagger_rounds == 1
    assert up.names() == list(specs()) and up.names("noise") == ["dagger", "full"] and up.names("select") == []
    full = up.factory("full")()
    assert (full.C, full.tol, full.max_iter, full.n_slacks, full.store, full.name) == (2.0, 0.5, 9, 1, "models", "full")
    assert up.factory("only_edge")().C == 2.0  # the ablations take the full model's C
    assert up.factory("dagger")().dagger_rounds == 3 and up.factory("dagger")().C == 5.0
    assert up.factory("chance")().seed == 4 and up.factory("symb_plan_svm")().horizon == 6
    assert up.factory("full")() is not up.factory("full")()
    assert list(up.factories(["dagger", "full"])) == ["dagger", "full"]
    assert list(up.at_C(1.0).factories()) == list(specs())
    assert list(up.running("noise")) == ["dagger", "full"]
    assert up.at_C(0.5).factory("dagger")().C == 0.5 and up.at_C(0.5).factory("full")().store == "models"
    every = up.at_C(1.0).mrf()
    assert "full" in every and "chance" not in every and "symb_plan_svm" not in every
    assert all(make().C == 1.0 for make in every.values())
    assert refused(up.mrf, ["full", "chance", "multiclass"]) == ("chance, multiclass: not MRF methods (only those "
                                                                 "have fold models)")


def test_only_methods_tuned_by_a_c_count_as_mrf_methods(monkeypatch):
    # a method that fits no C of its own (C_from None) is no MRF method of the fold models, even when it is one
    fixed = MethodSpec("fixed", "fixed model", lambda b: replace(b, C=1.0).mrf("full"), C_from=None)
    monkeypatch.setattr(spec_module, "_SPECS", {**spec_module._SPECS, "fixed": fixed})
    up = lineup().at_C(2.0)
    assert up.factory("fixed")().C == 1.0
    assert "fixed" not in up.mrf() and "full" in up.mrf()
    assert list(up.mrf(["fixed"])) == ["fixed"]


# ---- a method's spec (taskseq.methods.spec) -------------------------------------------------------------------------

@dataclass(frozen=True)
class Needs:
    """Settings with a field that has no default."""

    rounds: int


@dataclass(frozen=True)
class Listed:
    """Settings whose one field has a default factory."""

    rates: tuple[float, ...] = dataclasses.field(default_factory=lambda: (0.1,))


def make_nothing(build):
    return None


def test_a_spec_is_checked_when_it_is_made():
    assert refused(MethodSpec, "two words", "x", make_nothing) == ("method name 'two words' must be a Python "
                                                                   "identifier (it names files and runs)")
    assert refused(MethodSpec, "mine", "x", make_nothing, policy="random") == (
        "method mine: unknown policy 'random'; known: greedy, feasible, lookahead")
    message = "method mine: its settings must be a dataclass with a default for each field"
    assert refused(MethodSpec, "mine", "x", make_nothing, settings=dict) == message
    assert refused(MethodSpec, "mine", "x", make_nothing, settings=Needs) == message
    assert MethodSpec("mine", "x", make_nothing, policy="lookahead", settings=Listed).settings is Listed
    assert MethodSpec("mine", "x", make_nothing, settings=Rates).policy == "greedy"


def test_a_spec_says_whose_c_it_takes():
    assert MethodSpec("mine", "x", make_nothing).tuned_as == "mine"
    assert MethodSpec("mine", "x", make_nothing, C_from="full").tuned_as == "full"
    assert MethodSpec("mine", "x", make_nothing, C_from=None).tuned_as is None
    assert specs()["only_edge"].tuned_as == "full" and specs()["chance"].tuned_as is None


def test_a_name_is_registered_once_and_the_lists_keep_the_order_registered(monkeypatch):
    monkeypatch.setattr(spec_module, "_SPECS", {})
    first = spec_module.register(MethodSpec("b", "the b", make_nothing))
    assert spec_module.register(MethodSpec("b", "the b", make_nothing)) == first  # the same spec again: no change
    spec_module.register(MethodSpec("a", "the a", make_nothing))
    assert refused(spec_module.register, MethodSpec("b", "another b", make_nothing)) == "method 'b' is registered twice"
    assert [n for n in spec_module.method_names() if n in "ab"] == ["b", "a"]  # methods of no module of the package
    assert spec_module.method_spec("b") == first
    assert spec_module.method_labels(["b", "a"]) == {"b": "the b", "a": "the a"}


def test_a_build_makes_the_mrf_method_with_everything_in_force():
    build = spec_module.Build("mine", "lookahead", 2.5, Learner(0.5, 9, 1), Crossval(), 6, "models", None)
    method = build.mrf("relations", dagger_rounds=2)
    assert (method.features, method.C, method.tol, method.max_iter, method.n_slacks, method.name, method.store,
            method.policy, method.dagger_rounds) == ("relations", 2.5, 0.5, 9, 1, "mine", "models", "lookahead", 2)
    assert refused(replace(build, C=None).mrf, "full") == ("method mine: an MRF method needs a C (its spec's C_from "
                                                           "is None)")
