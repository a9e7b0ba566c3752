"""Every result-bearing setting of the pipeline, with its default, in one place.

Each dataclass is one section of `params.yaml`, field by field (a test checks
that the defaults here equal the file), and `Params` is the whole file. The
`methods` section is the one without defaults here: each method's entry (the
experiments that run it, its own settings) is written in the file only, and
checked against the method's spec (`taskseq.methods`) when a stage configures
the methods. A
stage reads the file once (`Params.load`), with any `--set section.key=value`
of its command line on top, and picks what it needs into its own settings
object; the stage's `params` list in `dvc.yaml` names exactly those keys (a
test checks that too). How work is spread over CPUs and how many recordings
are written change no number and are not settings: they are options of the
commands only.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import yaml


@dataclass(frozen=True)
class World:
    """Which worlds the pipeline draws: results are means over `seeds`; settings are chosen on `dev_seed`."""

    family: str = "paper"  # paper: the 13 rooms of the reproduction; procedural: rooms drawn by the world seed
    seeds: tuple[int, ...] = (0, 3, 7)  # reported world seeds
    dev_seed: int = 100  # the development world: settings are chosen here and it is never reported


@dataclass(frozen=True)
class Procedural:
    """The distribution rooms are drawn from in the procedural family; docs/world.md gives each value's reason.

    Counts are inclusive ranges (low high), drawn uniformly per room.
    """

    environments: int = 13  # rooms per world
    size_spread: float = 0.15  # a catalog object's width, length and height each vary by up to this share
    new_objects: float = 0.4  # probability that a movable object or bin is of a kind the catalog never had
    tables: tuple[int, ...] = (1, 2)
    shelves: tuple[int, ...] = (0, 2)
    bins: tuple[int, ...] = (1, 2)
    pourers: tuple[int, ...] = (1, 3)  # each with a liquid inside
    vessels: tuple[int, ...] = (3, 6)
    filled_vessels: tuple[int, ...] = (1, 3)  # of the vessels, how many hold a liquid (something to stir)
    stirrers: tuple[int, ...] = (1, 3)
    items: tuple[int, ...] = (1, 3)
    stacks: float = 0.5  # probability that a small object rests on a book, magazine, tray or board

    def __post_init__(self) -> None:
        if self.environments < 1:
            raise ValueError(f"procedural.environments must be at least 1, got {self.environments}")
        for name in ("size_spread", "new_objects", "stacks"):
            if not 0.0 <= getattr(self, name) < 1.0:
                raise ValueError(f"procedural.{name} must lie in [0, 1), got {getattr(self, name)}")
        for name in ("tables", "shelves", "bins", "pourers", "vessels", "filled_vessels", "stirrers", "items"):
            bounds = getattr(self, name)
            if len(bounds) != 2 or not 0 <= bounds[0] <= bounds[1]:
                got = " ".join(map(str, bounds))
                raise ValueError(f"procedural.{name} must be two counts, low then high, got {got}")
        if self.tables[0] < 1 or self.bins[0] < 1:
            raise ValueError("procedural.tables and procedural.bins must start at 1: every task needs a table "
                             "and throwing away needs a bin")


@dataclass(frozen=True)
class Generate:
    """One draw of the simulated benchmark (a world): its family, seed and, when drawn, the rooms' distribution."""

    seed: int = 0  # scenario draws (and item position jitter, or the rooms themselves)
    family: str = "paper"
    procedural: Procedural = Procedural()


@dataclass(frozen=True)
class Select:
    """Settings chosen on the development world by cross-validation, never on a reported world."""

    C: tuple[float, ...] = (0.3, 1.0, 3.0, 10.0)  # slack weights tried for each MRF method (grid, extended at an edge)
    max_extensions: int = 2  # grid values added beyond an edge per method at most (docs/planner-shipped.md)
    # rooms of the development world when world.family is procedural (the paper family has its 13): a large
    # benchmark chooses its settings on a world of this size, not on one as large as the reported ones
    environments: int = 13

    def __post_init__(self) -> None:
        if self.environments < 1:
            raise ValueError(f"select.environments must be at least 1, got {self.environments}")
        if len(self.C) < 2 or min(self.C) <= 0:
            raise ValueError(f"select.C must list at least two positive values (the grid's spacing is how it is "
                             f"extended), got {' '.join(f'{c:g}' for c in self.C)}")
        if self.max_extensions < 0:
            raise ValueError(f"select.max_extensions must be at least 0, got {self.max_extensions}")


@dataclass(frozen=True)
class Learner:
    """The cutting-plane structural SVM's settings (`train` section) but C, which is each method's own: the `select`
    stage chooses it on the development world (`taskseq.methods.selection`)."""

    tol: float = 1e-3  # relative primal-dual gap to stop at
    max_iter: int = 2000  # cutting-plane iterations at most
    n_slacks: int = 0  # slack groups, one cut each per iteration (0: one per step, n-slack; 1: classic 1-slack)


@dataclass(frozen=True)
class Train(Learner):
    """The learner, and the method of the model `taskseq plan` uses."""

    method: str = "best"  # an MRF method of Table I by name, or best: the one `select` ranked first

    @property
    def learner(self) -> Learner:
        """The learner without the method: what every evaluated MRF method takes."""
        return Learner(self.tol, self.max_iter, self.n_slacks)


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
    # the multiclass SVM's stopping tolerance, chosen on the development world (scripts/multiclass_tol.py)
    multiclass_tol: float = 0.01
    ranking_C: float = 1.0  # role-ranking SVMs of symb-plan-svm
    max_steps: int = 20  # step cap of closed-loop runs

    @property
    def fold_settings(self) -> Folds:
        return Folds(self.folds, self.group_by, self.seed)


@dataclass(frozen=True)
class Noise:
    """Attribute noise at test time (`noise` stage); the methods run are those whose `experiments` name noise."""

    rates: tuple[float, ...] = (0.0, 0.1, 0.2, 0.3, 0.4)  # probability of flipping each binary attribute
    draws: int = 3  # noise draws per rate
    seed: int = 0  # seed of the noise draws


@dataclass(frozen=True)
class Feedback:
    """An observer's feedback (`feedback` stage); the methods run are those whose `experiments` name feedback."""

    k: tuple[int, ...] = (2, 3)  # candidates offered to the observer
    n: tuple[str, ...] = ("0", "1", "2", "3", "5", "all")  # steps with feedback

    def __post_init__(self) -> None:
        bad = [n for n in self.n if n != "all" and not n.isdigit()]
        if bad:
            raise ValueError(f"feedback.n must list whole numbers of steps or 'all', got {bad[0]!r}")


@dataclass(frozen=True)
class Recipes:
    """Programs chained into recipes (`recipes` stage); the methods run are those whose `experiments` name recipes."""

    observer_k: int = 3  # candidates the observer picks among at the start of each program (feedback runs)


@dataclass(frozen=True)
class People:
    """People's demonstrations (`taskseq serve`): where they are, and whether `train` learns from them."""

    logs: str = "data/people"  # folder of *.jsonl logs; empty by default, which changes no figure
    train: bool = False  # add them to the training steps of the `train` stage


@dataclass(frozen=True)
class Teach:
    """Teaching rooms never seen: a scripted person demonstrates k tasks in each; the rest are tested."""

    environments: tuple[str, ...] = ("proc011", "proc012", "proc013")  # drawn rooms held out of the training data
    k: tuple[int, ...] = (0, 1, 2, 3)  # tasks demonstrated per room
    seed: int = 0  # order in which tasks are demonstrated
    weight: int = 30  # times each taught step counts in training (scripts/teach_weight.py, on the development world)

    def __post_init__(self) -> None:
        if not self.k or min(self.k) < 0:
            raise ValueError(f"teach.k must list numbers of tasks, at least 0, got {' '.join(map(str, self.k))}")
        if self.weight < 1:
            raise ValueError(f"teach.weight must be at least 1 (times a taught step counts), got {self.weight}")


@dataclass(frozen=True)
class Stats:
    """The bootstrap behind Table I's confidence intervals and the paired comparisons (`stats` stage)."""

    seed: int = 0  # seed of the resamples
    resamples: int = 2000  # bootstrap resamples (worlds, then scenarios within each)
    confidence: float = 0.95  # coverage of the intervals

    def __post_init__(self) -> None:
        if self.resamples < 1:
            raise ValueError(f"stats.resamples must be at least 1, got {self.resamples}")
        if not 0.0 < self.confidence < 1.0:
            raise ValueError(f"stats.confidence must lie strictly between 0 and 1, got {self.confidence}")


# What a method's `experiments` may name: the experiments beside Table I, which runs every method.
EXPERIMENTS = {
    "select": "its own C chosen on the development world, and ranked for shipping",
    "noise": "run with attribute noise at test time (noise stage, and the scenes stage's drawn worlds)",
    "feedback": "run with an observer's feedback (feedback stage, and the scenes stage's drawn worlds)",
    "recipes": "programs chained into recipes (recipes stage; fold_models trains its models per recipe)",
    "transfer": "trained on the paper-shaped world and run in the drawn one (scenes stage)",
}


@dataclass(frozen=True)
class MethodEntry:
    """One method's entry of the `methods` section: the experiments that run it, and its own settings as written
    (the method's spec, `taskseq.methods`, checks them against its settings and their defaults)."""

    experiments: tuple[str, ...] = ()
    settings: tuple[tuple[str, Any], ...] = ()


@dataclass(frozen=True)
class Methods:
    """The `methods` section: per Table I method, its settings and the experiments beside Table I that run it.

    The file's order is the order the experiments run them in (and `select` breaks a tie in the ranking by it). A
    method the file does not name keeps its spec's defaults (`taskseq.methods`), so this class has no list of
    methods of its own: the file is where the pipeline's are written.
    """

    entries: tuple[tuple[str, MethodEntry], ...] = ()

    @classmethod
    def parse(cls, section: Mapping[str, Any], source: str = "params.yaml") -> Methods:
        entries = []
        for name, entry in section.items():
            entry = {} if entry is None else entry
            if not isinstance(entry, dict):
                raise ValueError(f"{source}: methods.{name} must hold keys (experiments and its own settings), got "
                                 f"{entry!r}")
            written = entry.get("experiments", "")
            items = written.split() if isinstance(written, str) else written if isinstance(written, list) else None
            if items is None:
                raise ValueError(f"{source}: methods.{name}.experiments must list experiments, got {written!r}")
            unknown = [e for e in items if e not in EXPERIMENTS]
            if unknown:
                raise ValueError(f"{source}: methods.{name}.experiments: unknown {unknown}; known: "
                                 f"{', '.join(EXPERIMENTS)}")
            own = tuple((k, v) for k, v in entry.items() if k != "experiments")
            entries.append((str(name), MethodEntry(tuple(dict.fromkeys(items)), own)))
        return cls(tuple(entries))

    def flat(self) -> dict[str, Any]:
        """Each entry's keys as `methods.NAME.KEY`, the experiments as one space-separated value."""
        out: dict[str, Any] = {}
        for name, entry in self.entries:
            out[f"methods.{name}.experiments"] = " ".join(entry.experiments)
            out |= {f"methods.{name}.{key}": value for key, value in entry.settings}
        return out

    def entry(self, name: str) -> MethodEntry | None:
        """The file's entry of a method, or None when the file does not name it."""
        return dict(self.entries).get(name)


@dataclass(frozen=True)
class Replay:
    """How the noise and feedback stages re-run the test scenarios: crossval's folds, so each scenario is run
    by a model that did not train on it, and step cap, and the learner of those models."""

    folds: Folds
    max_steps: int
    learner: Learner

    @classmethod
    def of(cls, params: Params) -> Replay:
        return cls(params.crossval.fold_settings, params.crossval.max_steps, params.train.learner)


# What a key may hold beyond its type, checked when the file is read.
CHOICES: dict[tuple[str, str], tuple[str, ...]] = {
    ("world", "family"): ("paper", "procedural"),
    ("crossval", "group_by"): ("scenario", "environment"),
}

@dataclass(frozen=True)
class Params:
    """The whole of `params.yaml`, a typed section per field."""

    world: World = World()
    procedural: Procedural = Procedural()
    select: Select = Select()
    train: Train = Train()
    pddl: Pddl = Pddl()
    crossval: Crossval = Crossval()
    noise: Noise = Noise()
    feedback: Feedback = Feedback()
    recipes: Recipes = Recipes()
    methods: Methods = Methods()
    people: People = People()
    teach: Teach = Teach()
    stats: Stats = Stats()

    @classmethod
    def load(cls, path: Path | str | None = Path("params.yaml"), overrides: Iterable[str] = ()) -> Params:
        """The file's settings (defaults where it is missing or silent), then `section.key=value` overrides.

        Raises `ValueError` naming the file and the key for anything it cannot take.
        """
        source = "params.yaml" if path is None else str(path)
        overrides = list(overrides)
        raw: dict[str, Any] = {}
        if path is not None and Path(path).exists():
            try:
                raw = yaml.safe_load(Path(path).read_text()) or {}
            except yaml.YAMLError as err:
                raise ValueError(f"{source}: not valid YAML ({err})") from None
            if not isinstance(raw, dict):
                raise ValueError(f"{source}: expected sections such as 'train:', got {type(raw).__name__}")
        raw = {k: dict(v) if isinstance(v, dict) else v for k, v in raw.items()}
        if isinstance(raw.get("methods"), dict):  # its entries are changed in place by overrides below: copies
            raw["methods"] = {k: dict(v) if isinstance(v, dict) else v for k, v in raw["methods"].items()}
        for item in overrides:
            key, sep, value = item.partition("=")
            section, dot, name = key.strip().partition(".")
            if not sep or not dot or not name:
                raise ValueError(f"--set {item!r}: expected section.key=value, e.g. train.tol=1e-4")
            raw.setdefault(section, {})
            if not isinstance(raw[section], dict):
                raise ValueError(f"{source}: section {section!r} must hold keys, got {raw[section]!r}")
            parsed = yaml.safe_load(value) if value.strip() else ""
            method, dot, key = name.partition(".")
            if section == "methods" and dot:  # methods.NAME.KEY=value: one key of one method's entry
                entry = raw[section].get(method)
                raw[section][method] = {**(entry if isinstance(entry, dict) else {}), key: parsed}
            else:
                raw[section][name] = parsed
        if overrides:
            source = f"{source} with --set {' '.join(overrides)}"
        unknown = sorted(set(raw) - {f.name for f in fields(cls)})
        if unknown:
            raise ValueError(f"{source}: unknown sections {unknown}; known: {', '.join(f.name for f in fields(cls))}")
        sections = {}
        for f in fields(cls):
            section = raw.get(f.name) or {}
            if not isinstance(section, dict):
                raise ValueError(f"{source}: section {f.name!r} must hold keys, got {section!r}")
            kind = type(getattr(cls(), f.name))
            sections[f.name] = kind.parse(section, source) if kind is Methods else parse_section(kind, section,
                                                                                                    f.name, source)
        return cls(**sections)

    def flat(self) -> dict[str, Any]:
        """Every setting as `section.key` (a method's as `methods.NAME.KEY`): what a stage's run records."""
        out: dict[str, Any] = {}
        for s in fields(self):
            section = getattr(self, s.name)
            if isinstance(section, Methods):
                out |= section.flat()
            else:
                out |= {f"{s.name}.{k.name}": getattr(section, k.name) for k in fields(section)}
        return out


SECTIONS: dict[str, type] = {f.name: type(getattr(Params(), f.name)) for f in fields(Params)}


def _value(kind: type, value: Any, key: str, source: str) -> Any:
    """One value as the field's type, or a `ValueError` that names the key and what it got."""
    if kind is bool:
        if isinstance(value, bool) or str(value).lower() in ("true", "false"):
            return value if isinstance(value, bool) else str(value).lower() == "true"
        raise ValueError(f"{source}: {key} must be true or false, got {value!r}")
    if isinstance(value, (bool, list, dict)):
        raise ValueError(f"{source}: {key} must be {kind.__name__}, got {value!r}")
    try:
        if kind is int:
            if isinstance(value, float) or (isinstance(value, str) and not value.lstrip("-").isdigit()):
                raise ValueError
            return int(value)
        if kind is float:
            return float(value)
        return str(value)
    except (TypeError, ValueError):
        what = {int: "a whole number", float: "a number"}.get(kind, kind.__name__)
        raise ValueError(f"{source}: {key} must be {what}, got {value!r}") from None


def parse_section(cls: type, section: Mapping[str, Any], name: str | None = None,
                  source: str = "params.yaml") -> Any:
    """A settings object from a `params.yaml` section; lists may be written as space-separated strings."""
    name = name or next((s for s, c in SECTIONS.items() if c is cls), cls.__name__.lower())
    known = [f.name for f in fields(cls)]
    unknown = sorted(set(section) - set(known))
    if unknown:
        keys = ", ".join(f"{name}.{k}" for k in unknown)
        raise ValueError(f"{source}: unknown setting {keys}; {name} has {', '.join(known)}")
    out = {}
    for f in fields(cls):
        if f.name not in section:
            continue
        value, default, key = section[f.name], getattr(cls(), f.name), f"{name}.{f.name}"
        if isinstance(default, tuple):
            items = value.split() if isinstance(value, str) else value if isinstance(value, list) else [value]
            value = tuple(_value(type(default[0]), v, key, source) for v in items)
            if not value:
                raise ValueError(f"{source}: {key} must list at least one value")
        else:
            value = _value(type(default), value, key, source)
        choices = CHOICES.get((name, f.name))
        if choices and value not in choices:
            raise ValueError(f"{source}: {key} must be one of {', '.join(choices)}, got {value!r}")
        out[f.name] = value
    try:
        return cls(**out)
    except ValueError as err:
        raise ValueError(f"{source}: {err}") from None
