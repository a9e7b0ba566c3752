"""Every method behind one interface: fit on training steps, predict a step, run a sequence.

A step prediction is (primitive, a1, a2) from the true state and history
(teacher-forced); -1 for an argument the method does not predict. A sequence
is run closed-loop in the simulator from a scenario's initial state.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np

from ..demonstrations.benchmark import Benchmark
from ..features.context import N_PRIM, OBJECT_COLUMNS, StepContext, candidate_index, step_context
from ..features.dataset import StepMeta
from ..features.drawn_rooms import drawn_room_steps
from ..features.perception import noisy_copies
from ..imitation.dagger import fit_imitation
from ..learn.estimator import StepScorer
from ..learn.store import ModelStore, training_key
from ..plan.planner import POLICIES, Memo, Policy, Program, learned_policy, program, run_loop, run_programs
from ..plan.symbolic.executor import SymbolicPolicy, first_action
from ..plan.symbolic.roles import ROLE_OF_TASK, RoleRanker, demonstrated_roles
from ..settings import Crossval, Pddl, Procedural
from ..sim.primitives import Action
from ..sim.scenarios import Scenario
from ..sim.state import WorldState
from ..sim.tasks import TASKS, Task

Y = tuple[int, int, int]


class Method(Protocol):
    """`meta` says which sequence and step each context is; `scenarios` holds (at least) the training
    scenarios, which methods that consult the demonstrator need; `demos` holds world states and actions."""

    name: str
    predicts_args: bool

    def fit(self, contexts: list[StepContext], meta: list[StepMeta],
            scenarios: Mapping[str, Scenario] | None = None) -> Method: ...

    def predict_steps(self, contexts: list[StepContext], meta: list[StepMeta], demos: Benchmark) -> list[Y]: ...

    def run(self, scenario: Scenario, max_steps: int) -> Program | None: ...


@dataclass
class ChanceMethod:
    """A primitive drawn uniformly (the seven and done), then its arguments uniformly among the step's
    candidates for it: the paper's chance, whose primitive is right 1 time in 7."""

    seed: int = 0
    name: str = "chance"
    predicts_args: bool = True

    def fit(self, contexts: list[StepContext], meta: list[StepMeta], scenarios=None) -> ChanceMethod:
        return self

    def _draw(self, n: int, rng: np.random.Generator) -> Y:
        p, a1, a2 = candidate_index(n)
        prim = int(rng.integers(N_PRIM))
        options = np.flatnonzero(p == prim)
        k = int(options[rng.integers(len(options))])
        return prim, int(a1[k]), int(a2[k])

    def predict_steps(self, contexts: list[StepContext], meta=None, demos=None) -> list[Y]:
        rng = np.random.default_rng(self.seed)
        return [self._draw(x.n, rng) for x in contexts]

    def run(self, scenario: Scenario, max_steps: int) -> Program:
        rng = np.random.default_rng([self.seed, sum(map(ord, scenario.id))])
        return run_loop(lambda ctx, state: [(self._draw(ctx.n, rng), 0.0)], scenario.initial, scenario.task,
                        max_steps)


def multiclass_features(x: StepContext) -> np.ndarray:
    """Task, the last two primitives, whether the hand is full, and the rows of the held
    object and of the task's arguments: what a per-step classifier can see without
    choosing arguments."""
    out = [np.eye(len(TASKS))[x.task], np.eye(N_PRIM + 1)[x.prev_prims[0]], np.eye(N_PRIM + 1)[x.prev_prims[1]]]
    held = np.flatnonzero(x.objects[:, 0] > 0.5)
    out.append([float(len(held) > 0)])
    out.append(x.objects[held[0]] if len(held) else np.zeros(len(OBJECT_COLUMNS)))
    for k in range(2):
        rows = np.flatnonzero(x.task_rel[:, k] > 0.5)
        out.append(x.objects[rows[0]] if len(rows) else np.zeros(len(OBJECT_COLUMNS)))
    return np.concatenate([np.asarray(v, dtype=float) for v in out])


@dataclass
class MulticlassMethod:
    """A Crammer-Singer linear SVM over the primitive only; it predicts no arguments."""

    C: float = Crossval.multiclass_C
    tol: float = Crossval.multiclass_tol  # liblinear's stopping tolerance
    name: str = "multiclass"
    predicts_args: bool = False

    def fit(self, contexts: list[StepContext], meta: list[StepMeta], scenarios=None) -> MulticlassMethod:
        from sklearn.svm import LinearSVC  # imported here: only this baseline's fit needs scikit-learn

        X = np.array([multiclass_features(x) for x in contexts])
        y = np.array([x.gold[0] for x in contexts])
        self.svm_ = LinearSVC(multi_class="crammer_singer", C=self.C, tol=self.tol, max_iter=200000,
                              random_state=0).fit(X, y)
        return self

    def predict_steps(self, contexts: list[StepContext], meta=None, demos=None) -> list[Y]:
        X = np.array([multiclass_features(x) for x in contexts])
        return [(int(p), -1, -1) for p in self.svm_.predict(X)]

    def run(self, scenario: Scenario, max_steps: int) -> None:
        return None  # no arguments, no program


@dataclass
class ScorerMethod:
    """A Table I method built around a `StepScorer`: the scorer's feature set and learner settings, the
    training data it is fitted on, and the policy its programs pick steps with.

    `chained_starts` adds, per training scenario, a demonstration that starts
    where it ended (`imitation.starts`); `dagger_rounds` rolls the scorer out
    on the training scenarios that many times and adds the demonstrator's
    answers in the states it reached (`imitation.dagger`). Both need the
    training scenarios at `fit`. `noise_copies` adds that many copies of the
    training steps seen with each binary attribute flipped with probability
    `noise_rate` (`features.perception.noisy_copies`). `training_rooms` adds
    the demonstrated steps of that many rooms drawn from `rooms_from` with
    `rooms_seed` (`features.drawn_rooms`): rooms no world reports.
    `policy` is how its programs pick a step
    (`plan.planner.POLICIES`); it changes no weight, so it is not part of a
    stored model's key. With a `store` folder (written by the `fold_models`
    stage), a model already trained on the same steps with the same settings
    is loaded, not retrained.
    """

    features: str = "full"
    C: float = 3.0  # the learner's settings default to `StepScorer`'s; a Table I method is given each of them
    tol: float = 1e-3
    max_iter: int = 2000
    n_slacks: int = 0
    chained_starts: bool = False
    dagger_rounds: int = 0
    noise_rate: float = 0.0
    noise_copies: int = 0
    training_rooms: int = 0
    rooms_seed: int = 0
    rooms_from: Procedural = Procedural()
    name: str = "full"
    predicts_args: bool = True
    store: str | None = None
    policy: str = "greedy"

    def __post_init__(self) -> None:
        if self.policy not in POLICIES:
            raise ValueError(f"method {self.name}: unknown policy {self.policy!r}; known: {', '.join(POLICIES)}")

    def learner_params(self) -> dict[str, float | int]:
        """The settings that change the weights (and so address a stored model)."""
        return {"C": self.C, "tol": self.tol, "max_iter": self.max_iter, "n_slacks": self.n_slacks,
                "chained_starts": self.chained_starts, "dagger_rounds": self.dagger_rounds,
                **({"noise_rate": self.noise_rate, "noise_copies": self.noise_copies} if self.noise_copies else {}),
                **({"training_rooms": self.training_rooms, "rooms_seed": self.rooms_seed,
                    "rooms_from": repr(self.rooms_from)} if self.training_rooms else {})}

    def key(self, contexts: list[StepContext]) -> str:
        return training_key(self.features, self.learner_params(), contexts)

    def plain(self) -> ScorerMethod:
        """This method's features and learner settings fitted on the demonstrated steps alone (no chained starts,
        DAgger, noisy copies or drawn rooms): the model a fit of its richer training data starts from
        (`experiments.fold_models.plan_tasks`)."""
        return replace(self, chained_starts=False, dagger_rounds=0, noise_rate=0.0, noise_copies=0,
                       training_rooms=0, rooms_seed=0, rooms_from=Procedural())

    def estimator(self) -> StepScorer:
        """The unfitted scorer with this method's feature set and learner settings."""
        return StepScorer(self.features, C=self.C, tol=self.tol, max_iter=self.max_iter, n_slacks=self.n_slacks)

    def fit(self, contexts: list[StepContext], meta: list[StepMeta],
            scenarios: Mapping[str, Scenario] | None = None, base: StepScorer | None = None,
            warm: StepScorer | None = None) -> ScorerMethod:
        """Sets `planner_`, the fitted `StepScorer`: loaded from the store when it holds these steps and settings,
        else fitted.

        `base` is this method's scorer without DAgger, fitted on the same
        steps, when the caller has it: DAgger starts from it. `warm` is a
        scorer of the same features, at any C, fitted on steps this fit's
        begin with (`contexts` alone, or this recipe's very steps): the fit
        starts from its cuts (`StepScorer.fit`'s warm start).
        """
        stored = ModelStore(self.store).load(self.key(contexts)) if self.store else None
        if stored is not None:
            self.planner_ = stored
            return self
        steps = contexts + noisy_copies(contexts, meta, self.noise_rate, self.noise_copies)[0]
        if self.training_rooms:
            steps += drawn_room_steps(self.training_rooms, self.rooms_seed, self.rooms_from)
        if self.chained_starts or self.dagger_rounds:
            if scenarios is None:
                raise ValueError(f"method {self.name}: chained starts and DAgger need the training scenarios")
            training = [scenarios[s] for s in dict.fromkeys(m.scenario_id for m in meta)]
            if base is None and self.dagger_rounds and self.store:  # the model without DAgger, stored or not
                base = replace(self, dagger_rounds=0).fit(contexts, meta, scenarios, warm=warm).planner_
            self.planner_ = fit_imitation(self.estimator(), steps, training, self.dagger_rounds,
                                          self.chained_starts, base=base, warm=warm)
        else:
            self.planner_ = self.estimator().fit(steps, warm_start=warm)
        return self

    def predict_steps(self, contexts: list[StepContext], meta=None, demos=None) -> list[Y]:
        return self.planner_.predict(contexts)

    def policy_for(self, scenario: Scenario) -> Policy:
        """The policy of one program of `scenario`: the one `run` and `run_all` take (a variant of the method
        that runs otherwise, `scripts/lookahead_grid.py`'s, changes this alone)."""
        return learned_policy(self.policy, self.planner_, scenario.task, scenario.initial)

    def run(self, scenario: Scenario, max_steps: int) -> Program:
        return run_loop(self.policy_for(scenario), scenario.initial, scenario.task, max_steps,
                        memo=Memo(worlds=_worlds_met(scenario)))

    def run_all(self, scenarios: list[Scenario], max_steps: int) -> list[Program]:
        """`run` of every scenario, the programs advancing together and scored in batches (`run_programs`)."""
        return run_programs(self.planner_, [program(self.policy_for(sc), sc.initial, sc.task, max_steps,
                                                    memo=Memo(worlds=_worlds_met(sc))) for sc in scenarios])


def configured(make: Callable[[], ScorerMethod], **changes: Any) -> ScorerMethod:
    """The unfitted method `make()` makes, with `changes` to its fields (another name, a model store): a
    module-level function, so `functools.partial(configured, make, ...)` goes to a worker process."""
    return replace(make(), **changes)


# The worlds and step contexts the programs of a scenario met, by history, kept per process across methods: the
# methods of a grid run one after another on the same scenario objects (`runtime.jobs.Shared`), and a world and
# its context at a history are the same whichever policy reached it (`plan.planner.Memo`), so a later method reads
# them back instead of stepping the simulator and building the context again (7 of 10 contexts of a world's
# cross-validation). Each entry keeps its scenario, so no id is reused while it is kept; past `_KEPT_SCENARIOS`
# (a fold's test scenarios of the largest world measured) all are dropped at once.
_WORLDS_MET: dict[int, tuple[Scenario, dict]] = {}
_KEPT_SCENARIOS = 300


def _worlds_met(scenario: Scenario) -> dict:
    kept = _WORLDS_MET.get(id(scenario))
    if kept is None or kept[0] is not scenario:
        if len(_WORLDS_MET) >= _KEPT_SCENARIOS:
            _WORLDS_MET.clear()
        kept = _WORLDS_MET[id(scenario)] = (scenario, {})
    return kept[1]


def _role_candidates(x: StepContext) -> tuple[np.ndarray, list[str]]:
    """Rows (state bits, attributes, task relations) of the objects that are not task arguments."""
    keep = [i for i in range(x.n) if x.task_rel[i, 0] < 0.5 and x.task_rel[i, 1] < 0.5]
    return np.hstack([x.objects, x.task_rel])[keep], [x.object_ids[i] for i in keep]


@dataclass
class SymbolicMethod:
    """SATPLAN over the PDDL domain; the goal's open roles from the demonstration or from ranking SVMs."""

    goals: str = "manual"  # manual | svm
    C: float = Crossval.ranking_C  # of the role-ranking SVMs
    horizon: int = Pddl.horizon
    name: str = "symb_plan_manual"
    predicts_args: bool = True

    def fit(self, contexts: list[StepContext], meta: list[StepMeta], scenarios=None) -> SymbolicMethod:
        if self.goals == "manual":
            return self
        if scenarios is None:
            raise ValueError(f"method {self.name}: the role rankers need the training scenarios (their tasks)")
        by_sequence: dict[str, tuple[str, list[StepContext]]] = {}
        for x, m in zip(contexts, meta, strict=True):
            by_sequence.setdefault(m.sequence_id, (m.scenario_id, []))[1].append(x)
        groups: dict[str, list[tuple[np.ndarray, int]]] = {}
        for scenario_id, steps in by_sequence.values():
            first, task = steps[0], scenarios[scenario_id].task
            role = ROLE_OF_TASK.get(task.name)
            if role is None:
                continue
            chosen = demonstrated_roles(task, [x.action(x.gold) for x in steps])[role]
            X, ids = _role_candidates(first)
            groups.setdefault(role, []).append((X, ids.index(chosen)))
        self.rankers_ = {role: RoleRanker(self.C).fit(g) for role, g in groups.items()}
        return self

    def roles(self, task: Task, initial: WorldState, demonstration: tuple[Action, ...]) -> dict[str, str]:
        role = ROLE_OF_TASK.get(task.name)
        if role is None:
            return {}
        if self.goals == "manual":
            return demonstrated_roles(task, demonstration)
        X, ids = _role_candidates(step_context(initial, task, []))
        if role not in self.rankers_:  # no training task had this role: no preference, the first object
            return {role: ids[0]}
        return {role: ids[self.rankers_[role].best(X)]}

    def predict_steps(self, contexts: list[StepContext], meta: list[StepMeta], demos: Benchmark) -> list[Y]:
        out = []
        for x, m in zip(contexts, meta, strict=True):
            task = demos.scenarios[m.scenario_id].task
            roles = self.roles(task, demos.states[(m.sequence_id, 0)], demos.actions[m.sequence_id])
            action = first_action(demos.states[(m.sequence_id, m.step)], task, roles, self.horizon)
            out.append(x.encode(action) if action is not None else (-1, -1, -1))
        return out

    def run(self, scenario: Scenario, max_steps: int) -> Program:
        roles = self.roles(scenario.task, scenario.initial, scenario.demonstrations[0])
        return run_loop(SymbolicPolicy(scenario.task, roles, self.horizon), scenario.initial, scenario.task,
                        max_steps)


def method_params(name: str, method: Method) -> dict[str, Any]:
    """What tells one method's run from another's in MLflow: name, feature set, C and the options it has."""
    out: dict[str, Any] = {"method": name}
    if isinstance(method, ScorerMethod):
        out.update(feature_set=method.features, C=method.C, chained_starts=method.chained_starts,
                   dagger_rounds=method.dagger_rounds, policy=method.policy)
    elif isinstance(method, MulticlassMethod):
        out.update(C=method.C)
    elif isinstance(method, SymbolicMethod):
        out.update(goals=method.goals, horizon=method.horizon, **({"C": method.C} if method.goals == "svm" else {}))
    return out
