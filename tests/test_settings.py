"""params.yaml as a stage reads it: overrides, and every kind of bad value refused with its key named."""

from __future__ import annotations

from pathlib import Path

import pytest

from taskseq.settings import Params, Replay

ROOT = Path(__file__).resolve().parents[1]


def test_the_repository_file_equals_the_defaults_and_a_missing_file_gives_them(tmp_path):
    assert Params.load(ROOT / "params.yaml") == Params()
    assert Params.load(tmp_path / "absent.yaml") == Params()


def test_overrides_set_one_key_each_with_its_type(tmp_path):
    params = Params.load(tmp_path / "absent.yaml", ["crossval.folds=2", "noise.rates=0 0.2", "train.C=10",
                                                    "people.train=true", "world.seeds=[1, 2]"])
    assert params.crossval.folds == 2 and params.noise.rates == (0.0, 0.2) and params.train.C == 10.0
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
    params = Params.load(None, ["crossval.folds=3", "crossval.seed=5", "crossval.max_steps=9", "train.C=2"])
    replay = Replay.of(params)
    assert (replay.folds.folds, replay.folds.seed, replay.max_steps, replay.learner.C) == (3, 5, 9, 2.0)
