"""params.yaml as a stage reads it: overrides, and every kind of bad value refused with its key named."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from taskseq.settings import MethodEntry, Methods, Params, Replay

ROOT = Path(__file__).resolve().parents[1]


def test_the_repository_file_equals_the_defaults_and_a_missing_file_gives_them(tmp_path):
    # but for its `methods` section, which is written there and nowhere else
    assert replace(Params.load(ROOT / "params.yaml"), methods=Methods()) == Params()
    assert Params.load(tmp_path / "absent.yaml") == Params()


def test_the_methods_section_keeps_its_order_and_each_entry(tmp_path):
    path = tmp_path / "params.yaml"
    path.write_text("methods:\n  relations: {experiments: noise select}\n  full: {experiments: [select]}\n"
                    "  noise_trained: {experiments: select, noise_rate: 0.2}\n  chance:\n")
    methods = Params.load(path).methods
    assert [name for name, _ in methods.entries] == ["relations", "full", "noise_trained", "chance"]
    assert methods.entry("relations") == MethodEntry(("noise", "select"))
    assert methods.entry("noise_trained") == MethodEntry(("select",), (("noise_rate", 0.2),))
    assert methods.entry("chance") == MethodEntry() and methods.entry("dagger") is None
    over = Params.load(path, ["methods.full.experiments=noise", "methods.dagger.dagger_rounds=2"]).methods
    assert over.entry("full") == MethodEntry(("noise",))
    assert over.entry("dagger") == MethodEntry((), (("dagger_rounds", 2),))
    assert Params.load(path).methods.entry("full") == MethodEntry(("select",))  # the file's entry is not changed


def test_overrides_set_one_key_each_with_its_type(tmp_path):
    params = Params.load(tmp_path / "absent.yaml", ["crossval.folds=2", "noise.rates=0 0.2", "train.tol=0.01",
                                                    "people.train=true", "world.seeds=[1, 2]"])
    assert params.crossval.folds == 2 and params.noise.rates == (0.0, 0.2) and params.train.tol == 0.01
    assert params.people.train is True and params.world.seeds == (1, 2)
    assert params.crossval.seed == Params().crossval.seed  # the rest as before


@pytest.mark.parametrize(("override", "message"), [
    ("crossval.folds=six", "crossval.folds must be a whole number, got 'six'"),
    ("crossval.folds=2.5", "crossval.folds must be a whole number, got 2.5"),
    ("train.tol=small", "train.tol must be a number, got 'small'"),
    ("people.train=maybe", "people.train must be true or false, got 'maybe'"),
    ("crossval.group_by=world", "crossval.group_by must be one of scenario, environment, got 'world'"),
    ("feedback.n=1 two", "feedback.n must list whole numbers of steps or 'all', got 'two'"),
    ("noise.rates=", "noise.rates must list at least one value"),
    ("train.tl=1", "unknown setting train.tl"),
    ("train.C=3", "unknown setting train.C"),
    ("methods.full.experiments=select nois", "methods.full.experiments: unknown ['nois']"),
    ("methods.full=3", "methods.full must hold keys"),
    ("nosection.key=1", "unknown sections ['nosection']"),
    ("train=1", "expected section.key=value"),
])
def test_a_bad_value_names_its_key(override, message, tmp_path):
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]").replace(".", r"\.")):
        Params.load(tmp_path / "absent.yaml", [override])


def test_a_bad_file_is_named(tmp_path):
    bad = tmp_path / "params.yaml"
    bad.write_text("train: [1, 2\n")
    with pytest.raises(ValueError, match=f"{bad}: not valid YAML"):
        Params.load(bad)
    bad.write_text("train:\n  tol: 1\n  feature: full\n")
    with pytest.raises(ValueError, match=f"{bad}: unknown setting train.feature"):
        Params.load(bad)


def test_replay_takes_crossvals_folds_and_cap_and_the_learner():
    params = Params.load(None, ["crossval.folds=3", "crossval.seed=5", "crossval.max_steps=9", "train.tol=0.5"])
    replay = Replay.of(params)
    assert (replay.folds.folds, replay.folds.seed, replay.max_steps, replay.learner.tol) == (3, 5, 9, 0.5)
