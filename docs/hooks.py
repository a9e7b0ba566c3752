"""Build-time hooks of the documentation site: every figure and listing that a file already holds.

- The Results page is the pipeline's own `reports/summary.md`, followed by the Markdown tables
  the `aggregate` and `crossval` stages write, each included as the file stands, and links to
  the report files themselves. The DVC-cached per-program tables (the names DVC lists in the
  `.gitignore` beside them) are left out: they are large, and a fresh clone does not have them
  until `dvc repro` has run, while every other report is committed.
- The CLI reference page is the help of `taskseq.cli.build_parser()`, every subcommand's.
- A page line `<!-- generated: NAME -->` is replaced by the table `GENERATED[NAME]` makes:
  the timings of `reports/bench.json` and `reports/scaling.json`, the mutation scores of
  `reports/mutation/`, the development world's ranking in `reports/selection.json`, the `teach`
  stage's tables of `reports/teach/`, the VEIL pipeline's timing of `reports/veil_timing.json`,
  Table I's means and per-seed figures (`reports/crossval_means.json`, `crossval_seeds.csv`), the
  noise and feedback tables (`reports/noise.csv`, `feedback.csv`), the failure analysis's
  tables (`reports/failures.md`, `failures.csv`), the
  development world's checks of the scripts (`multiclass_tol.json`, `revisits.json`, `goal_stop.json`,
  `drawn_rooms_choice.json`, `teach_weight.json`, `teach_room_prior.json`, `teach_adapt.json`), and the
  package's layout from its modules' docstrings.

Nothing is copied by hand, so a build after `dvc repro` (or `taskseq bench`, `taskseq
scaling`, `scripts/mutation.py`) shows that run's numbers.
"""

from __future__ import annotations

import ast
import csv
import json
import os
import re
from pathlib import Path

from mkdocs.config.defaults import MkDocsConfig
from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parents[1]
REPORTS = ROOT / "reports"
PACKAGE = ROOT / "taskseq"
CLI_PAGE = "reference/cli.md"
PARAMS_PAGE = "reference/params.md"
CHANGELOG_PAGE = "changelog.md"
SITE = "results"  # the report files are published under it as they lie in reports/, so summary.md's
# relative links to its figures hold on the page
LINKED = {".csv", ".json", ".tex", ".png"}  # report files a reader may download


def _dvc_cached(folder: Path) -> set[str]:
    """The outputs DVC caches in this folder: the names it lists in the folder's .gitignore."""
    ignore = folder / ".gitignore"
    if not ignore.is_file():
        return set()
    return {line.strip().lstrip("/") for line in ignore.read_text().splitlines() if line.strip()}


def _report_files() -> list[Path]:
    """Every committed report file a reader may download, in a stable order (per-world ones last)."""
    out = []
    for path in sorted(REPORTS.rglob("*")):
        rel = path.relative_to(REPORTS)
        if (not path.is_file() or path.suffix not in LINKED or rel.parts[0] == "recordings"
                or path.name in _dvc_cached(path.parent)):
            continue
        out.append(rel)
    return sorted(out, key=lambda rel: (len(rel.parts) > 1, _world_order(rel), str(rel)))


def _world_order(rel: Path) -> int:
    """reports/worlds/S/...: sort by the seed as a number (seed 10 after seed 7)."""
    return int(rel.parts[1]) if len(rel.parts) > 2 and rel.parts[0] == "worlds" and rel.parts[1].isdigit() else -1


def _worlds() -> list[str]:
    folder = REPORTS / "worlds"
    seeds = [p.name for p in folder.iterdir() if p.is_dir() and p.name.isdigit()] if folder.is_dir() else []
    return sorted(seeds, key=int)


def _table(name: str) -> str:
    """A Markdown report as it is, or a line saying the pipeline has not written it."""
    path = REPORTS / name
    if not path.is_file():
        return f"`reports/{name}` has not been written yet: run `dvc repro`.\n"
    return path.read_text()


def _shipped_comparisons(name: str, where: str) -> str:
    """The rows of a comparisons table (`taskseq stats`) that pair a method with the shipped planner, under the
    table's own header and test paragraph."""
    path = REPORTS / name
    if not path.is_file():
        return _table(name)
    lines = path.read_text().splitlines()
    header = next(i for i, line in enumerate(lines) if line.startswith("| method |"))
    rows = [line for line in lines[header + 2:] if "(the shipped planner)" in line]
    if not rows:
        return ""
    return (f"Paired with the shipped planner, program by program, {where} (every comparison: "
            f"`reports/{name}`). " + " ".join(lines[2:header]).strip() + "\n\n"
            + "\n".join([*lines[header:header + 2], *rows]) + "\n")


def results_page(files: list[Path]) -> str:
    """The Markdown of the Results page."""
    # the site's navigation is hidden on this page: its tables are wide (Table I per primitive has 19 columns)
    parts = ["---\nhide:\n  - navigation\n---\n\n" + _table("summary.md").rstrip("\n")]
    parts.append("## Table I per primitive\n\n`reports/table1.md` (also `table1.csv` and `table1.tex`): "
                 "mean ± sd over world seeds, the best of each column in bold.\n\n" + _table("table1.md"))
    parts.append("## Why programs fail, per method and task\n\n`reports/failures.md`.\n\n" + _table("failures.md"))
    parts.append("## Rooms never seen in training\n\nTable I with whole rooms held out of training: the "
                 "paper-shaped rooms (`reports/scenes/paper/table1.md`), then rooms drawn by the world seed "
                 "(`reports/scenes/drawn/table1.md`; how they are drawn: "
                 "[the benchmark world](../world.md#drawn-rooms)), models of the paper-shaped rooms run in drawn ones "
                 "(`reports/scenes/transfer.md`) and why programs fail in drawn rooms "
                 "(`reports/scenes/drawn/failures.md`).\n\n" + "\n".join(
                     _table(name) for name in ("scenes/paper/table1.md", "scenes/drawn/table1.md",
                                               "scenes/transfer.md", "scenes/drawn/failures.md"))
                 + "\n" + _shipped_comparisons("scenes/drawn/comparisons.md", "in drawn rooms held out")
                 + "\n" + _shipped_comparisons("scenes/transfer/comparisons.md",
                                                "trained on the paper-shaped rooms and run in drawn ones"))
    parts.append("## People's demonstrations (VEIL-500)\n\nThe methods on sequences people demonstrated, with whole "
                 "environments held out (`reports/veil/tables.md`; [People's demonstrations](../veil.md)).\n\n"
                 + veil_results(reports=""))
    for seed in _worlds():
        world = f"worlds/{seed}"
        section = [f"## World seed {seed}", f"Table I of this world alone (`reports/{world}/table1.md`)."]
        if (REPORTS / world / "table1.md").is_file():
            section.append(_table(f"{world}/table1.md"))
        if (REPORTS / world / "confusion.png").is_file():
            section.append(f"![Confusion matrix of world seed {seed}]({world}/confusion.png)")
        parts.append("\n\n".join(section))
    listing = [f"- [`reports/{rel.as_posix()}`]({rel.as_posix()})" for rel in files]
    parts.append("## Report files\n\nEvery committed file of `reports/`, as the last `dvc repro` wrote it "
                 "(the per-program tables are DVC-cached and stay in the repository).\n\n" + "\n".join(listing))
    return "\n\n".join(parts) + "\n"


def on_files(files: Files, config: MkDocsConfig) -> Files:
    """Add the Results page and the report files it shows and links, and the CLI reference page."""
    report_files = _report_files()
    files.append(File.generated(config, f"{SITE}/index.md", content=results_page(report_files)))
    files.append(File.generated(config, CLI_PAGE, content=cli_page()))
    files.append(File.generated(config, PARAMS_PAGE, content=params_page()))
    files.append(File.generated(config, CHANGELOG_PAGE, content=(ROOT / "CHANGELOG.md").read_text()))
    for rel in report_files:
        files.append(File.generated(config, f"{SITE}/{rel.as_posix()}", abs_src_path=str(REPORTS / rel)))
    return files


# ---------------------------------------------------------------------------------------------
# Tables generated into hand-written pages

MARKER = re.compile(r"^<!-- generated: ([\w-]+) -->$", re.M)


def on_page_markdown(markdown: str, page, config: MkDocsConfig, files: Files) -> str:
    """Replace each `<!-- generated: NAME -->` line by the table it names (an unknown name fails the build)."""
    def replace(match: re.Match) -> str:
        name = match.group(1)
        if name not in GENERATED:
            raise ValueError(f"{page.file.src_uri}: no generated table named {name!r} (docs/hooks.py)")
        return GENERATED[name]().rstrip("\n")
    return MARKER.sub(replace, markdown)


def _json(name: str) -> dict | None:
    path = REPORTS / name
    return json.loads(path.read_text()) if path.is_file() else None


def _csv_rows(name: str) -> list[dict[str, str]] | None:
    path = REPORTS / name
    if not path.is_file():
        return None
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))


def _missing(name: str, command: str) -> str:
    return f"`reports/{name}` has not been written yet: run `{command}`.\n"


def _rows(header: list[str], align: str, rows: list[list]) -> str:
    """A Markdown table; `align` has one letter per column, l or r."""
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" if a == "l" else "---:" for a in align) + "|"]
    out += ["| " + " | ".join(str(cell) for cell in row) + " |" for row in rows]
    return "\n".join(out) + "\n"


def _machine(report: dict) -> str:
    m = report.get("machine", {})
    return f"{m.get('cpus', '?')} CPUs, {m.get('processor', '?')}, Python {m.get('python', '?')}"


BENCH_COMMAND = "taskseq bench --output reports/bench.json"


def bench_training() -> str:
    """The learner's fits of `reports/bench.json`."""
    bench = _json("bench.json")
    if bench is None:
        return _missing("bench.json", BENCH_COMMAND)
    train = bench["train"]
    rows = []
    for run in train["runs"]:
        excess = f"{run['excess']:.1e}" if "excess" in run else "-"
        rows.append([run["features"], f"{run['tol']:.0e}", "n" if run["n_slacks"] == 0 else run["n_slacks"],
                     f"{run['seconds']:.2f}", run["iterations"], f"{100 * run['oracle_share']:.0f}%",
                     f"{100 * run['qp_share']:.0f}%", f"{run['primal_objective']:.3f}", excess])
    ref = train["reference"]
    return (f"`{BENCH_COMMAND}`: {train['steps']} steps, C = {train['C']:g}, on {_machine(bench)}; "
            f"peak resident memory {train['peak_rss_mib']:.0f} MiB.\n\n"
            + _rows(["model", "gap", "slacks", "seconds", "iterations", "oracle", "QP", "objective", "excess"],
                    "lrrrrrrrr", rows)
            + f"\nReference: the full model to a gap of {ref['tol']:.0e} in {ref['seconds']:.1f} s; certified "
            f"lower bound on the optimum {train['lower_bound']:.3f}. Peak memory of the features stage: "
            f"{bench['features_peak_mib']:.1f} MiB.\n")


def bench_latency() -> str:
    """Per-step inference and planner step of `reports/bench.json`."""
    bench = _json("bench.json")
    if bench is None:
        return _missing("bench.json", BENCH_COMMAND)
    rows = [[n, f"{v['candidates']:,}", f"{v['inference_ms']:.3f}", f"{v['step_ms']:.3f}"]
            for n, v in sorted(bench["latency"].items(), key=lambda kv: int(kv[0]))]
    return (f"`{BENCH_COMMAND}`, on {_machine(bench)}:\n\n"
            + _rows(["objects", "candidates", "inference ms", "planner step ms"], "rrrr", rows))


SCALING_COMMAND = ("taskseq scaling --rooms 13 39 130 --selection reports/selection.json "
                   "--plot docs/img/scaling.png --output reports/scaling.json")
STAGE_ORDER = ("generate", "ingest", "features", "fold_models", "crossval", "noise", "feedback")


def _load(size: dict) -> str:
    load = size.get("load_average", {})
    if not load:
        return "-"
    return f"{load['before'][0]:.1f} → {load['after'][0]:.1f}"


def scaling_fit() -> str:
    """The timed fit and inference per world size of `reports/scaling.json`."""
    scaling = _json("scaling.json")
    if scaling is None:
        return _missing("scaling.json", SCALING_COMMAND)
    s = scaling["settings"]
    rows = []
    for size in scaling["sizes"]:
        t, inf = size.get("train"), size.get("inference")
        if not t or not inf:
            continue
        rows.append([size["rooms"], f"{size['scenarios']:,}", f"{size['steps']:,}", f"{t['seconds']:.2f}",
                     f"{t['cpu_seconds']:.2f}", t["iterations"], f"{t['cpu_ms_per_step']:.2f}",
                     f"{100 * t['qp_share']:.0f}%", f"{t['peak_rss_mib']:.0f} ({t['loaded_rss_mib']:.0f})",
                     f"{inf['median_ms']:.3f}", _load(size)])
    return (f"`{SCALING_COMMAND}`: world seed {s['world_seed']}, C = {s['C']:g} (selection: {s['selection']}), "
            f"gap {s['tol']:g}, {s['n_jobs']} processes per parallel stage, on {_machine(scaling)}.\n\n"
            + _rows(["rooms", "scenarios", "steps", "fit, wall s", "fit, CPU s", "iterations", "CPU ms a step",
                     "QP share", "peak MiB (after reading the features)", "inference ms a step",
                     "load average (1 min)"], "rrrrrrrrrrl", rows))


def scaling_stages() -> str:
    """Each stage's wall and CPU time and peak memory per world size of `reports/scaling.json`."""
    scaling = _json("scaling.json")
    if scaling is None:
        return _missing("scaling.json", SCALING_COMMAND)
    stages = [name for name in STAGE_ORDER if any(name in size.get("stages", {}) for size in scaling["sizes"])]
    rows = []
    for size in scaling["sizes"]:
        timed = size.get("stages", {})
        cells = [f"{timed[n]['seconds']:.1f} ({timed[n]['cpu_seconds']:.1f}) · {timed[n]['peak_rss_mib']:.0f}"
                 if n in timed else "-" for n in stages]
        rows.append([size["rooms"], *cells, f"{sum(v['cpu_seconds'] for v in timed.values()):.0f}"])
    return ("Each stage: wall seconds (CPU seconds) · peak MiB of its largest process.\n\n"
            + _rows(["rooms", *stages, "all, CPU s"], "r" * (len(stages) + 2), rows))


def scaling_growth() -> str:
    """Log-log slopes against steps of `reports/scaling.json` (`growth`)."""
    scaling = _json("scaling.json")
    if scaling is None:
        return _missing("scaling.json", SCALING_COMMAND)
    growth = scaling["growth"]
    names = ["train_cpu_seconds", "train_seconds", "train_peak_rss_mib", "inference_ms"]
    names += [f"stage.{n}.cpu" for n in STAGE_ORDER] + [f"stage.{n}" for n in STAGE_ORDER]
    rows = []
    for name in names:
        if name not in growth:
            continue
        g = growth[name]
        between = " · ".join(f"{b['slope']:.2f} ({b['steps'][0]:,} to {b['steps'][1]:,})" for b in g["between"])
        rows.append([f"`{name}`", f"{g['overall']:.2f}", between])
    return _rows(["figure", "slope, smallest to largest", "between neighbouring sizes (steps)"], "lrl", rows)


MUTATION = REPORTS / "mutation"
_MUTATION_HEAD = re.compile(r"^(?P<date>\d{4}-\d\d-\d\d), `(?P<command>[^`]+)`"
                            r"(?: \((?P<tool>[^)]*)\))?,? ?(?P<rest>.*)$")
_MODULE_ROW = re.compile(r"^\| `(taskseq\.[\w.]+)` \| (\d+) \| (\d+) \| (\d+) \| (\d+) \| ([\d.]+%) \|$")
_TOTAL_ROW = re.compile(r"^\| (\d+) \| (\d+) \| (\d+) \| (\d+) \| ([\d.]+%) \|$")


def mutation_report(path: Path) -> dict:
    """A group's report of `scripts/mutation.py`: its run line, its total and its modules' rows."""
    lines = path.read_text().splitlines()
    head = next((m for m in map(_MUTATION_HEAD.match, lines) if m), None)
    total = next((m.groups() for m in map(_TOTAL_ROW.match, lines) if m), None)
    modules = [m.groups() for m in map(_MODULE_ROW.match, lines) if m]
    return {"group": path.stem, "head": head.groupdict() if head else None, "total": total, "modules": modules}


def mutation_scores() -> str:
    """Every group's mutants, per module, from `reports/mutation/GROUP.md`."""
    reports = [mutation_report(p) for p in sorted(MUTATION.glob("*.md"))] if MUTATION.is_dir() else []
    if not reports:
        return "`reports/mutation/` holds no report yet: run `python scripts/mutation.py GROUP`.\n"
    rows = []
    for report in reports:
        group = f"`{report['group']}`"
        rows += [[group, f"`{name}`", *counts] for name, *counts in report["modules"]]
        if report["total"]:
            *counts, score = report["total"]
            rows.append([group, "**all**", *counts, f"**{score}**"])
    runs = []
    for report in reports:
        head = report["head"] or {}
        minutes = re.search(r"(\d+(?:\.\d+)?) min", head.get("rest", ""))
        runs.append([f"`{report['group']}`", f"`reports/mutation/{report['group']}.md`", head.get("date", "-"),
                     minutes.group(1) if minutes else "-", head.get("tool") or "-"])
    return (_rows(["group", "module", "mutants", "killed", "survived", "equivalent", "score"], "llrrrrr", rows)
            + "\n" + _rows(["group", "report", "run on", "minutes", "tool"], "llrrl", runs))


def selection_ranking() -> str:
    """The development world's ranking of `reports/selection.json`, each method at its own C."""
    selection = _json("selection.json")
    if selection is None:
        return _missing("selection.json", "dvc repro select")
    from taskseq.methods import method_labels

    labels = method_labels()
    rows = []
    for entry in selection["methods"]:
        name = entry["method"]
        tried = " ".join(f"{c['C']:g}" for c in selection["settings"].get(name, {}).get("candidates", []))
        capped = " (capped)" if selection["settings"].get(name, {}).get("capped") else ""
        rows.append([labels.get(name, name), f"{entry['C']:g}{capped}", tried or "-",
                     f"{entry['sequence_arg']:.1f}", f"{entry['success']:.1f}"])
    return (f"`reports/selection.json` (development world seed {selection['dev_seed']}), ranked; the first is "
            f"the shipped method (`{selection['method']}`).\n\n"
            + _rows(["method", "C", "C tried", "sequence arg", "success"], "lrlrr", rows))


# the one-line summary of a subpackage whose __init__.py has no docstring
SUBPACKAGES = {
    "sim": "the simulated world: objects and attributes, state, primitives, tasks, safety rules, the catalog, "
           "drawn rooms, the demonstrator",
    "features": "what the model sees of a step, the choice cues, perception noise, the feature files",
    "learn": "the structural SVM, its working-set QP, the unrolled MRF, the estimator, model files",
    "plan": "the step-by-step planner; `symbolic/`: PDDL problems, the SAT planner, the symbolic policy",
    "report": "Table I, figures over world seeds, statistics, long CSV files, figures, summary.md",
    "track": "MLflow runs of the stages and their writer process, Rerun recordings",
}


def _summary(path: Path) -> str:
    """The first sentence of a module's docstring."""
    doc = ast.get_docstring(ast.parse(path.read_text())) or ""
    first = " ".join(doc.split("\n\n")[0].split())
    return first.replace("|", "\\|")


def package_layout() -> str:
    """Every module of `taskseq/`, with the first sentence of its docstring, read from the source."""
    top = [[f"`taskseq/{p.name}`", _summary(p)] for p in sorted(PACKAGE.glob("*.py"))]
    parts = ["### Top-level modules\n\n" + _rows(["module", "what it is"], "ll", top)]
    for package in sorted(p for p in PACKAGE.iterdir() if (p / "__init__.py").is_file()):
        summary = _summary(package / "__init__.py") or SUBPACKAGES.get(package.name, "")
        modules = sorted(m for m in package.rglob("*.py") if m.name != "__init__.py" and "__pycache__" not in m.parts)
        rows = [[f"`{m.relative_to(package).as_posix()}`", _summary(m)] for m in modules]
        parts.append(f"### `taskseq/{package.name}/`\n\n{summary}\n\n"
                     + (_rows(["module", "what it is"], "ll", rows) if rows else ""))
    return "\n".join(parts)


def veil_results(reports: str = f"{SITE}/") -> str:
    """The people's-demonstrations tables (`reports/veil/tables.md` without its title) and figure, or how to make
    them; `reports` is where the published report files are from the page (the results page is among them)."""
    path = REPORTS / "veil" / "tables.md"
    if not path.is_file():
        return ("`reports/veil/tables.md` has not been written yet: put the release at `data/veil500` and run "
                "`dvc repro veil/dvc.yaml`.\n")
    text = path.read_text()
    figure = (f"\n![Next step and goal reached per method]({reports}veil/results.png)\n"
              if (REPORTS / "veil" / "results.png").is_file() else "")
    return (text.split("\n", 1)[1].lstrip("\n") if text.startswith("# ") else text) + figure + \
        "\nWritten by `dvc repro veil/dvc.yaml` (stage `evaluate`: `taskseq veil evaluate`).\n"


VEIL_TIMING_COMMAND = "python scripts/veil_timing.py --output reports/veil_timing.json"


def veil_timing() -> str:
    """Where the VEIL pipeline's time goes (`reports/veil_timing.json`, from its last MLflow runs)."""
    timing = _json("veil_timing.json")
    if timing is None:
        return _missing("veil_timing.json", f"dvc repro veil/dvc.yaml` then `{VEIL_TIMING_COMMAND}")
    order = [n for n in ("import", "evaluate", "train") if n in timing["stages"]]  # the file's keys are sorted
    stages = [[name, f"{timing['stages'][name]:.0f}"] for name in order]
    methods = sorted(timing["evaluate_methods"].items(), key=lambda kv: -kv[1])
    return (f"`{timing['command']}`, then `{VEIL_TIMING_COMMAND}`, on {_machine(timing)}: "
            f"{timing['total']:.0f} s ({timing['total'] / 60:.1f} min) in the stages' own runs.\n\n"
            + _rows(["stage", "wall s"], "lr", stages)
            + "\nThe evaluation's methods, seconds summed over their folds (the folds run in parallel, so the sum "
            "exceeds the stage's wall time):\n\n"
            + _rows(["method", "seconds"], "lr", [[name, f"{seconds:.0f}"] for name, seconds in methods]))


DRAWN_ROOMS_COMMAND = "python scripts/drawn_rooms.py --rooms 13 26 52 104 --output reports/drawn_rooms_choice.json"


def drawn_rooms_choice() -> str:
    """How many drawn rooms the `drawn_rooms` method trains on, as `scripts/drawn_rooms.py` ranked them on the
    development world's drawn rooms held out (`reports/drawn_rooms_choice.json`)."""
    choice = _json("drawn_rooms_choice.json")
    if choice is None:
        return _missing("drawn_rooms_choice.json", DRAWN_ROOMS_COMMAND)
    rows = [[f"**{r['rooms']} (chosen)**" if r["rooms"] == choice["chosen"] else r["rooms"],
             f"{r['sequence_arg']:.1f}", f"{r['success']:.1f}"] for r in choice["ranked"]]
    rows += [["none (`choice_lookahead`)", f"{r['sequence_arg']:.1f}", f"{r['success']:.1f}"]
             for r in choice["without"]]
    return (f"`{DRAWN_ROOMS_COMMAND}`: the drawn development world {choice['dev_seed']}, 6 folds holding out whole "
            f"rooms, C = {choice['C']:g} (the choice-cue planner's), training rooms drawn with seed "
            f"{choice['rooms_seed']}; % of programs.\n\n"
            + _rows(["drawn rooms added", "sequence arg", "success"], "rrr", rows))


TEACH_COMMAND = "dvc repro teach"


def teach_results() -> str:
    """The `teach` stage's table (`reports/teach/teach.md` without its title) and each world's counts of held-out
    tasks and programs as demonstrated per k (`reports/teach/teach_seeds.csv`)."""
    path = REPORTS / "teach" / "teach.md"
    seeds = REPORTS / "teach" / "teach_seeds.csv"
    if not path.is_file() or not seeds.is_file():
        return _missing("teach/teach.md", TEACH_COMMAND)
    text = path.read_text()
    text = text.split("\n", 1)[1].lstrip("\n") if text.startswith("# ") else text
    rows = _csv_rows("teach/teach_seeds.csv")
    ks = sorted({int(r["k"]) for r in rows})
    worlds = sorted({int(r["world_seed"]) for r in rows})
    got = {(int(r["world_seed"]), int(r["k"])): r for r in rows}
    table = _rows(["world seed", "held-out tasks", *(f"seq arg %, k = {k}" for k in ks)], "r" * (len(ks) + 2),
                  [[w, got[w, ks[0]]["held_out_tasks"], *(got[w, k]["sequence_arg"] for k in ks)] for w in worlds])
    return (text.rstrip("\n") + "\n\nPer world (`reports/teach/teach_seeds.csv`), the held-out tasks and the share "
            "of programs as demonstrated for each k:\n\n" + table)


FAILURES_COMMAND = "dvc repro aggregate"
# the methods the failure analysis of docs/evaluation.md discusses, by their names in reports/failures.csv
FAILURE_METHODS = ("symb_plan_svm", "symb_plan_manual", "full", "relations")


def _shipped_method() -> str | None:
    selection = _json("selection.json")
    return None if selection is None else selection.get("method")


def failure_kinds() -> str:
    """The rows of `reports/failures.md`'s first table (each method's programs by kind) that the failure analysis
    discusses: the symbolic planners, the full model, relations and the shipped method."""
    path = REPORTS / "failures.md"
    rows = _csv_rows("failures.csv")
    if not path.is_file() or rows is None:
        return _missing("failures.md", FAILURES_COMMAND)
    from taskseq.methods import method_labels

    labels = method_labels(sorted({r["method"] for r in rows}))
    wanted = [labels[m] for m in (*FAILURE_METHODS, _shipped_method()) if m in labels]
    lines = path.read_text().split("\n\n")[1].splitlines()  # the first table: header, rule, a row per method
    keep = lines[:2] + [line for label in wanted for line in lines[2:] if line.startswith(f"| {label} |")]
    return "`reports/failures.md` (`" + FAILURES_COMMAND + "`), these methods' rows:\n\n" + "\n".join(keep) + "\n"


def exact_by_task() -> str:
    """Exact programs per task and world seed of the full model and of relations (`reports/failures.csv`)."""
    rows = _csv_rows("failures.csv")
    if rows is None:
        return _missing("failures.csv", FAILURES_COMMAND)
    seeds = sorted({int(r["world_seed"]) for r in rows})
    count: dict[tuple, int] = {}
    for r in rows:
        key = (int(r["world_seed"]), r["method"], r["task"])
        count[key] = count.get(key, 0) + int(r["programs"])
        if r["kind"] == "exact":
            count[(*key, "exact")] = int(r["programs"])
    tasks = sorted({r["task"] for r in rows if r["task"] != "all"})
    table = [[f"{task} ({count[seeds[0], 'full', task]})",
              *(f"{count.get((s, 'full', task, 'exact'), 0)} / {count.get((s, 'relations', task, 'exact'), 0)}"
                for s in seeds)] for task in tasks]
    return _rows(["task (programs)", *(f"seed {s}" for s in seeds)], "l" + "r" * len(seeds), table)


TEACH_WEIGHT_COMMAND = (
    "python scripts/teach_weight.py --weights 1 3 10 30 100 300 --dev-seeds 100 101 102 103 104 "
    "--output reports/teach_weight.json")


def teach_weight() -> str:
    """How much a taught step counts, as `scripts/teach_weight.py` ranked the weights on drawn development worlds."""
    choice = _json("teach_weight.json")
    if choice is None:
        return _missing("teach_weight.json", TEACH_WEIGHT_COMMAND)
    seeds, most = [str(seed) for seed in choice["dev_seeds"]], max(choice["k"])

    def removed(r: dict) -> list[str]:
        cells = []
        for seed in [*seeds, None]:
            before, after = (sum(r["misses"][s][i] for s in ([seed] if seed else seeds)) for i in (0, 1))
            share = f" ({100 * (before - after) / before:.0f}%)" if before else ""
            cells.append(f"{before} → {after}{share}")
        return cells

    rows = [[f"**{r['weight']} (chosen)**" if r["weight"] == choice["chosen"] else r["weight"],
             f"{r['sequence_arg']:.1f}", f"{r['success']:.1f}", *removed(r)] for r in choice["ranked"]]
    rows.append(["nothing taught (k = 0)", f"{choice['untaught']['sequence_arg']:.1f}",
                 f"{choice['untaught']['success']:.1f}", *[""] * (len(seeds) + 1)])
    return (f"`{TEACH_WEIGHT_COMMAND}`: the drawn development worlds {', '.join(seeds)}, rooms "
            f"{', '.join(choice['environments'])} held out, k = {', '.join(map(str, choice['k']))}, the shipped "
            f"planner (`{choice['method']}`, C = {choice['C']:g}); % of the programs of every k above 0 and every "
            f"world together; then the misses of sequence arg at k = 0 and at k = {most} (the share removed) per "
            "world and in all.\n\n"
            + _rows(["weight", "sequence arg", "success", *(f"misses, world {s}" for s in seeds), "misses, all"],
                    "rrr" + "r" * (len(seeds) + 1), rows))


def _against_untouched(report: dict, setting: str) -> list[tuple[dict, str, str, str]]:
    """Each row of a report of `scripts/teach_weight.py`'s `room_variants` (the room prior's, the room
    correction's), with what its planner was refitted with, its setting (`none` where 0: the planner untouched)
    and its change in misses against the untouched planner of the same refit."""
    untouched = {r["refit_k"]: r["misses"] for r in report["rows"] if r[setting] == 0}
    out = []
    for r in report["rows"]:
        refit = ("nothing (k = 0)" if r["refit_k"] == 0
                 else f"the first {r['refit_k']} tasks, each step {report['weight']} times")
        none = r[setting] == 0
        out.append((r, refit, "none" if none else f"{r[setting]:g}",
                    "" if none else f"{r['misses'] - untouched[r['refit_k']]:+d}"))
    return out


TEACH_ROOM_PRIOR_COMMAND = (
    "python scripts/teach_room_prior.py --betas 0.25 0.5 1 2 --dev-seeds 100 101 102 103 104 "
    "--output reports/teach_room_prior.json")


def teach_room_prior() -> str:
    """The room prior's misses and successes, as `scripts/teach_room_prior.py` measured them on development draws."""
    prior = _json("teach_room_prior.json")
    if prior is None:
        return _missing("teach_room_prior.json", TEACH_ROOM_PRIOR_COMMAND)
    rows = [[refit, setting, r["misses"], change, r["successes"], r["programs"]]
            for r, refit, setting, change in _against_untouched(prior, "beta")]
    return (f"`{TEACH_ROOM_PRIOR_COMMAND}`: the drawn development worlds "
            f"{', '.join(map(str, prior['dev_seeds']))} pooled, rooms {', '.join(prior['environments'])} held out, "
            f"the first {prior['taught']} tasks of each taught, the shipped planner (`{prior['method']}`, "
            f"C = {prior['C']:g}); misses of sequence arg and successes over the other tasks of those rooms, the "
            "change in misses against the same planner without the prior.\n\n"
            + _rows(["refitted with", "prior (beta)", "misses", "change", "successes", "programs"], "llrrrr", rows))


TEACH_ADAPT_COMMAND = (
    "python scripts/teach_adapt.py --Cs 0.1 0.3 1 --dev-seeds 100 101 102 103 104 --output reports/teach_adapt.json")


def teach_adapt() -> str:
    """The room correction's misses and successes, as `scripts/teach_adapt.py` measured them on development draws."""
    adapt = _json("teach_adapt.json")
    if adapt is None:
        return _missing("teach_adapt.json", TEACH_ADAPT_COMMAND)
    seeds = [str(s) for s in adapt["dev_seeds"]]
    rows = [[refit, setting, *(r["misses_by_world"][s] for s in seeds), r["misses"], change, r["successes"],
             r["programs"]] for r, refit, setting, change in _against_untouched(adapt, "C")]
    return (f"`{TEACH_ADAPT_COMMAND}`: the drawn development worlds {', '.join(seeds)}, rooms "
            f"{', '.join(adapt['environments'])} held out, the first {adapt['taught']} tasks of each taught, the "
            f"shipped planner (`{adapt['method']}`, C = {adapt['C']:g}); misses of sequence arg per world and in all, "
            "the change in misses against the same planner without the correction, and successes, over the other "
            "tasks of those rooms.\n\n"
            + _rows(["refitted with", "correction C", *(f"misses, world {s}" for s in seeds), "misses, all",
                     "change", "successes", "programs"], "ll" + "r" * (len(seeds) + 4), rows))


MULTICLASS_TOL_COMMAND = "python scripts/multiclass_tol.py --world data/dev --output reports/multiclass_tol.json"


def multiclass_tol() -> str:
    """The multiclass baseline's tolerances as `scripts/multiclass_tol.py` compared them on the development world."""
    report = _json("multiclass_tol.json")
    if report is None:
        return _missing("multiclass_tol.json", MULTICLASS_TOL_COMMAND)
    rows = [[f"**{r['tol']:g} (chosen)**" if r["tol"] == report["chosen"] else f"{r['tol']:g}",
             f"{r['cpu_seconds']:.2f}", f"{r['avg_prim']:.2f}", f"{r['differ_from_tightest']} of {report['steps']}"]
            for r in report["rows"]]
    return (f"`{MULTICLASS_TOL_COMMAND}`: the folds of `{report['world']}`, C = {report['C']:g}; the fits' CPU "
            "seconds vary from run to run, the predictions do not.\n\n"
            + _rows(["tolerance", "fits' CPU-s", "avg prim", f"held-out steps that differ from "
                     f"{report['rows'][0]['tol']:g}"], "rrrr", rows))


REVISITS_COMMAND = "python scripts/revisits.py --rooms 52 --output reports/revisits.json"


def revisits() -> str:
    """The lookahead's programs with and without the rule against going back to a world, on the development world
    (`scripts/revisits.py`), and every program that differs."""
    report = _json("revisits.json")
    if report is None:
        return _missing("revisits.json", REVISITS_COMMAND)
    rows = [[f"`{r['method']}`", r["rule"], f"{r['sequence_arg']:.1f}", f"{r['success']:.1f}", r["step_cap"],
             r["unsafe"]] for r in report["table"]]
    changed = "".join(f"- `{c['method']}` on `{c['scenario']}`: without the rule {c['without']['status']}, "
                      f"{'a success' if c['without']['success'] else 'no success'}; with it {c['with']['status']}, "
                      f"{'a success' if c['with']['success'] else 'no success'}.\n" for c in report["changed"])
    return (f"`{REVISITS_COMMAND}`: the development world {report['dev_seed']} drawn with {report['rooms']} rooms, "
            f"{report['folds']} folds holding out whole rooms, {report['table'][0]['programs']} programs per "
            "method.\n\n"
            + _rows(["method", "rule", "sequence arg", "success", "programs at the step cap", "unsafe programs"],
                    "llrrrr", rows)
            + (f"\nThe programs that differ:\n\n{changed}" if changed else "\nNo program differs.\n"))


GOAL_STOP_COMMAND = "python scripts/goal_stop.py --output reports/goal_stop.json"


def goal_stop() -> str:
    """The shipped planner's programs with and without the lookahead's stop at the goal, on the development world's
    teaching protocol (`scripts/goal_stop.py`)."""
    report = _json("goal_stop.json")
    if report is None:
        return _missing("goal_stop.json", GOAL_STOP_COMMAND)
    rows = [[r["rule"], r["k"], f"{r['sequence_arg']:.1f}", f"{r['success']:.1f}", r["misses"],
             f"{r['misses_removed']:.0f}%"] for r in report["table"]]
    return (f"`{GOAL_STOP_COMMAND}`: the drawn development world {report['dev_seed']}, rooms "
            f"{', '.join(report['environments'])} held out, k tasks taught in each (each taught step counted "
            f"{report['weight']} times), the shipped planner (`{report['method']}`, C = {report['C']:g}) on the "
            f"{report['table'][0]['programs']} other tasks there; each k's model fitted once and run with the rule "
            f"and without; {len(report['changed'])} programs differ.\n\n"
            + _rows(["rule", "k", "sequence arg", "success", "misses",
                     f"k = {report['table'][0]['against_k']}'s misses removed"], "lrrrrr", rows))


TABLE1_COLUMNS = ("average_prim", "average_arg", "sequence_prim", "sequence_arg", "goal_reached", "success")


def table1_means() -> str:
    """Table I's columns, mean ± sd over the world seeds (`reports/crossval_means.json`), each method added beyond
    the paper in italics, and the paper's figures for its three rows."""
    means = _json("crossval_means.json")
    if means is None:
        return _missing("crossval_means.json", "dvc repro aggregate")
    from taskseq.methods import PAPER_METHODS, method_labels
    from taskseq.report.paper import TABLE1

    rows = []
    for name, label in method_labels().items():
        if name not in means:
            continue
        m = means[name]
        cells = [f"{m[c]:.1f} ± {m.get(c + '_sd', 0.0):.1f}" if c in m else "-" for c in TABLE1_COLUMNS]
        rows.append([label if name in PAPER_METHODS else f"*{label} (added)*", *cells])
    paper = [TABLE1[label] for label in ("symb-plan-svm", "symb-plan-manual", "ours - full")]
    rows.append(["*paper: symb-plan-svm / -manual / ours - full*",
                 *(f"*{' / '.join(f'{p[k]:.1f}' for p in paper)}*" for k in range(4)), "", ""])
    return _rows(["method", "average prim", "average arg", "sequence prim", "sequence arg", "goal reached",
                  "success"], "lrrrrrr", rows)


def _seeds_table(name: str, command: str) -> str:
    """Sequence arg and success of every method per world seed, from a `*_seeds.csv` report (`reports/<name>`)."""
    path = REPORTS / name
    if not path.is_file():
        return _missing(name, command)
    from taskseq.methods import method_labels

    rows = _csv_rows(name)
    seeds = sorted({int(r["world_seed"]) for r in rows})
    got = {(r["method"], int(r["world_seed"])): r for r in rows}

    def per_seed(name: str, figure: str) -> str:
        values = [got[name, s][figure] if (name, s) in got else "" for s in seeds]
        return " / ".join(f"{float(v):.1f}" for v in values) if all(values) else "-"

    table = [[label, per_seed(name, "sequence_arg"), per_seed(name, "success")]
             for name, label in method_labels().items() if (name, seeds[0]) in got]
    seeds_text = " / ".join(map(str, seeds))
    return _rows(["method", f"sequence arg ({seeds_text})", f"success ({seeds_text})"], "lrr", table)


def table1_seeds() -> str:
    """Table I's scenario folds per world seed (`reports/crossval_seeds.csv`)."""
    return _seeds_table("crossval_seeds.csv", "dvc repro aggregate")


def drawn_seeds() -> str:
    """The drawn worlds with whole rooms held out, per world seed (`reports/scenes/drawn/crossval_seeds.csv`)."""
    return _seeds_table("scenes/drawn/crossval_seeds.csv", "dvc repro scenes")


def transfer_seeds() -> str:
    """Trained on the paper-shaped world, run in the drawn one of its seed (`reports/scenes/transfer_seeds.csv`)."""
    return _seeds_table("scenes/transfer_seeds.csv", "dvc repro scenes")


def _table_rows(name: str, keep=lambda row: True) -> str:
    """The Markdown table of a report (`reports/<name>`), its header and the rows `keep` accepts."""
    path = REPORTS / name
    if not path.is_file():
        return _missing(name, "dvc repro stats")
    lines = [line for line in path.read_text().splitlines() if line.startswith("|")]
    return "\n".join(lines[:2] + [row for row in lines[2:] if keep(row)]) + "\n"


def table1_ci() -> str:
    """Table I with its 95% intervals (`reports/table1_ci.md`), as `taskseq stats` wrote it."""
    return _table_rows("table1_ci.md")


def comparisons_excerpt() -> str:
    """The paired comparisons of the relations row and the choice-cue lookahead row against the paper's model and
    the best baseline (`reports/comparisons.md`)."""
    rows = ("| ours + relations |", "| ours + relations + choice cues + safety lookahead |")
    return _table_rows("comparisons.md", lambda row: row.startswith(rows) and "(the shipped planner)" not in row)


def _mean_sd(row: dict[str, str]) -> str:
    return f"{float(row['sequence_arg']):.1f} ± {float(row['sequence_arg_sd']):.1f}"


def noise_table() -> str:
    """Sequence arg under attribute noise, a row per method and a column per flip rate (`reports/noise.csv`,
    stage `aggregate`), with the paper's figures."""
    from taskseq.methods import method_labels
    from taskseq.report.paper import NOISE

    rows = _csv_rows("noise.csv")
    if rows is None:
        return _missing("noise.csv", "dvc repro")
    rates = list(dict.fromkeys(r["rate"] for r in rows))
    labels = method_labels()
    by_method: dict[str, dict[str, str]] = {}
    for r in rows:
        by_method.setdefault(r["method"], {})[r["rate"]] = _mean_sd(r)
    body = [[labels.get(m, m), *(cells.get(rate, "") for rate in rates)] for m, cells in by_method.items()]
    body.append(["paper", *(f"{NOISE[float(rate)]:.1f}" if float(rate) in NOISE else "" for rate in rates)])
    return _rows(["r", *(f"{float(rate):g}" for rate in rates)], "l" + "r" * len(rates), body)


def feedback_table() -> str:
    """Sequence arg with an observer's feedback, a row per method and top k, a column per number of steps with
    feedback (`reports/feedback.csv`, stage `aggregate`), with the paper's figures."""
    from taskseq.methods import method_labels
    from taskseq.report.paper import FEEDBACK

    rows = _csv_rows("feedback.csv")
    if rows is None:
        return _missing("feedback.csv", "dvc repro")
    steps = list(dict.fromkeys(r["n"] for r in rows))
    labels = method_labels()
    by_row: dict[tuple[str, str], dict[str, str]] = {}
    for r in rows:
        by_row.setdefault((r["method"], r["k"]), {})[r["n"]] = _mean_sd(r)
    body = [[f"{labels.get(m, m)}, top {k}", *(cells.get(n, "") for n in steps)] for (m, k), cells in by_row.items()]
    ks = sorted({int(k) for _, k in by_row})
    body.append([f"paper, top {' / top '.join(map(str, ks))}",
                 *(" / ".join(f"{FEEDBACK[(k, n)]:.1f}" for k in ks) if all((k, n) in FEEDBACK for k in ks)
                   else "" for n in steps)])
    return _rows(["sequence arg", *(f"n = {n}" if i == 0 else n for i, n in enumerate(steps))],
                 "l" + "r" * len(steps), body)


GENERATED = {
    "goal-stop": goal_stop,
    "noise-table": noise_table,
    "feedback-table": feedback_table,
    "teach-results": teach_results,
    "teach-weight": teach_weight,
    "teach-room-prior": teach_room_prior,
    "teach-adapt": teach_adapt,
    "bench-training": bench_training,
    "bench-latency": bench_latency,
    "scaling-fit": scaling_fit,
    "scaling-stages": scaling_stages,
    "scaling-growth": scaling_growth,
    "mutation-scores": mutation_scores,
    "selection-ranking": selection_ranking,
    "package-layout": package_layout,
    "veil-results": veil_results,
    "veil-timing": veil_timing,
    "drawn-rooms-choice": drawn_rooms_choice,
    "multiclass-tol": multiclass_tol,
    "revisits": revisits,
    "table1-means": table1_means,
    "table1-seeds": table1_seeds,
    "drawn-seeds": drawn_seeds,
    "transfer-seeds": transfer_seeds,
    "table1-ci": table1_ci,
    "comparisons-excerpt": comparisons_excerpt,
    "failure-kinds": failure_kinds,
    "exact-by-task": exact_by_task,
}


# ---------------------------------------------------------------------------------------------
# The CLI reference

def cli_page() -> str:
    """Every subcommand of `taskseq`, with its help as argparse prints it."""
    import argparse

    from taskseq.cli import build_parser
    from taskseq.stages import STAGES

    columns = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "100"  # argparse wraps to the terminal: the same page on every machine
    try:
        parser = build_parser()
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        import taskseq.cli

        doc = " ".join(taskseq.cli.__doc__.split())
        about = doc[doc.index("Exit codes"):] if "Exit codes" in doc else ""
        parts = ["# Command line\n\nGenerated from `taskseq.cli.build_parser()` when the site is built: the help "
                 "of `taskseq` and of every subcommand. Each pipeline stage is a subcommand, which `dvc.yaml` runs "
                 f"with the options it lists; the other subcommands are tools. {about}\n\n"
                 "```text\n" + parser.format_help().rstrip() + "\n```"]
        for kind, names in (("Pipeline stages", [n for n in sub.choices if n in STAGES]),
                            ("Tools", [n for n in sub.choices if n not in STAGES])):
            parts.append(f"## {kind}\n\n" + ", ".join(f"[`{n}`](#taskseq-{n.replace('_', '-')})" for n in names))
            for name in names:
                command = sub.choices[name]
                parts.append(f"### taskseq {name} {{ #taskseq-{name.replace('_', '-')} }}\n\n"
                             f"{command.description or ''}\n\n```text\n{command.format_help().rstrip()}\n```")
    finally:
        if columns is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = columns
    return "\n\n".join(parts) + "\n"


# ---------------------------------------------------------------------------------------------
# The params reference

_SECTION = re.compile(r"^(\w+):\s*(?:#\s*(.*))?$")
_KEY = re.compile(r"^\s+(\w+):\s*(.*?)\s*(?:#\s*(.*))?$")


def params_page() -> str:
    """Every setting of `params.yaml` with its value and its comment, section by section."""
    path = ROOT / "params.yaml"
    parts = ["# Parameters\n\nEvery setting of `params.yaml`, the file `dvc.yaml`'s stages read, with the value it "
             "holds and its comment there; this page is generated from the file when the site is built. The "
             "defaults in code are `taskseq/settings.py`, which keeps them equal to this file, but for the `methods` "
             "section, which is written here only (each method's spec, in `taskseq/methods/`, holds the defaults of "
             "its own settings). Change one for a "
             "run with `--set SECTION.KEY=VALUE` on a stage's command, or as an experiment with "
             "`dvc exp run -S SECTION.KEY=VALUE` ([the pipeline](../pipeline.md#params)).\n"]
    rows: list[list[str]] = []
    section, intro, pending = None, "", []

    def flush():
        if section and rows:
            parts.append(f"## `{section}`\n\n" + (f"{intro}\n\n" if intro else "")
                         + _rows(["setting", "value", "what it sets"], "lll", rows))

    for line in path.read_text().splitlines():
        if not line.strip():
            continue
        if line.lstrip().startswith("#"):
            pending.append(line.strip().lstrip("#").strip())
            continue
        match = _SECTION.match(line)
        if match:
            flush()  # the comments above a section and on its line say what it is: they go under its heading
            section, rows = match.group(1), []
            intro, pending = " ".join([*pending, match.group(2) or ""]).strip(), []
            continue
        match = _KEY.match(line)
        if match and section:
            key, value, comment = match.groups()
            text = " ".join([*pending, comment or ""]).strip().replace("|", "\\|")
            rows.append([f"`{section}.{key}`", f"`{value}`" if value else "-", text])
            pending = []
    flush()
    return "\n\n".join(p for p in parts if p) + "\n"
