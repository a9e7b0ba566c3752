"""Every result-bearing setting of the pipeline, with its default, in one place.

Each dataclass mirrors one section of `params.yaml` field by field (a test
checks that the defaults here equal the file), so a stage run by hand with no
options computes what `dvc repro` computes. How work is spread over CPUs and
how many recordings are written change no number and are not settings: they
are options of the commands only.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any


@dataclass(frozen=True)
class Generate:
    """One draw of the simulated benchmark (a world)."""

    seed: int = 0  # scenario draws and item position jitter


@dataclass(frozen=True)
class World:
    """Which worlds the pipeline draws: results are means over `seeds`; settings are chosen on `dev_seed`."""

    seeds: tuple[int, ...] = (0, 3, 7)  # reported world seeds
    dev_seed: int = 100  # the development world: settings are chosen here and it is never reported


@dataclass(frozen=True)
class Select:
    """Settings chosen on the development world by cross-validation, never on a reported world."""

    C: tuple[float, ...] = (0.3, 1.0, 3.0, 10.0)  # slack weights tried for the MRF models


@dataclass(frozen=True)
class Learner:
    """The cutting-plane structural SVM, and DAgger's rounds (`train` section, without the feature set)."""

    C: float = 3.0  # slack weight: 0.5 ||w||^2 + C * sum of slacks; the pipeline takes it from `select`
    tol: float = 1e-3  # relative primal-dual gap to stop at
    max_iter: int = 2000  # cutting-plane iterations at most
    n_slacks: int = 0  # slack groups, one cut each per iteration (0: one per step, n-slack; 1: classic 1-slack)
    dagger_rounds: int = 1  # DAgger rounds (roll out, ask the demonstrator, refit) of the `dagger` method

    @property
    def ssvm(self) -> dict[str, float | int]:
        """The structural SVM's own settings (what `MRFPlanner` takes besides its feature set)."""
        return {"C": self.C, "tol": self.tol, "max_iter": self.max_iter, "n_slacks": self.n_slacks}


@dataclass(frozen=True)
class Train(Learner):
    feature_set: str = "full"  # full | edge | clique

    @property
    def learner(self) -> Learner:
        return Learner(self.C, self.tol, self.max_iter, self.n_slacks, self.dagger_rounds)


@dataclass(frozen=True)
class Pddl:
    horizon: int = 12  # longest plan the SAT planner searches (also the symbolic baselines')


@dataclass(frozen=True)
class Folds:
    """Which scenarios each cross-validation fold tests on (the `crossval` section's first three)."""

    folds: int = 6
    group_by: str = "scenario"  # scenario | environment (unseen environments)
    seed: int = 0  # fold assignment


@dataclass(frozen=True)
class Crossval(Folds):
    chance_seed: int = 0
    multiclass_C: float = 1.0
    ranking_C: float = 1.0  # role-ranking SVMs of symb-plan-svm
    max_steps: int = 20  # step cap of closed-loop runs

    @property
    def fold_settings(self) -> Folds:
        return Folds(self.folds, self.group_by, self.seed)


@dataclass(frozen=True)
class Noise:
    rates: tuple[float, ...] = (0.0, 0.1, 0.2, 0.3, 0.4)  # probability of flipping each binary attribute
    seeds: int = 3  # noise draws per rate
    seed: int = 0


@dataclass(frozen=True)
class Feedback:
    k: tuple[int, ...] = (2, 3)  # candidates offered to the observer
    n: tuple[str, ...] = ("0", "1", "2", "3", "5", "all")  # steps with feedback


@dataclass(frozen=True)
class People:
    """People's demonstrations (`taskseq serve`): where they are, and whether `train` learns from them."""

    logs: str = "data/people"  # folder of *.jsonl logs; empty by default, which changes no figure
    train: bool = False  # add them to the training steps of the `train` stage


@dataclass(frozen=True)
class Teach:
    """Teaching unseen environments: a scripted person demonstrates k tasks in each; the rest are tested."""

    environments: tuple[str, ...] = ("env11", "env12", "env13")  # held out of the training data
    k: tuple[int, ...] = (0, 1, 2, 3)  # tasks demonstrated per environment
    seed: int = 0  # order in which tasks are demonstrated


SECTIONS: dict[str, type] = {
    "world": World,
    "select": Select,
    "train": Train,
    "pddl": Pddl,
    "crossval": Crossval,
    "noise": Noise,
    "feedback": Feedback,
    "people": People,
    "teach": Teach,
}


# Fields of a section's class that params.yaml leaves out, and why.
NOT_IN_PARAMS = {("train", "C"): "chosen by the select stage on the development world (reports/selection.json)"}


def from_values(cls: type, values: dict[str, Any]) -> Any:
    """A settings object from a mapping that may hold more keys (argparse's namespace, say)."""
    return cls(**{f.name: values[f.name] for f in fields(cls) if f.name in values})


def parse_section(cls: type, section: dict[str, Any]) -> Any:
    """A settings object from a `params.yaml` section; lists may be written as space-separated strings."""
    unknown = set(section) - {f.name for f in fields(cls)}
    if unknown:
        raise ValueError(f"params.yaml: unknown settings {sorted(unknown)} for {cls.__name__}")
    out = {}
    for f in fields(cls):
        if f.name not in section:
            continue
        value = section[f.name]
        default = getattr(cls(), f.name)
        if isinstance(default, tuple):
            items = value.split() if isinstance(value, str) else list(value)
            value = tuple(type(default[0])(v) for v in items)
        elif isinstance(default, float):
            value = float(value)
        out[f.name] = value
    return cls(**out)
