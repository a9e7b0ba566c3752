"""Mutation testing of one group of core modules with mutmut; writes the survivors to reports/mutation/<group>.md.

    nice -n 10 python scripts/mutation.py GROUP      # GROUP: one of GROUPS below, or `list`

mutmut copies the sources into a `mutants/` folder and rewrites every function into a trampoline that runs one
mutant at a time, so the run happens in a scratch copy of the project (`.mutation/<group>/`, git-ignored) whose
pyproject.toml names the group's modules and the tests that judge them. Every run starts afresh: mutmut would
reuse a mutant's verdict when only the tests changed. Functions with a decorator (the Numba
`@njit` kernels among them) are never mutated by mutmut; the kernels are checked bit for bit against scipy by
tests/test_ssvm.py and tests/test_mrf.py.

Score: killed (a test failed, the test process crashed, or the mutant ran past mutmut's timeout) over all mutants,
where a mutant no selected test reaches counts as a survivor; mutants listed in scripts/mutation_equivalent.toml
(each with the reason it changes nothing observable) are left out of the denominator and listed apart in the report.

mutmut names a mutant by its function and a number, and the numbers shift when the function's code changes, so each
entry also records the mutant's changed lines (`mutation`): a run whose mutant of that name changes other lines stops
and names it. `python scripts/mutation.py GROUP --fill-fingerprints` records the lines of the entries that have none
yet, from the group's last report (the diffs a person checked against the reasons), without running mutmut.
"""

from __future__ import annotations

import argparse
import datetime
import json
import re
import shutil
import subprocess
import sys
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path

from taskseq.runtime.atomic import write_text_atomic

ROOT = Path(__file__).resolve().parents[1]
EQUIVALENT = ROOT / "scripts" / "mutation_equivalent.toml"
MUTMUT = Path(sys.executable).with_name("mutmut")  # the one installed beside this Python
# mutmut's verdicts that count as killed: a failed test, a test process that crashed (a mutant that makes a compiled
# kernel write out of bounds), a run past the timeout
KILLED = ("killed", "segfault", "timeout")


@dataclass(frozen=True)
class Group:
    """Modules mutated together and the test files that judge them (fast ones: every survivor runs them all)."""

    modules: tuple[str, ...]
    tests: tuple[str, ...]
    timeout_multiplier: float = 15.0  # mutmut's: a mutant is stopped after about this many times its tests' time

    def dotted(self) -> set[str]:
        """The modules as mutmut's names begin with them (`taskseq.sim.primitives`)."""
        return {m.removesuffix(".py").replace("/", ".") for m in self.modules}


GROUPS = {
    "evaluate": Group(("taskseq/evaluate/failures.py", "taskseq/evaluate/metrics.py",
                       "taskseq/experiments/selection.py"),
                      ("tests/test_metrics_behaviour.py", "tests/test_failures.py", "tests/test_evaluate.py",
                       "tests/test_selection_behaviour.py")),
    "seeds": Group(("taskseq/report/seeds.py", "taskseq/stages/aggregate.py"),
                   ("tests/test_aggregate_behaviour.py", "tests/test_seeds.py")),
    "primitives": Group(("taskseq/sim/primitives.py", "taskseq/sim/tasks.py"),
                        ("tests/test_preconditions_behaviour.py", "tests/test_primitives.py",
                         "tests/test_tasks_behaviour.py")),
    "planner": Group(("taskseq/plan/planner.py", "taskseq/experiments/robustness.py", "taskseq/features/perception.py"),
                     ("tests/test_feedback_behaviour.py", "tests/test_robustness_behaviour.py",
                      "tests/test_feasible.py", "tests/test_noise_training.py", "tests/test_lookahead.py",
                      "tests/test_lockstep.py")),
    "features": Group(("taskseq/features/context.py", "taskseq/features/cues.py", "taskseq/learn/mrf.py",
                       "taskseq/learn/hamming.py"),
                      ("tests/test_features_behaviour.py", "tests/test_choice_cues.py", "tests/test_mrf.py",
                       "tests/test_relations.py", "tests/test_lockstep.py")),
    "learner": Group(("taskseq/learn/ssvm.py", "taskseq/learn/working_set.py", "taskseq/learn/estimator.py"),
                     ("tests/test_learner_behaviour.py", "tests/test_ssvm.py")),
    "recipes": Group(("taskseq/experiments/recipes.py",), ("tests/test_recipes_behaviour.py",)),
    "world": Group(("taskseq/sim/safety.py", "taskseq/sim/procedural.py", "taskseq/sim/demonstrator.py"),
                   ("tests/test_safety.py", "tests/test_demonstrator.py", "tests/test_procedural.py",
                    "tests/test_primitives.py")),
    "atomic": Group(("taskseq/runtime/atomic.py",), ("tests/test_atomic_behaviour.py",)),
    "serve": Group(("taskseq/serve/writer.py", "taskseq/serve/environments.py", "taskseq/serve/load.py"),
                   ("tests/test_serve_files_behaviour.py", "tests/test_serve_load_behaviour.py",
                    "tests/test_serve.py")),
    "records": Group(("taskseq/plan/records.py",), ("tests/test_records_behaviour.py",)),
    "teach": Group(("taskseq/stages/teach.py", "taskseq/experiments/teaching.py"), ("tests/test_teach_behaviour.py",)),
    # hand-built worlds only (the world-building tests would run for every mutant), and a short timeout: a mutant of
    # the walks of `descendants` and `shelved` can loop forever
    "state": Group(("taskseq/sim/state.py",), ("tests/test_state_behaviour.py",), timeout_multiplier=5.0),
    # params.yaml's values, selection.json's C, the methods' specs and the methods configured from all three, on
    # hand-written files
    "settings": Group(("taskseq/settings.py", "taskseq/selection.py", "taskseq/methods/spec.py",
                       "taskseq/methods/lineup.py"),
                      ("tests/test_settings_behaviour.py", "tests/test_settings.py")),
}


def _scratch(name: str, group: Group) -> Path:
    """The scratch copy of the working tree's sources and tests, with the group's mutmut settings."""
    scratch = ROOT / ".mutation" / name
    # mutmut re-tests a mutant only when its function changed, not when the tests did: start each run afresh
    shutil.rmtree(scratch / "mutants", ignore_errors=True)
    for folder in ("taskseq", "tests"):
        shutil.copytree(ROOT / folder, scratch / folder, dirs_exist_ok=True,
                        ignore=shutil.ignore_patterns("__pycache__"))
    tests = [t for t in group.tests if (ROOT / t).exists()]
    settings = "\n".join([
        "", "[tool.mutmut]", 'source_paths = ["taskseq"]',
        f"only_mutate = {list(group.modules)!r}",
        f"pytest_add_cli_args_test_selection = {tests!r}",
        'pytest_add_cli_args = ["-p", "no:cacheprovider", "-n", "0"]',  # mutmut follows one process
        f"timeout_multiplier = {group.timeout_multiplier!r}", "",
    ]).replace("'", '"')
    (scratch / "pyproject.toml").write_text((ROOT / "pyproject.toml").read_text() + settings)
    return scratch


def _mutmut(scratch: Path, *args: str) -> str:
    return subprocess.run([str(MUTMUT), *args], cwd=scratch, check=True, capture_output=True, text=True).stdout


@dataclass(frozen=True)
class Equivalent:
    """A mutant that changes nothing observable: why, and the lines it changes (empty until recorded)."""

    reason: str
    mutation: tuple[str, ...] = ()


class MovedMutant(Exception):
    """A recorded equivalent whose name now belongs to a mutant that changes other lines."""


HEADER = """\
# Mutants that change nothing observable, by mutmut's name, each with the reason and the lines it changes.
# scripts/mutation.py leaves them out of the score and lists them apart in reports/mutation/<group>.md, and stops
# when a name has come to mean a mutant with other changed lines (`mutation`: the diff's - and + lines, stripped).
"""


def _equivalent(path: Path = EQUIVALENT) -> dict[str, Equivalent]:
    """The recorded equivalents: a table with `reason` and `mutation`, or the reason alone (lines not yet recorded)."""
    raw = tomllib.loads(path.read_text()) if path.exists() else {}
    return {m: Equivalent(e) if isinstance(e, str) else Equivalent(e["reason"], tuple(e.get("mutation", ())))
            for m, e in raw.items()}


def write_equivalent(entries: dict[str, Equivalent], path: Path = EQUIVALENT) -> None:
    """The equivalents as TOML, one table each, in the given order (JSON strings are TOML basic strings)."""
    lines = [HEADER]
    for m, e in entries.items():
        lines += [f"[{json.dumps(m, ensure_ascii=False)}]", f"reason = {json.dumps(e.reason, ensure_ascii=False)}"]
        if e.mutation:
            lines.append("mutation = [" + ", ".join(json.dumps(x, ensure_ascii=False) for x in e.mutation) + "]")
        lines.append("")
    write_text_atomic(path, "\n".join(lines))


def fingerprint(diff: str) -> tuple[str, ...]:
    """The lines a mutant's diff removes and adds, each as its sign and its text without the indentation.

    With the function that mutmut's name carries, this says which mutant it is, whatever its number.
    """
    lines = diff.splitlines()
    body = lines[next((i for i, line in enumerate(lines) if line.startswith("@@")), 0):]  # past the file names
    return tuple(f"{line[0]} {line[1:].strip()}" for line in body if line.startswith(("-", "+")))


def check_fingerprints(equivalent: dict[str, Equivalent], diffs: dict[str, str]) -> None:
    """Raise `MovedMutant` naming every recorded equivalent whose mutant now changes other lines."""
    moved = [m for m, e in equivalent.items() if e.mutation and fingerprint(diffs[m]) != e.mutation]
    if moved:
        raise MovedMutant("\n".join(
            [f"{len(moved)} recorded equivalent mutant(s) of {EQUIVALENT.relative_to(ROOT)} now name other "
             "mutants (mutmut renumbers a function's mutants when its code changes); move each entry to the mutant "
             "whose diff its reason describes, or drop it:"]
            + [f"  {m}\n    recorded: {' | '.join(equivalent[m].mutation)}\n    now:      "
               f"{' | '.join(fingerprint(diffs[m]))}" for m in moved]))


def report_diffs(report_text: str) -> dict[str, str]:
    """The diff of each equivalent mutant listed in a report written by `report`."""
    section = report_text.split("\n## Equivalent mutants\n", 1)[-1]
    return dict(re.findall(r"^### `([^`]+)`\n\n.*?^```diff\n(.*?)\n```$", section, re.M | re.S))


def fill_fingerprints(group: str, report_file: Path, path: Path = EQUIVALENT) -> list[str]:
    """Record, for the group's equivalents that have none, the changed lines shown in its report; the names filled.

    The report is the one a person checked each equivalent's diff against its reason in; a name the report does not
    list is left as it is (it belongs to another group, or the report is older than the entry).
    """
    entries = _equivalent(path)
    diffs = report_diffs(report_file.read_text())
    modules = GROUPS[group].dotted()
    filled = [m for m, e in entries.items() if not e.mutation and _module(m) in modules and m in diffs]
    for m in filled:
        entries[m] = Equivalent(entries[m].reason, fingerprint(diffs[m]))
    write_equivalent(entries, path)
    return filled


def report(name: str, group: Group, scratch: Path, command: str, minutes: float) -> tuple[str, dict[str, int]]:
    """The Markdown report of the last run: counts, score and every surviving mutant's diff."""
    status = dict(re.findall(r"^\s*(\S+): (.+)$", _mutmut(scratch, "results", "--all", "true"), re.M))
    equivalent = {m: e for m, e in _equivalent().items() if m in status}
    counted = {m: s for m, s in status.items() if m not in equivalent}
    killed = sum(s in KILLED for s in counted.values())
    survivors = sorted((m for m, s in counted.items() if s in ("survived", "no tests")),
                       key=_natural)
    counts = {"mutants": len(status), "killed": killed, "survived": len(survivors), "equivalent": len(equivalent)}
    score = 100.0 * killed / max(len(counted), 1)
    lines = [f"# Mutation testing: {name}", "",
             f"{datetime.date.today().isoformat()}, `{command}` (mutmut {_mutmut(scratch, '--version').split()[-1]}), "
             f"{minutes:.0f} min on this machine",
             "", f"Modules: {', '.join(f'`{m}`' for m in group.modules)}.  ",
             f"Tests: {', '.join(f'`{t}`' for t in group.tests if (ROOT / t).exists())}.", "",
             "| mutants | killed | survived | equivalent | score |", "|---:|---:|---:|---:|---:|",
             f"| {len(status)} | {killed} | {len(survivors)} | {len(equivalent)} | {score:.1f}% |", "",
             "Score: killed / (mutants - equivalent); a mutant no selected test reaches counts as a survivor.", ""]
    lines += ["| module | mutants | killed | survived | equivalent | score |", "|---|---:|---:|---:|---:|---:|"]
    for module in sorted({_module(m) for m in status}):
        mine = {m: s for m, s in counted.items() if _module(m) == module}
        k = sum(s in KILLED for s in mine.values())
        n_eq = sum(_module(m) == module for m in equivalent)
        lines.append(f"| `{module}` | {len(mine) + n_eq} | {k} | {len(mine) - k} | {n_eq} | "
                     f"{100.0 * k / max(len(mine), 1):.1f}% |")
    diffs = _diffs(scratch, [*survivors, *equivalent])
    check_fingerprints(equivalent, diffs)
    lines += ["", "## Survivors", ""] + (["None.", ""] if not survivors else [])
    for m in survivors:
        lines += [f"### `{m}` ({counted[m]})", "", "```diff", diffs[m], "```", ""]
    lines += ["## Equivalent mutants", ""] + (["None.", ""] if not equivalent else [])
    for m in sorted(equivalent, key=_natural):
        lines += [f"### `{m}`", "", equivalent[m].reason, "", "```diff", diffs[m], "```", ""]
    return "\n".join(lines).rstrip() + "\n", {**counts, "score": round(score, 1)}


# every diff in one process: `mutmut show` per mutant starts Python (and reads mutmut's state) once each
_DIFFS = """
import json, sys
from mutmut.mutation.diff_apply import find_mutant, get_diff_for_mutant
names = json.load(sys.stdin)
json.dump({n: get_diff_for_mutant(n, path=find_mutant(n).path) for n in names}, sys.stdout)
"""


def _diffs(scratch: Path, mutants: list[str]) -> dict[str, str]:
    """The diff of each mutant against the original source (what `mutmut show` prints)."""
    out = subprocess.run([sys.executable, "-c", _DIFFS], cwd=scratch, input=json.dumps(mutants), check=True,
                         capture_output=True, text=True).stdout
    return {name: diff.strip() for name, diff in json.loads(out).items()}


def _module(mutant: str) -> str:
    """`taskseq.report.seeds` of `taskseq.report.seeds.x_mean_sd__mutmut_3` (methods: `.xǁClassǁname`)."""
    return re.match(r"(.+?)\.x[_ǁ]", mutant).group(1)


def _natural(name: str) -> tuple:
    return tuple(int(p) if p.isdigit() else p for p in re.split(r"(\d+)", name))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("group", choices=[*GROUPS, "list"], help="modules to mutate (`list` prints the groups)")
    parser.add_argument("--max-children", type=int, default=2, help="mutants tested at once (default 2)")
    parser.add_argument("--output", type=Path, default=None,
                        help="report file (default reports/mutation/GROUP.md)")
    parser.add_argument("--fill-fingerprints", action="store_true",
                        help="record the changed lines of the group's equivalents that have none, from the report "
                             "(--output), without running mutmut")
    args = parser.parse_args(argv)
    if args.group == "list":
        for name, g in GROUPS.items():
            print(f"{name}: {' '.join(g.modules)}")
        return 0
    group = GROUPS[args.group]
    output = args.output or ROOT / "reports" / "mutation" / f"{args.group}.md"
    if args.fill_fingerprints:
        filled = fill_fingerprints(args.group, output)
        print(f"{args.group}: recorded the changed lines of {len(filled)} equivalent mutant(s) from {output}")
        return 0
    scratch = _scratch(args.group, group)
    start = time.monotonic()
    run = subprocess.run([str(MUTMUT), "run", "--max-children", str(args.max_children)], cwd=scratch,
                         stdout=subprocess.DEVNULL)
    if run.returncode != 0:
        print(f"mutmut run failed with exit code {run.returncode} (in {scratch})", file=sys.stderr)
        return run.returncode
    command = f"nice -n 10 python scripts/mutation.py {args.group}"
    try:
        text, counts = report(args.group, group, scratch, command, (time.monotonic() - start) / 60)
    except MovedMutant as moved:
        print(moved, file=sys.stderr)
        return 1
    unrecorded = [m for m, e in _equivalent().items() if not e.mutation and _module(m) in group.dotted()]
    if unrecorded:
        print(f"{len(unrecorded)} equivalent(s) of {args.group} have no recorded lines, so a renumbering would go "
              f"unnoticed: check their diffs in the report, then `python scripts/mutation.py {args.group} "
              "--fill-fingerprints`", file=sys.stderr)
    write_text_atomic(output, text)
    print(f"{args.group}: {counts}; survivors in {output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
