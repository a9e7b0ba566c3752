"""Cross-validation: grouped folds, teacher-forced steps and closed-loop sequences per method."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field, replace

from threadpoolctl import threadpool_limits

from ..demonstrations.benchmark import Benchmark
from ..evaluate.failures import classify
from ..evaluate.folds import grouped_folds
from ..evaluate.methods import Method, MulticlassMethod, ScorerMethod, SymbolicMethod
from ..features.context import StepContext
from ..features.dataset import StepMeta
from ..plan.planner import Program
from ..runtime.jobs import Shared, run_jobs
from ..sim.scenarios import Scenario
from . import outcome_cache

Y = tuple[int, int, int]


@dataclass(frozen=True)
class SequenceOutcome:
    scenario_id: str
    task: str
    actions: tuple[str, ...]
    status: str
    prim_correct: bool  # the primitives equal those of a demonstration
    arg_correct: bool  # primitives and arguments equal a demonstration
    goal_reached: bool
    safe: bool
    success: bool
    failure: str  # its kind (`failures.KINDS`): exact, other_success, or why it failed


@dataclass
class FoldResult:
    method: str
    fold: int
    step_index: list[int]
    step_predictions: list[Y]
    sequences: list[SequenceOutcome] | None  # None: the method runs no programs
    programs: dict[str, Program] = field(default_factory=dict)  # kept for recordings


def judge(scenario: Scenario, program: Program) -> SequenceOutcome:
    actions = tuple(program.actions)
    prims = tuple(a.primitive for a in actions)
    unsafe = [k for k, s in enumerate(program.steps) if s.unsafe]
    return SequenceOutcome(
        scenario_id=scenario.id,
        task=scenario.task.name,
        actions=tuple(str(a) for a in actions),
        status=program.status,
        prim_correct=any(prims == tuple(a.primitive for a in d) for d in scenario.demonstrations),
        arg_correct=any(actions == d for d in scenario.demonstrations),
        goal_reached=program.goal_reached,
        safe=program.safe,
        success=program.success,
        failure=classify(actions, program.status, unsafe, program.success, scenario.demonstrations,
                         program.goal_reached),
    )


def run_fold(make: Callable[[], Method], fold: int, contexts: list[StepContext], meta: list[StepMeta],
             scenarios: dict[str, Scenario], test_scenarios: set[str], max_steps: int,
             demos: Benchmark | None = None, keep_programs: frozenset[str] = frozenset()) -> FoldResult:
    with threadpool_limits(limits=1):  # the same sums, so the same bytes, in any process (see learn/estimator.py)
        return _run_fold(make, fold, contexts, meta, scenarios, test_scenarios, max_steps, demos, keep_programs)


def _run_fold(make, fold, contexts, meta, scenarios, test_scenarios, max_steps, demos, keep_programs) -> FoldResult:
    train_index = training_index(meta, test_scenarios)
    test_index = [i for i, m in enumerate(meta) if m.scenario_id in test_scenarios]
    method = make()

    def fitted() -> Method:
        return method.fit([contexts[i] for i in train_index], [meta[i] for i in train_index], scenarios)

    # a scorer's weights key its outcomes (the store may hold a model trained otherwise), so it is fitted (read
    # from the store) first; the baselines' fits (scikit-learn's SVMs) are decided by what the key already holds,
    # and are done only when their outcomes are not read back
    scorer = isinstance(method, ScorerMethod)
    if scorer:
        method = fitted()

    def ready() -> Method:  # the method fitted, when it is about to run
        return method if scorer else fitted()

    data = (contexts, meta, scenarios, test_scenarios, demos)

    def decoded(entry: dict) -> FoldResult:  # the programs kept for recordings run again: an entry holds none
        result = _decoded(entry)
        kept = sorted(keep_programs & test_scenarios) if result.sequences is not None else []
        runner = ready() if kept else method
        return replace(result, programs={sid: runner.run(scenarios[sid], max_steps) for sid in kept})

    return outcome_cache.read_or_run(
        "crossval", make, method, data, {"fold": fold, "max_steps": max_steps},
        lambda: _tested(ready(), fold, contexts, meta, scenarios, test_scenarios, test_index, max_steps, demos,
                        keep_programs), _encoded, decoded)


def _tested(method, fold, contexts, meta, scenarios, test_scenarios, test_index, max_steps, demos,
            keep_programs) -> FoldResult:
    """The fitted `method`'s predictions of the fold's test steps and its programs on the fold's test scenarios."""
    predictions = method.predict_steps([contexts[i] for i in test_index], [meta[i] for i in test_index], demos)
    outcomes: list[SequenceOutcome] | None = []
    programs = {}
    order = sorted(test_scenarios)
    if isinstance(method, ScorerMethod):  # a learned planner's programs advance together, scored in batches
        ran: Iterable[Program | None] = method.run_all([scenarios[sid] for sid in order], max_steps)
    else:  # one at a time, as they are read: a method with no program (None) ends the loop at its first
        ran = (method.run(scenarios[sid], max_steps) for sid in order)
    for sid, program in zip(order, ran, strict=True):
        if program is None:
            outcomes = None
            break
        outcomes.append(judge(scenarios[sid], program))
        if sid in keep_programs:
            programs[sid] = program
    return FoldResult(method.name, fold, test_index, predictions, outcomes, programs)


def _encoded(result: FoldResult) -> dict:
    """A fold's result as JSON, its kept programs aside (they hold every world state they met)."""
    return {"method": result.method, "fold": result.fold, "step_index": result.step_index,
            "step_predictions": result.step_predictions,
            "sequences": None if result.sequences is None else [asdict(o) for o in result.sequences]}


def outcome_of(entry: dict) -> SequenceOutcome:
    """A `SequenceOutcome` from its JSON (`dataclasses.asdict`)."""
    return SequenceOutcome(**{**entry, "actions": tuple(entry["actions"])})


def _decoded(entry: dict) -> FoldResult:
    sequences = None if entry["sequences"] is None else [outcome_of(o) for o in entry["sequences"]]
    return FoldResult(entry["method"], entry["fold"], entry["step_index"],
                      [tuple(y) for y in entry["step_predictions"]], sequences)


def training_index(meta: list[StepMeta], test_scenarios: set[str]) -> list[int]:
    """The steps a fold trains on: every step of a scenario outside its test set."""
    return [i for i, m in enumerate(meta) if m.scenario_id not in test_scenarios]


def scenario_folds(scenarios: dict[str, Scenario], n_folds: int, seed: int, group_by: str) -> list[set[str]]:
    """Test scenarios of each fold, grouped by scenario or by environment."""
    if group_by not in ("scenario", "environment"):
        raise ValueError(f"group_by must be 'scenario' or 'environment', got {group_by!r}")
    ids = sorted(scenarios)
    groups = [s if group_by == "scenario" else scenarios[s].env_id for s in ids]
    return [{ids[i] for i in idx} for idx in grouped_folds(groups, n_folds, seed)]


def cross_validate(methods: dict[str, Callable[[], Method]], contexts: list[StepContext], meta: list[StepMeta],
                   bench: Benchmark, n_folds: int = 6, seed: int = 0,
                   group_by: str = "scenario", max_steps: int = 20, n_jobs: int = 1,
                   verbose: int = 0, keep_programs: dict[str, frozenset[str]] | None = None) -> list[FoldResult]:
    """`keep_programs` names, per method, the scenarios whose programs come back (for recordings)."""
    scenarios = bench.scenarios
    folds = scenario_folds(scenarios, n_folds, seed, group_by)
    jobs = [(name, k) for name in methods for k in range(n_folds)]
    keep = keep_programs or {}
    # sent to each worker once; without the raw log records, which no method reads (half the benchmark's size)
    steps, shared_meta = Shared(contexts), Shared(meta)
    shared_scenarios, demos = Shared(scenarios), Shared(replace(bench, records=[]))
    made = {name: make() for name, make in methods.items()}  # unfitted: what each method is, for planning the jobs
    cost = {name: _fold_job_cost(method) for name, method in made.items()}
    # the symbolic planners of a fold run in one job, one after the other: where their roles agree (most
    # scenarios) they pose the same SAT problems, which the process then solves once (`plan.symbolic.sat.solve`)
    symbolic = tuple(name for name, method in made.items() if isinstance(method, SymbolicMethod))
    tasks = [(symbolic, k) for k in range(n_folds)] if symbolic else []
    tasks += [((name,), k) for name, k in jobs if name not in symbolic]
    parts = run_jobs([(run_folds, (tuple(methods[name] for name in names), k, steps, shared_meta, shared_scenarios,
                                   folds[k], max_steps, demos, tuple(keep.get(name, frozenset()) for name in names)))
                      for names, k in tasks], n_jobs, verbose, cost=[sum(cost[name] for name in names)
                                                                     for names, _ in tasks], stored_first=True)
    done = {(name, k): result for (names, k), part in zip(tasks, parts, strict=True)
            for name, result in zip(names, part, strict=True)}
    return [done[job] for job in jobs]


def run_folds(makes: tuple[Callable[[], Method], ...], fold: int, contexts: list[StepContext], meta: list[StepMeta],
              scenarios: dict[str, Scenario], test_scenarios: set[str], max_steps: int, demos: Benchmark | None,
              keep_programs: tuple[frozenset[str], ...]) -> list[FoldResult]:
    """`run_fold` of several methods on one fold, in turn, in one process."""
    return [run_fold(make, fold, contexts, meta, scenarios, test_scenarios, max_steps, demos, keep)
            for make, keep in zip(makes, keep_programs, strict=True)]


def _fold_job_cost(method: Method) -> float:
    """A rough time of one fold job, so that the long ones start first (it orders the work, never its results).

    The symbolic planners solve a SAT problem per test step; a multiclass
    SVM or an MRF model without a stored fit trains (longer for a larger C);
    an MRF model from the store is loaded and rolled out; chance draws.
    """
    if isinstance(method, SymbolicMethod):
        return 4.0
    if isinstance(method, ScorerMethod):
        return 1.0 if method.store else 2.0 + method.C / 10.0
    if isinstance(method, MulticlassMethod):
        return 2.0
    return 0.1
