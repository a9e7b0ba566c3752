"""The people's-demonstrations experiment: every method over environment folds, written as reports.

For each fold the MRF rows choose C inside the training environments (the
fold's training environments split once more by number, the best next-step
accuracy, action and arguments, on the inner held-out ones), then refit on all
training environments. Every figure is a mean over held-out sequences per
fold, reported as mean ± sd over folds, with a bootstrap interval that
resamples held-out environments and a paired sign-flip test of the best MRF
row against each baseline on the same sequences.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np
import yaml

from ..runtime.atomic import atomic_directory
from ..runtime.jobs import Shared, run_jobs
from .baselines import Chance, MostFrequent, MulticlassSVM, NearestDemonstration
from .evaluate import (
    Executor,
    Run,
    closed_loop,
    derive_goals,
    env_number,
    environment_folds,
    next_steps,
    people_runs,
    split,
    states_of,
)
from .features import Vocabulary
from .figures import results_png
from .ingest import counts_without_names
from .ingest import summarize as import_summary
from .lookahead import LOOKAHEAD, GoalLookahead, planner
from .methods import DomainScorer, VeilMethod
from .metrics import bootstrap_by_group, paired_sign_flip
from .persist import TrainedModel
from .recordings import record_run
from .release import Release, read_release
from .replay import Replay, replay_release
from .symbolic import SymbolicPlanner

BASELINES = ("chance", "most_frequent", "nearest_demonstration", "multiclass_svm", "symbolic_planner")
# each MRF row: its feature set, whether an object's row says its category, and how C is chosen inside the
# training environments: by next-step accuracy, or by the share of the goal closed-loop runs reach. A row with a
# `base` is that row's fitted model run another way (`lookahead.GoalLookahead`): it shares the base's C and fit.
MRF_ROWS = {"mrf_attributes": {"features": "full", "categories": False, "select": "next_step"},
            "mrf_categories": {"features": "full", "categories": True, "select": "next_step"},
            "mrf_categories_goal": {"features": "full", "categories": True, "select": "goal"},
            "mrf_categories_lookahead": {"base": "mrf_categories"}}
LABELS = {"chance": "chance", "most_frequent": "most frequent next step",
          "nearest_demonstration": "nearest demonstration, replayed", "multiclass_svm": "multiclass SVM",
          "symbolic_planner": "symbolic planner toward the derived goal",
          "mrf_attributes": "ours - full (attributes)", "mrf_categories": "ours - full + categories",
          "mrf_categories_goal": "ours - full + categories, C by goal reached",
          "mrf_categories_lookahead": "ours - full + categories + goal lookahead",
          "people": "people (leave one out): a ceiling"}


@dataclass(frozen=True)
class Settings:
    """The experiment's settings (params.yaml, section `veil`)."""

    folds: int = 4
    C_grid: tuple[float, ...] = (0.1, 1.0, 10.0)
    tol: float = 1e-3
    max_steps: int = 40
    methods: tuple[str, ...] = BASELINES + tuple(MRF_ROWS)
    policies: tuple[str, ...] = ("plain", "feasible")
    resamples: int = 2000
    seed: int = 0
    recordings: int = 2  # Rerun recordings per fold of the first MRF row's runs (feasible policy), when asked for
    lookahead_widths: tuple[int, ...] = (3,)  # the goal lookahead's widths, one chosen per fold inside its training

    def __post_init__(self) -> None:
        unknown = set(self.methods) - set(BASELINES) - set(MRF_ROWS)
        if unknown:
            raise ValueError(f"veil.methods: unknown {sorted(unknown)} (known: {list(BASELINES) + list(MRF_ROWS)})")
        if self.folds < 2 or self.max_steps < 1 or not self.C_grid or min(self.C_grid) <= 0:
            raise ValueError("veil: folds >= 2, max_steps >= 1 and a C_grid of positive values are required")
        if not self.lookahead_widths or min(self.lookahead_widths) < 1:
            raise ValueError(f"veil.lookahead_widths: one or more whole numbers >= 1, "
                             f"got {list(self.lookahead_widths)}")


@dataclass
class FoldResult:
    fold: int
    held_out: list[int]
    C: dict[str, float] = field(default_factory=dict)
    width: dict[str, int] = field(default_factory=dict)  # of each goal-lookahead row
    next_step: dict[str, dict[str, float]] = field(default_factory=dict)
    closed_loop: dict[str, dict[str, float]] = field(default_factory=dict)
    # facts in each objective's derived goal, objectives in name order (0: none); sizes, not the facts, since the
    # facts name the release's categories and objectives, which the reports (committed) never hold
    goal_facts: list[int] = field(default_factory=list)
    seconds: dict[str, float] = field(default_factory=dict)


def read_settings(path: Path | str) -> Settings:
    """The `veil` section of a params file (missing file or section: the defaults); unknown keys are refused."""
    path = Path(path)
    section = (yaml.safe_load(path.read_text()) or {}).get("veil", {}) if path.is_file() else {}
    known = {f.name for f in fields(Settings)}
    if unknown := set(section) - known:
        raise ValueError(f"{path}: veil: unknown settings {sorted(unknown)} (known: {sorted(known)})")
    return Settings(**{k: tuple(v) if isinstance(v, list) else v for k, v in section.items()})


def make_method(name: str, release: Release, objectives: Sequence[str], settings: Settings,
                C: float | None = None) -> VeilMethod:
    if name == "chance":
        return Chance(settings.seed)
    if name == "most_frequent":
        return MostFrequent()
    if name == "nearest_demonstration":
        return NearestDemonstration()
    if name == "multiclass_svm":
        return MulticlassSVM()
    if name == "symbolic_planner":
        return SymbolicPlanner(Executor(release))
    row = MRF_ROWS[name]
    if "base" in row:
        raise ValueError(f"{name} runs another row's fitted model: `fold_job` builds it around that model")
    vocabulary = Vocabulary.of(release.catalog, objectives, row["categories"])
    return DomainScorer(name, vocabulary, row["features"], C=C if C is not None else settings.C_grid[0],
                        tol=settings.tol)


def both_accuracy(method: VeilMethod, test: Sequence[Replay]) -> float:
    rows = next_steps(method, test)
    return float(np.mean([r.both for r in rows])) if rows else 0.0


def inner_split(train: Sequence[Replay], settings: Settings, choosing: str) -> tuple[list[Replay], list[Replay]]:
    """The training environments split once more by number: (inner training, inner held-out), where a setting
    (`choosing`, for the error) is chosen."""
    numbers = {env_number(r.point.env_id) for r in train}
    if len(numbers) < 2:
        raise ValueError(f"choosing {choosing} needs training environments of two numbers or more, "
                         f"got {sorted(numbers)}: give one value or fewer folds")
    return split(train, environment_folds(train, min(settings.folds, len(numbers)))[0])


def _best(scores: Sequence[float]) -> int:
    """The best score's index; no figure (no goal, no run) counts as the worst; ties: the first."""
    return int(np.argmax(np.nan_to_num(np.array(scores, dtype=float), nan=-1.0)))


@dataclass
class Fits:
    """The MRF fits of one job, shared by the rows that would make the same fit: rows of one feature set and row
    content differ only in how they choose C or run the model, so each (C, sequences) is fitted once. Fits are
    deterministic, so a shared fit is the very model each row would have fitted alone."""

    release: Release
    objectives: Sequence[str]
    settings: Settings
    _fits: dict[tuple, VeilMethod] = field(default_factory=dict)

    def __call__(self, name: str, C: float, replays: Sequence[Replay]) -> VeilMethod:
        key = self._key(name, C, replays)
        if key not in self._fits:
            self._fits[key] = make_method(name, self.release, self.objectives, self.settings, C).fit(replays)
        return self._fits[key]

    def add(self, name: str, C: float, replays: Sequence[Replay], weights: np.ndarray) -> None:
        """The weights of a fit made elsewhere (another process) of row `name` at C on `replays`."""
        method = make_method(name, self.release, self.objectives, self.settings, C)
        assert isinstance(method, DomainScorer)
        method.w_ = weights
        self._fits[self._key(name, C, replays)] = method

    @staticmethod
    def _key(name: str, C: float, replays: Sequence[Replay]) -> tuple:
        row = MRF_ROWS[name]
        return row["features"], row["categories"], C, tuple(r.point.seq_id for r in replays)


def choose_C(name: str, release: Release, objectives: Sequence[str], train: Sequence[Replay],
             settings: Settings, fits: Fits | None = None) -> float:
    """C of an MRF row from its training environments alone: the grid's best on an inner held-out number, by the
    row's criterion (next-step accuracy, or the goal share of feasible closed-loop runs there, whose goals come
    from the inner training sequences); ties go to the smallest C, the most regularised. The inner fits come from
    `fits` when given (shared with the job's other rows)."""
    grid = sorted(settings.C_grid)
    if len(grid) == 1:
        return grid[0]
    fit = fits or Fits(release, objectives, settings)
    fit_on, check_on = inner_split(train, settings, f"C among {grid}")
    fitted = [fit(name, C, fit_on) for C in grid]
    if MRF_ROWS[name]["select"] == "goal":
        goals, executor = derive_goals(fit_on), Executor(release)
        scores = [_mean(closed_loop(m, executor, check_on, goals, "feasible", settings.max_steps), "goal_share")
                  for m in fitted]
    else:
        scores = [both_accuracy(m, check_on) for m in fitted]
    return grid[_best(scores)]


def choose_width(base: str, C: float, release: Release, objectives: Sequence[str], train: Sequence[Replay],
                 settings: Settings, fits: Fits | None = None) -> int:
    """The goal lookahead's width from its training environments alone: the width of `lookahead_widths` whose
    feasible runs on the inner held-out number reach the largest share of the goal (goals derived from the inner
    training sequences), around the base row fitted there at C (from `fits` when given: choosing C fitted it);
    ties go to the smallest width, the one closest to the model's own ranking."""
    widths = sorted(settings.lookahead_widths)
    if len(widths) == 1:
        return widths[0]
    fit_on, check_on = inner_split(train, settings, f"the lookahead's width among {widths}")
    model = (fits or Fits(release, objectives, settings))(base, C, fit_on)
    executor, goals = Executor(release), derive_goals(fit_on)  # one executor: the widths meet the same states
    return widths[_best([_goal_share(model, w, executor, fit_on, check_on, goals, settings) for w in widths])]


def _goal_share(model: VeilMethod, width: int, executor: Executor, fit_on: Sequence[Replay],
                check_on: Sequence[Replay], goals: dict, settings: Settings) -> float:
    """The share of the goal the goal lookahead at `width` around `model` reaches in feasible runs on `check_on`."""
    lookahead = GoalLookahead("inner", model, executor, width=width).with_goals(fit_on)
    return _mean(closed_loop(lookahead, executor, check_on, goals, "feasible", settings.max_steps), "goal_share")


def _mean(runs: Sequence[Run], attr: str) -> float:
    values = [getattr(r, attr) for r in runs if getattr(r, attr) is not None]
    return float(np.mean(values)) if values else float("nan")


def fit_groups(methods: Sequence[str]) -> list[tuple[str, ...]]:
    """`methods` in jobs: the MRF rows that make the same fits (one feature set and row content; a row with a
    `base` as its base) run in one job, which fits each (C, sequences) once (`Fits`); a row with a `base` comes
    after the rows it may share with."""

    def identity(name: str) -> str | tuple:
        row = MRF_ROWS.get(name)
        if row is None:
            return name
        row = MRF_ROWS[row["base"]] if "base" in row else row
        return (row["features"], row["categories"])

    groups: dict[str | tuple, list[str]] = {}
    for name in methods:
        groups.setdefault(identity(name), []).append(name)
    return [tuple(sorted(g, key=lambda name: "base" in MRF_ROWS.get(name, {}))) for g in groups.values()]


@dataclass(frozen=True)
class MethodOnFold:
    """What one method did on one fold."""

    fold: int
    name: str
    C: float | None  # of an MRF row, chosen inside the fold's training environments
    width: int | None  # of a goal-lookahead row, likewise
    next_step: dict[str, float]  # verb, args, both (NaN for a method that predicts no next step)
    runs: dict[str, list[Run]]  # by policy
    seconds: float


def fold_job(k: int, held_out: frozenset[int], names: tuple[str, ...], data: tuple[Release, list[Replay]],
             settings: Settings, recordings_dir: Path | None = None) -> list[MethodOnFold]:
    """`names` on one fold, sharing their MRF fits (`Fits`); a row with a `base` runs the base's model. The first
    MRF row of `settings.methods` also records its first `settings.recordings` runs into
    `recordings_dir`."""
    release, replays = data
    objectives = sorted({r.point.objective for r in replays})
    train, test = split(replays, held_out)
    goals = derive_goals(train)
    executor = Executor(release)
    fits = Fits(release, objectives, settings)
    chosen_C: dict[str, float] = {}
    out = []
    for name in names:
        start = time.perf_counter()
        base = MRF_ROWS.get(name, {}).get("base")
        row = base or name
        C: float | None = None
        width: int | None = None
        if name in MRF_ROWS:
            if row not in chosen_C:
                chosen_C[row] = choose_C(row, release, objectives, train, settings, fits)
            C = chosen_C[row]
        if base is not None and C is not None:
            width = choose_width(base, C, release, objectives, train, settings, fits)
            method: VeilMethod = GoalLookahead(name, fits(base, C, train), executor, width=width).with_goals(train)
        elif C is not None:
            method = fits(name, C, train)
        else:
            method = make_method(name, release, objectives, settings).fit(train)
        if getattr(method, "predicts_next_step", True):
            rows = next_steps(method, test)
            figures = {part: float(np.mean([getattr(r, part) for r in rows])) for part in ("verb", "args", "both")}
        else:
            figures = {part: float("nan") for part in ("verb", "args", "both")}
        runs = {policy: closed_loop(method, executor, test, goals, policy, settings.max_steps)
                for policy in settings.policies}
        recorded = next((m for m in settings.methods if m in MRF_ROWS), None)
        if recordings_dir is not None and name == recorded and settings.recordings:
            policy = settings.policies[-1]
            people = {r.point.seq_id: r for r in test}
            for run in runs[policy][: settings.recordings]:
                replay = people[run.seq_id]
                record_run(Path(recordings_dir) / f"fold{k}_{run.seq_id}.rrd", f"veil-{name}-{run.seq_id}",
                           states_of(executor, replay.initial, run.steps), run.steps, run.objective, replay.kept,
                           f"{name}, {policy}: goal reached {100 * (run.goal_share or 0):.0f}%")
        out.append(MethodOnFold(k, name, C, width, figures, runs, time.perf_counter() - start))
    return out


def run_experiment(release_root: Path | str, settings: Settings, n_jobs: int = 1,
                   recordings_dir: Path | None = None) -> dict:
    """Every method on every fold, `n_jobs` at a time (the MRF rows first: they cost the most); returns the
    report (per fold, per method, with tests and intervals). The jobs are pure functions of their arguments,
    so the report is the same bytes whatever `n_jobs`."""
    release = read_release(release_root)
    replays = replay_release(release)
    folds = environment_folds(replays, settings.folds)
    data = Shared((release, replays))
    jobs = [(fold_job, (k, held_out, names, data, settings, recordings_dir)) for k, held_out in enumerate(folds)
            for names in fit_groups(settings.methods)]
    done = run_jobs(jobs, n_jobs, cost=[10.0 * len(args[2]) if args[2][0] in MRF_ROWS else 1.0 for _, args in jobs])
    results = [FoldResult(k, sorted(held_out)) for k, held_out in enumerate(folds)]
    per_sequence: dict[str, list[Run]] = {f"{name}/{policy}": [] for name in settings.methods
                                          for policy in settings.policies}
    for m in (method for job in done for method in job):
        fr = results[m.fold]
        if m.C is not None:
            fr.C[m.name] = m.C
        if m.width is not None:
            fr.width[m.name] = m.width
        fr.next_step[m.name] = m.next_step
        fr.seconds[m.name] = m.seconds
        for policy, policy_runs in m.runs.items():
            fr.closed_loop[f"{m.name}/{policy}"] = _figures(policy_runs)
            per_sequence[f"{m.name}/{policy}"].extend(policy_runs)
    people: list[Run] = []
    for k, held_out in enumerate(folds):
        train, test = split(replays, held_out)
        goals = derive_goals(train)
        results[k].goal_facts = goal_sizes(goals, replays)
        own = people_runs(test, goals)
        people.extend(own)
        results[k].closed_loop["people"] = _figures(own)
    report = summarize(results, per_sequence, people, settings)
    report["noisy_steps"] = counts_without_names(import_summary(release, replays))
    return report


def summarize(results: Sequence[FoldResult], per_sequence: dict[str, list[Run]], people: Sequence[Run],
              settings: Settings, methods: Sequence[str] | None = None) -> dict:
    methods = tuple(methods or settings.methods)

    def over_folds(get: Callable[[FoldResult], float]) -> dict[str, float | None | list]:
        """Mean and sd over the folds that have the figure (none: no person to compare with, no goal)."""
        values = np.array([get(fr) for fr in results], dtype=float)
        known = values[~np.isnan(values)]
        return {"mean": float(known.mean()) if known.size else None, "sd": float(known.std()) if known.size else None,
                "folds": [None if np.isnan(v) else float(v) for v in values]}

    next_step = {name: {part: over_folds(lambda fr, n=name, p=part: fr.next_step[n][p])
                        for part in ("verb", "args", "both")} for name in methods}
    loop_keys = list(per_sequence) + ["people"]
    closed = {key: {figure: over_folds(lambda fr, k=key, f=figure: fr.closed_loop[k][f])
                    for figure in ("goal_share", "edit_distance", "exact", "stopped", "refused_per_run")}
              for key in loop_keys}
    intervals = {}
    for key, runs in list(per_sequence.items()) + [("people", list(people))]:
        scored = [r for r in runs if r.goal_share is not None]
        if scored:
            intervals[key] = asdict(bootstrap_by_group([r.goal_share for r in scored], [r.env_id for r in scored],
                                                       settings.resamples, settings.seed))
    mrf_keys = [k for k in per_sequence if k.split("/")[0] in MRF_ROWS]
    baseline_keys = [k for k in per_sequence if k.split("/")[0] in BASELINES]
    tests = {}
    if mrf_keys and baseline_keys:
        best = max(mrf_keys, key=lambda k: closed[k]["goal_share"]["mean"] or 0.0)
        by_seq = {k: {r.seq_id: r.goal_share for r in per_sequence[k] if r.goal_share is not None}
                  for k in per_sequence}
        for other in baseline_keys:
            common = sorted(set(by_seq[best]) & set(by_seq[other]))
            if not common:
                continue
            tests[other] = {"best_mrf": best, "difference": float(np.mean([by_seq[best][s] - by_seq[other][s]
                                                                          for s in common])),
                            "p": paired_sign_flip([by_seq[best][s] for s in common],
                                                  [by_seq[other][s] for s in common], seed=settings.seed)}
    folds = [{k: v for k, v in asdict(fr).items() if k != "seconds"} for fr in results]
    return {"settings": asdict(settings), "folds": folds, "next_step": next_step, "closed_loop": closed,
            "goal_share_intervals": intervals, "paired_tests": tests,
            "seconds": {name: [fr.seconds[name] for fr in results] for name in methods}}


def write_reports(report: dict, output: Path | str) -> None:
    """`report.json`, `tables.md` and `results.png` (`figures.results_png`) into `output`, replaced whole. The
    seconds each method took are left out (the command records them in MLflow): they differ from run to run while
    everything written is the same bytes."""
    figures = {k: v for k, v in report.items() if k != "seconds"}
    with atomic_directory(output) as tmp:
        (tmp / "report.json").write_text(json.dumps(figures, indent=2, sort_keys=True) + "\n")
        (tmp / "tables.md").write_text(tables(figures))
        results_png(figures, LABELS, tmp / "results.png")


def goal_sizes(goals: dict[str, frozenset], replays: Sequence[Replay]) -> list[int]:
    """Facts in the goal of each objective of `replays` (name order), 0 where none is derived."""
    return [len(goals.get(o, ())) for o in sorted({r.point.objective for r in replays})]


def _pm(figure: dict, scale: float = 100.0) -> str:
    if figure["mean"] is None:
        return "-"
    return f"{scale * figure['mean']:.1f} ± {scale * figure['sd']:.1f}"


def _three(value: float | None) -> str:
    return "-" if value is None else f"{value:.3f}"


NOISY_STEPS_TITLE = ("Sequences replayed in the domain (`docs/veil.md`, the rule for people's noisy steps: a step "
                     "the domain refuses is skipped and counted by its reason, no sequence is dropped):")


def noisy_steps_table(counts: dict) -> str:
    """The import's counts (`ingest.counts_without_names`) as a Markdown table."""
    status = counts["sequences_by_status"]
    share = 100 * counts["steps_kept"] / counts["steps"] if counts["steps"] else 0.0
    rows = [("sequences", f"{counts['sequences']:,}"),
            ("imported (at least one kept step)", f"{counts['sequences_imported']:,}"),
            *((f"status: {name}", f"{n:,}") for name, n in status.items()),
            ("steps", f"{counts['steps']:,}"), ("kept", f"{counts['steps_kept']:,} ({share:.1f} %)"),
            ("skipped", f"{counts['steps_skipped']:,}"),
            *((f"skipped: {reason}", f"{n:,}") for reason, n in counts["skipped_by_reason"].items())]
    return "\n".join(["| | count |", "|---|---:|", *(f"| {name} | {n} |" for name, n in rows)])


def tables(report: dict) -> str:
    s = report["settings"]
    title = (f"a trained model ({report['model']['name']}, C = {report['model']['C']:g}) on every sequence of a folder"
             if "model" in report else f"{s['folds']} folds of held-out environments")
    lines = [f"# People's demonstrations (VEIL-500): {title}", "",
             "Next step with the people's history, % (mean ± sd over folds):", "",
             "| method | verb | arguments | both |", "|---|---:|---:|---:|"]
    for name, parts in report["next_step"].items():
        lines.append(f"| {LABELS[name]} | {_pm(parts['verb'])} | {_pm(parts['args'])} | {_pm(parts['both'])} |")
    lines += ["", f"Closed loop (at most {s['max_steps']} steps): goal reached %, mean ± sd over folds "
              "[95% interval over environments]; edit distance to the nearest person (0 same, 1 nothing shared); "
              "exact match %:", "",
              "| method | policy | goal reached | interval | edit distance | exact | stops |",
              "|---|---|---:|---:|---:|---:|---:|"]
    for key, figs in report["closed_loop"].items():
        name, _, policy = key.partition("/")
        iv = report["goal_share_intervals"].get(key)
        interval = f"[{100 * iv['low']:.1f}, {100 * iv['high']:.1f}]" if iv else "-"
        lines.append(f"| {LABELS[name]} | {policy or '-'} | {_pm(figs['goal_share'])} | "
                     f"{interval} | {_three(figs['edit_distance']['mean'])} | "
                     f"{_pm(figs['exact']).split(' ±')[0]} | {_pm(figs['stopped']).split(' ±')[0]} |")
    chosen = [name for name in report["next_step"] if any(name in fold.get("C", {}) for fold in report["folds"])]
    if chosen and "model" not in report:
        lines += ["", "Settings each fold chose inside its training environments (C; the lookahead's width):", "",
                  "| method | " + " | ".join(f"fold {fold['fold'] + 1}" for fold in report["folds"]) + " |",
                  "|---|" + "---:|" * len(report["folds"])]
        for name in chosen:
            cells = [f"{fold['C'][name]:g}" + (f"; {fold['width'][name]}" if name in fold.get("width", {}) else "")
                     for fold in report["folds"]]
            lines.append(f"| {LABELS[name]} | " + " | ".join(cells) + " |")
    if report["folds"] and "goal_facts" in report["folds"][0]:
        lines += ["", "Derived goals per fold (objectives with a goal, of all; facts in each goal, objectives in name "
                  "order): an objective with none is not scored for goal reached.", "",
                  "| fold | objectives with a goal | facts per goal |", "|---|---:|---|"]
        for fold in report["folds"]:
            sizes = fold["goal_facts"]
            lines.append(f"| {fold['fold'] + 1} | {sum(n > 0 for n in sizes)} of {len(sizes)} | "
                         f"{', '.join(map(str, sizes))} |")
    if "noisy_steps" in report:
        lines += ["", NOISY_STEPS_TITLE, "", noisy_steps_table(report["noisy_steps"])]
    if report["paired_tests"]:
        lines += ["", "Paired sign-flip tests on goal reached, per held-out sequence:", "",
                  "| best MRF row | against | difference (points) | p |", "|---|---|---:|---:|"]
        for other, t in report["paired_tests"].items():
            lines.append(f"| {t['best_mrf']} | {other} | {100 * t['difference']:+.1f} | {t['p']:.4f} |")
    return "\n".join(lines) + "\n"


# one model for use: trained on a whole release, evaluated on any folder of the same format ------------------------
def inner_fit(name: str, C: float, data: tuple[Release, list[Replay]], held_out: frozenset[int],
              settings: Settings) -> tuple[float, np.ndarray]:
    """An MRF row at C fitted without the `held_out` numbers: its next-step accuracy on them, and its weights."""
    release, replays = data
    fit_on, check_on = split(replays, held_out)
    objectives = sorted({r.point.objective for r in replays})
    method = make_method(name, release, objectives, settings, C).fit(fit_on)
    assert isinstance(method, DomainScorer)
    return both_accuracy(method, check_on), method.w_


def choose_model(release: Release, replays: Sequence[Replay], settings: Settings, n_jobs: int = 1
                 ) -> tuple[str, float, Fits]:
    """The MRF row and C of `settings` with the best next-step accuracy on an inner held-out environment number
    of `replays`: the choice a model for use is trained with, made on its training data alone; with the winner's
    inner fit in a `Fits` (what `choose_width` reads next, on the same split). The candidates are fitted `n_jobs`
    at a time; the choice does not depend on it."""
    fitted_rows = [m for m in MRF_ROWS if "base" not in MRF_ROWS[m]]  # a model for use is one MRF's weights
    rows = [m for m in settings.methods if m in fitted_rows] or fitted_rows
    objectives = sorted({r.point.objective for r in replays})
    fits = Fits(release, objectives, settings)
    numbers = {env_number(r.point.env_id) for r in replays}
    if len(numbers) < 2:
        return rows[0], settings.C_grid[0], fits
    inner = environment_folds(replays, min(settings.folds, len(numbers)))[0]
    # a row that makes the same fits as an earlier one would score the same and lose the tie: left out
    distinct = list({(MRF_ROWS[m]["features"], MRF_ROWS[m]["categories"]): m for m in reversed(rows)}.values())
    candidates = [(name, C) for name in rows if name in distinct for C in settings.C_grid]
    data = Shared((release, list(replays)))
    # a larger C takes more iterations: those go first, so that no long fit starts last while a worker idles
    done = run_jobs([(inner_fit, (name, C, data, inner, settings)) for name, C in candidates], n_jobs,
                    cost=[C for _, C in candidates])
    best = max(range(len(candidates)), key=lambda i: (done[i][0], -i))  # ties: the earlier row, then the smaller C
    name, C = candidates[best]
    fits.add(name, C, split(replays, inner)[0], done[best][1])
    return name, C, fits


def full_fit(name: str, C: float, data: tuple[Release, list[Replay]], settings: Settings) -> np.ndarray:
    """The weights of MRF row `name` at C fitted on every sequence of `data`."""
    release, replays = data
    objectives = sorted({r.point.objective for r in replays})
    return make_method(name, release, objectives, settings, C).fit(replays).w_


def inner_goal_share(name: str, C: float, data: tuple[Release, list[Replay]], weights: np.ndarray, width: int,
                     settings: Settings) -> float:
    """`choose_width`'s score of one width, as a job of its own: the goal lookahead at `width` around row `name`'s
    inner fit at C (`weights`), on the inner split of `data` that `choose_width` makes."""
    release, replays = data
    objectives = sorted({r.point.objective for r in replays})
    fit_on, check_on = inner_split(replays, settings, "the lookahead's width")
    fits = Fits(release, objectives, settings)
    fits.add(name, C, fit_on, weights)
    return _goal_share(fits(name, C, fit_on), width, Executor(release), fit_on, check_on, derive_goals(fit_on),
                       settings)


def train_model(release_root: Path | str, settings: Settings, n_jobs: int = 1) -> TrainedModel:
    """The chosen MRF row fitted on every sequence of a release, with the goals of its objectives, its environments
    and the goal lookahead's width, chosen around that row's inner fit on the same inner split (`choose_width`).
    The final fit and each width's runs are separate jobs, `n_jobs` at a time: none reads another's result, and
    each gives what `choose_width` and the fit give in one process."""
    release = read_release(release_root)
    replays = replay_release(release)
    name, C, fits = choose_model(release, replays, settings, n_jobs)
    objectives = sorted({r.point.objective for r in replays})
    method = make_method(name, release, objectives, settings, C)
    assert isinstance(method, DomainScorer)
    widths = sorted(settings.lookahead_widths)
    if len(widths) == 1:
        method.w_ = full_fit(name, C, (release, list(replays)), settings)
        width = widths[0]
    else:
        fit_on = inner_split(replays, settings, f"the lookahead's width among {widths}")[0]
        inner = fits(name, C, fit_on)
        assert isinstance(inner, DomainScorer)
        data = Shared((release, list(replays)))
        done = run_jobs([(full_fit, (name, C, data, settings))]
                        + [(inner_goal_share, (name, C, data, inner.w_, w, settings)) for w in widths], n_jobs)
        method.w_, width = done[0], widths[_best(done[1:])]
    return TrainedModel(method, derive_goals(replays), sorted({r.point.env_id for r in replays}), width)


def evaluate_model(model: TrainedModel, release_root: Path | str, settings: Settings,
                   progress: Callable[[Iterable], Iterable] = iter) -> dict:
    """A trained model on every sequence of a folder: the experiment's figures, the folder as one fold; closed
    loop under each of the settings' policies and the goal lookahead (`lookahead`, at the model's width)."""
    method, goals = model.method, model.goals
    release = read_release(release_root)
    replays = replay_release(release)
    known = set(method.vocabulary.objectives)
    if unknown := sorted({r.point.objective for r in replays} - known):
        raise ValueError(f"{release_root}: objectives the model was not trained for: {unknown} (it knows "
                         f"{sorted(known)})")
    executor = Executor(release)
    fr = FoldResult(0, sorted({env_number(r.point.env_id) for r in replays}))
    fr.goal_facts = goal_sizes(goals, replays)
    rows = next_steps(method, replays)
    fr.next_step[method.name] = {part: float(np.mean([getattr(r, part) for r in rows]))
                                 for part in ("verb", "args", "both")}
    per_sequence: dict[str, list[Run]] = {}
    for name in (*settings.policies, LOOKAHEAD):
        runner, policy = planner(method, goals, executor, name, model.lookahead_width)
        runs = closed_loop(runner, executor, replays, goals, policy, settings.max_steps, progress)
        per_sequence[f"{method.name}/{name}"] = runs
        fr.closed_loop[f"{method.name}/{name}"] = _figures(runs)
    own = people_runs(replays, goals)
    fr.closed_loop["people"] = _figures(own)
    fr.seconds[method.name] = 0.0
    report = summarize([fr], per_sequence, own, settings, methods=(method.name,))
    report["noisy_steps"] = counts_without_names(import_summary(release, replays))
    report["model"] = {"name": method.name, "C": method.C, "lookahead_width": model.lookahead_width,
                       "evaluated_on": str(release_root)}
    return report


def _figures(runs: Sequence[Run]) -> dict[str, float]:
    return {"goal_share": _mean(runs, "goal_share"), "edit_distance": _mean(runs, "edit_distance"),
            "exact": _mean(runs, "exact"), "stopped": _mean(runs, "stopped"),
            "refused_per_run": _mean(runs, "refused")}
