"""The stage layout: DVC knows every file a stage runs, and settings defaults equal params.yaml."""

from __future__ import annotations

import importlib.util
import json
import os
import re
import subprocess
import sys
from dataclasses import fields
from pathlib import Path

import pytest
import yaml
from params_reads import keys_read

from taskseq.methods import Lineup
from taskseq.methods.spec import added_modules, specs
from taskseq.runtime.dvc_deps import pipeline_files
from taskseq.selection import read_selection
from taskseq.settings import SECTIONS, Methods, Params, parse_section
from taskseq.stages import STAGES

ROOT = Path(__file__).resolve().parents[1]
PIPELINE = pipeline_files(ROOT)  # dvc.yaml and its parts, pipelines/*/dvc.yaml
PIPELINE_FILES = {str(path.relative_to(ROOT)) for path in PIPELINE}
DVC = {name: stage for path in PIPELINE for name, stage in yaml.safe_load(path.read_text())["stages"].items()}
_spec = importlib.util.spec_from_file_location("stage_deps", ROOT / "scripts" / "stage_deps.py")
stage_deps = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(stage_deps)


def dvc_stage(name: str) -> dict:
    """A stage of dvc.yaml by name; a `foreach` stage's template."""
    stage = DVC[name]
    return stage.get("do", stage)


def test_every_stage_of_dvc_yaml_has_its_module():
    assert sorted(DVC) == sorted(STAGES)
    assert stage_deps.misplaced({path: path.read_text() for path in PIPELINE}) is None


def test_a_stage_in_no_pipeline_file_or_in_two_is_named():
    texts = {path: path.read_text() for path in PIPELINE}
    root, part = PIPELINE[0], PIPELINE[1]
    moved = next(iter(yaml.safe_load(texts[part])["stages"]))
    problem = stage_deps.misplaced({root: texts[root]})
    assert f"stage {moved} is in no dvc.yaml of the pipeline: add it to dvc.yaml or a part" in problem
    twice = stage_deps.misplaced({**texts, ROOT / "pipelines" / "copy" / "dvc.yaml": texts[part]})
    assert f"stage {moved} is in {part.relative_to(ROOT)} and pipelines/copy/dvc.yaml: keep it in one" in twice


@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # DVC's own, from its graph of outputs
def test_every_stage_of_a_part_runs_in_the_root_and_is_upstream_of_the_roots_stages():
    """`dvc repro` in the root runs the root's stages and what they need: a part's stage downstream of nothing
    there would never run."""
    import networkx as nx
    from dvc.repo import Repo

    graph = Repo(str(ROOT)).index.graph
    roots = [s for s in graph if s.dvcfile.relpath == "dvc.yaml"]
    needed = {s for r in roots for s in nx.descendants(graph, r)} | set(roots)
    for path in PIPELINE[1:]:
        for name, stage in yaml.safe_load(path.read_text())["stages"].items():
            assert stage.get("do", stage).get("wdir") == "../..", f"{path}: stage {name} runs in its own folder"
        part = {s for s in graph if s.dvcfile.relpath == str(path.relative_to(ROOT))}
        assert part and part <= needed, f"{path}: {sorted(s.addressing for s in part - needed)} never run"


@pytest.mark.parametrize("stage", STAGES)
def test_dvc_deps_are_exactly_the_project_code_a_stage_loads(stage):
    deps = [d for d in dvc_stage(stage)["deps"] if d.startswith("taskseq")]
    assert deps == stage_deps.code_deps(stage), f"dvc.yaml stage {stage}: run python scripts/stage_deps.py"
    assert f"taskseq/stages/{stage}.py" in deps


FRESH = ("import importlib, json, sys\nfor n in sys.argv[1:]: importlib.import_module(n)\n"
         "print(json.dumps(sorted(m.__file__ for n, m in sys.modules.items() if n.split('.')[0] == 'taskseq')))")


@pytest.mark.parametrize("entries", [
    ["taskseq.cli", "taskseq.stages.teach"], ["taskseq.cli", "taskseq.stages.generate"],
    ["taskseq.cli", "taskseq.stages.choose_C", "taskseq.methods.drawn_rooms"]])
def test_the_import_server_answers_as_a_fresh_interpreter(entries):
    """`loaded_files` asks a server whose children find the third-party modules loaded: what a child reports is
    what a fresh interpreter loads, whatever the requests before it loaded."""
    fresh = subprocess.run([sys.executable, "-c", FRESH, *entries], capture_output=True, text=True, check=True,
                           cwd=ROOT)
    assert stage_deps.loaded_files(entries) == [str(Path(f).relative_to(ROOT)) for f in json.loads(fresh.stdout)]


def test_the_import_server_names_a_module_that_fails_and_keeps_its_answers_in_step_past_one_that_prints():
    with pytest.raises(RuntimeError, match="importing taskseq.no_such_module with .* failed: ModuleNotFoundError"):
        stage_deps.loaded_files(["taskseq.no_such_module"])
    # `this` prints the Zen of Python when imported, in the child and then in the server
    jobs = stage_deps.loaded_files(["taskseq.runtime.jobs"])
    assert stage_deps.loaded_files(["this", "taskseq.runtime.jobs"]) == jobs
    assert "taskseq/stages/teach.py" in stage_deps.loaded_files(["taskseq.cli", "taskseq.stages.teach"])


def test_the_deps_writer_replaces_a_stages_code_deps_and_keeps_everything_else():
    text = ("stages:\n  a:\n    cmd: x\n    deps:\n      - data/in  # read\n      - taskseq/old.py\n"
            "      - taskseq/sim\n    outs:\n      - out\n  b:\n    foreach: [1]\n    do:\n      deps:\n"
            "        - taskseq/cli.py\n")
    new = stage_deps.rewrite(text, {"a": ["taskseq/learn", "taskseq/stages/a.py"], "b": ["taskseq/b.py"]})
    assert new == text.replace("      - taskseq/old.py\n      - taskseq/sim\n",
                               "      - taskseq/learn\n      - taskseq/stages/a.py\n").replace(
        "        - taskseq/cli.py\n", "        - taskseq/b.py\n")
    with pytest.raises(ValueError, match="no code deps found for c"):
        stage_deps.rewrite(text, {"c": ["taskseq/c.py"]})


@pytest.mark.parametrize("stage", [name for name, s in STAGES.items() if s.per_method])
def test_a_per_method_stage_runs_once_for_each_method_it_chooses_with_that_methods_module(stage):
    assert DVC[stage]["foreach"] == stage_deps.method_modules(stage), \
        f"dvc.yaml stage {stage}: run python scripts/stage_deps.py"
    assert list(DVC[stage]["foreach"]) == stage_deps.methods_run(stage)


def test_the_deps_writer_replaces_a_per_method_stages_items_and_keeps_everything_else():
    text = ("stages:\n  a:\n    foreach:\n      x: taskseq/methods/x.py\n      gone: taskseq/methods/gone.py\n"
            "    do:\n      cmd: run ${key}\n      deps:\n        - ${item}\n  b:\n    cmd: y\n")
    new = stage_deps.rewrite_items(text, {"a": {"x": "taskseq/methods/builtin.py", "y": "taskseq/methods/y.py"}})
    assert new == text.replace("      x: taskseq/methods/x.py\n      gone: taskseq/methods/gone.py\n",
                               "      x: taskseq/methods/builtin.py\n      y: taskseq/methods/y.py\n")
    with pytest.raises(ValueError, match="no foreach mapping found for b"):
        stage_deps.rewrite_items(text, {"b": {"x": "taskseq/methods/x.py"}})



def test_the_labels_file_holds_every_methods_label_as_its_spec_gives_it():
    # the stages that write tables read it instead of the methods' modules: python scripts/stage_deps.py writes it
    assert (ROOT / stage_deps.LABELS).read_text() == stage_deps.labels_json()
    assert json.loads(stage_deps.labels_json()) == {name: spec.label for name, spec in specs().items()}



def test_every_label_is_read_without_importing_an_added_methods_module():
    # the stages that write tables read labels only: under DVC, importing a method's module their deps do not
    # list would stop them (taskseq.runtime.dvc_deps)
    code = ("import json, sys; from taskseq.methods import method_labels; labels = method_labels(); "
            "print(json.dumps([len(labels), sorted(n for n in sys.modules if n.startswith('taskseq.methods.'))]))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    count, loaded = json.loads(out.stdout)
    assert count == len(specs())
    assert not {f"taskseq.methods.{name}" for name in added_modules()} & set(loaded)

def test_a_per_method_stage_refuses_a_method_without_an_entry_of_params(monkeypatch):
    # each run lists methods.NAME among its params, which DVC refuses when params.yaml has no such key
    monkeypatch.setattr(stage_deps, "methods_run", lambda stage: ["full", "no_entry"])
    with pytest.raises(ValueError, match=r"choose_C runs once for method no_entry, which has no entry in "
                                         r"params.yaml's methods section; add one \(no_entry: \{\} keeps"):
        stage_deps.method_modules("choose_C")

VEIL_DVC = yaml.safe_load((ROOT / "veil" / "dvc.yaml").read_text())["stages"]


@pytest.mark.parametrize("stage", stage_deps.VEIL_STAGES)
def test_veil_deps_are_exactly_the_project_code_its_subcommand_loads(stage):
    assert sorted(VEIL_DVC) == sorted(stage_deps.VEIL_STAGES)
    deps = [d for d in VEIL_DVC[stage]["deps"] if d.startswith("../taskseq")]
    assert deps == stage_deps.veil_code_deps(stage), f"veil/dvc.yaml stage {stage}: run python scripts/stage_deps.py"
    assert "../taskseq/veil/command.py" in deps and f"taskseq veil {stage} " in VEIL_DVC[stage]["cmd"]


LOADED_AT_EXIT = """
import atexit, json, sys
from taskseq.cli import main
atexit.register(lambda: print(json.dumps(sorted(m.__file__ for n, m in sys.modules.items()
                                                if n.startswith("taskseq") and getattr(m, "__file__", None)))))
sys.exit(main(sys.argv[1:]))
"""


def _other_commands_options() -> list[str]:
    """The project files that building the command line's parser loads beyond the modules the generator imports:
    other commands' options (the scaling benchmark names its stages in its help), which change no stage's result."""
    code = ("import json, sys; from taskseq.cli import build_parser; before = set(sys.modules); build_parser(); "
            "print(json.dumps(sorted(sys.modules[n].__file__ for n in set(sys.modules) - before "
            "if n.startswith('taskseq'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    return [str(Path(f).resolve().relative_to(ROOT)) for f in json.loads(out.stdout)]


@pytest.mark.parametrize("stage", ["import", "train"])
def test_a_veil_stage_run_on_a_release_loads_no_project_file_outside_its_deps(stage, tmp_path):
    """The generator's deps against what the sub-command really loads, run on the fixture release."""
    params = tmp_path / "params.yaml"
    params.write_text("veil:\n  folds: 2\n  C_grid: [1.0]\n  max_steps: 10\n  resamples: 10\n"
                      "  lookahead_widths: [1]\n")
    release = ROOT / "tests" / "fixtures" / "veil" / "release"
    argv = {"import": ["--output", str(tmp_path / "processed"), "--quiet"],
            "train": ["--output", str(tmp_path / "model.npz"), "--params", str(params)]}[stage]
    out = subprocess.run([sys.executable, "-c", LOADED_AT_EXIT, "--no-mlflow", "veil", stage, "--release",
                          str(release), *argv], capture_output=True, text=True, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    loaded = {str(Path(f).resolve().relative_to(ROOT)) for f in json.loads(out.stdout.strip().splitlines()[-1])}
    deps = [d.removeprefix("../") for d in stage_deps.veil_code_deps(stage)] + _other_commands_options()
    outside = sorted(f for f in loaded if not any(f == d or f.startswith(d + "/") for d in deps))
    assert outside == [], f"taskseq veil {stage} loads files veil/dvc.yaml does not list"


def _project_imports_in_functions(path: Path) -> list[str]:
    """`from .x import y` or `import taskseq...` statements inside a function of the file."""
    import ast

    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            for inner in ast.walk(node):
                if (isinstance(inner, ast.ImportFrom) and (inner.level or (inner.module or "").startswith("taskseq"))
                        or isinstance(inner, ast.Import) and any(a.name.startswith("taskseq") for a in inner.names)):
                    found.append(f"{path.relative_to(ROOT)}:{inner.lineno} in {node.name}")
    return found


def test_what_a_veil_stage_loads_imports_project_code_when_loaded_so_its_deps_see_it():
    """The generator reads the imports of the sub-command's function and then lets an interpreter load what they
    name: a project import inside a function of a module loaded that way would go unseen. The command-line
    modules, which dispatch to the tools, are the ones allowed to import when a command runs."""
    dispatchers = {"taskseq/cli.py", "taskseq/tool_commands.py", "taskseq/veil/command.py",
                   "taskseq/stages/command.py"}
    for stage in stage_deps.VEIL_STAGES:
        for dep in stage_deps.veil_code_deps(stage):
            path = ROOT / dep.removeprefix("../")
            for file in sorted(path.rglob("*.py")) if path.is_dir() else [path]:
                if str(file.relative_to(ROOT)) not in dispatchers:
                    assert _project_imports_in_functions(file) == [], stage


def _stages_a_change_can_rerun(repo, graph, path: str, dvcfiles: set[str] = PIPELINE_FILES) -> set[str]:
    """The stages of the pipeline (or of `dvcfiles`) that `dvc repro` may re-run after a change to the file `path`,
    as DVC's own graph has them: those that list it among their deps, and every stage downstream of those (re-run
    only when an output it reads changed)."""
    import networkx as nx

    def covers(dep: str) -> bool:
        return path == dep or path.startswith(dep.rstrip("/") + "/")

    direct = [s for s in graph if s.dvcfile.relpath in dvcfiles
              and any(covers(os.path.relpath(d.fs_path, repo.root_dir)) for d in s.deps)]
    return {_named(s) for s in direct} | {_named(a) for s in direct for a in nx.ancestors(graph, s)}


def _named(stage) -> str:
    """A stage of the pipeline by its name (`crossval@0`, whichever of its files holds it), another by DVC's
    address (`veil/dvc.yaml:train`)."""
    return stage.name if stage.dvcfile.relpath in PIPELINE_FILES else stage.addressing


@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # DVC's own, from its graph of outputs
def test_a_change_to_one_stages_code_reaches_only_that_stage_and_what_reads_its_outputs():
    from dvc.repo import Repo

    repo = Repo(str(ROOT))
    graph = repo.index.graph

    def reruns(path):
        return _stages_a_change_can_rerun(repo, graph, path)

    assert reruns("taskseq/stages/teach.py") == {"teach"}
    assert reruns("taskseq/serve/app.py") == {"teach"}  # the web app's record writer, which teach writes through
    assert reruns("taskseq/stages/scenes.py") == {"scenes", "report"}
    assert reruns("taskseq/bench/speed.py") == set()  # a tool's code
    veil = {"veil/dvc.yaml"}
    for path in ("taskseq/stages/teach.py", "taskseq/evaluate/methods.py", "taskseq/experiments/crossval.py",
                 "taskseq/methods/choice.py", "taskseq/serve/app.py"):
        assert _stages_a_change_can_rerun(repo, graph, path, veil) == set(), path  # none of VEIL's code
    assert _stages_a_change_can_rerun(repo, graph, "taskseq/veil/ingest.py", veil) == {
        "veil/dvc.yaml:import", "veil/dvc.yaml:evaluate", "veil/dvc.yaml:train"}
    seeds = Params.load(ROOT / "params.yaml").world.seeds
    assert reruns("taskseq/stages/drawn_world.py") == {
        *(f"{stage}@{s}" for stage in ("drawn_world", "scenes_world") for s in seeds), "scenes", "teach",
        "stats@drawn_rooms", "stats@transfer", "report"}  # the drawn worlds' stages, none of the reported worlds'


@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # DVC's own, from its graph of outputs
def test_a_change_to_one_methods_module_reruns_only_the_stages_that_run_it():
    from dvc.repo import Repo

    repo = Repo(str(ROOT))

    def listing(path: str) -> set[str]:  # the stages whose deps DVC checks for this file
        return {s.name for s in repo.index.graph if s.dvcfile.relpath in PIPELINE_FILES
                and any(path == d or path.startswith(d + "/")
                        for d in (os.path.relpath(dep.fs_path, repo.root_dir) for dep in s.deps))}

    seeds = Params.load(ROOT / "params.yaml").world.seeds
    per_world = {f"{stage}@{s}" for stage in ("fold_models", "crossval", "noise", "scenes_world") for s in seeds}
    # noise_trained runs in select (its own choice of C), noise and Table I (params.yaml); the tables over worlds
    # read every method's label from labels.json, not its module; teach and train take the shipped method alone,
    # the one selection.json ranks first
    assert listing("taskseq/methods/noise_trained.py") == per_world | {"choose_C@noise_trained"}
    tables = {"scenes", "aggregate", "report", *(f"stats@{t}" for t in ("scenario_folds", "drawn_rooms", "transfer"))}
    assert tables <= listing("taskseq/methods/labels.json")
    shipped = read_selection(ROOT / "reports" / "selection.json").method
    module = f"taskseq/methods/{shipped if shipped in added_modules() else 'builtin'}.py"
    assert {"train", "teach"} <= listing(module)
    for stage in ("feedback", "recipes"):  # they run full, relations, chained and choice_chained_lookahead
        assert not {f"{stage}@{s}" for s in seeds} & listing("taskseq/methods/noise_trained.py")
        assert {f"{stage}@{s}" for s in seeds} <= listing("taskseq/methods/builtin.py")
    assert {f"recipes@{s}" for s in seeds} <= listing("taskseq/methods/choice_chained_lookahead.py")
    # every method's choice of C loads the built-in methods' module; a change to an added one re-does its own only
    chosen = {s for s in listing("taskseq/methods/builtin.py") if s.startswith("choose_C@")}
    assert chosen == {f"choose_C@{name}" for name in stage_deps.methods_run("choose_C")}
    assert {s for s in listing("taskseq/methods/drawn_rooms.py") if s.startswith("choose_C")} == {
        "choose_C@drawn_rooms"}



@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # DVC's own, from its graph of outputs
def test_an_edit_of_one_methods_entry_of_params_re_does_that_methods_choice_of_c_alone():
    from dvc.dependency.param import ParamsDependency
    from dvc.repo import Repo

    def covers(key: str, entry: str) -> bool:
        return key == entry or key.startswith(entry + ".")

    repo = Repo(str(ROOT))
    reading = {s.name for s in repo.index.graph if s.name.startswith("choose_C@")
               and any(covers("methods.noise_trained.noise_rate", p) for d in s.deps
                       if isinstance(d, ParamsDependency) for p in d.params)}
    assert reading == {"choose_C@noise_trained"}

def test_the_shipped_methods_stages_load_the_method_selection_ranks_first_or_every_ranked_one_without_it(
        tmp_path, monkeypatch):
    entries = Params.load(ROOT / "params.yaml").methods.entries
    ranked = [name for name, entry in entries if "select" in entry.experiments]
    other = next(name for name in ranked if name != read_selection(ROOT / "reports" / "selection.json").method)
    chosen = tmp_path / "selection.json"
    chosen.write_text(json.dumps({"settings": {other: {"C": 1.0}}, "method": other}))
    monkeypatch.setattr(stage_deps, "SELECTION", chosen)
    assert stage_deps.methods_run("teach") == stage_deps.methods_run("train") == [other]
    monkeypatch.setattr(stage_deps, "SELECTION", tmp_path / "none.json")
    assert stage_deps.methods_run("teach") == ranked


@pytest.mark.parametrize("stage", ["train", "select", "fold_models", "crossval", "noise", "feedback", "recipes",
                                   "scenes_world"])
def test_stages_that_load_planners_start_without_scikit_learn(stage):
    # importing scikit-learn takes about a second in every stage process and worker; only the baselines'
    # fits need it, and they import it themselves
    code = f"import sys, taskseq.stages.{stage}; print('sklearn' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    assert out.stdout.strip() == "False"


def test_settings_defaults_equal_params_yaml():
    params = yaml.safe_load((ROOT / "params.yaml").read_text())
    for section, cls in SECTIONS.items():
        assert section in params, f"params.yaml has no section {section}"
        if cls is Methods:  # no defaults in code: the file is where the methods' entries are written, once
            continue
        assert parse_section(cls, params[section]) == cls(), f"defaults of {cls.__name__} differ from params.yaml"
        assert set(params[section]) == {f.name for f in fields(cls)}, section


def test_params_yaml_names_every_method_of_table1_once_with_settings_it_has():
    methods = Params.load(ROOT / "params.yaml").methods
    lineup = Lineup(methods)  # raises for a name no spec has, or a setting its method does not have
    written = [name for name, _ in methods.entries]
    assert sorted(written) == sorted(lineup.names()) and len(set(written)) == len(written)


def test_no_stage_command_passes_a_setting_that_changes_no_result():
    for name in STAGES:
        cmd = dvc_stage(name)["cmd"]
        assert not re.search(r"--n-jobs|--recordings(?!-dir)", cmd), name


def leaf_keys(entries: list[str]) -> set[str]:
    """dvc.yaml params entries as `section.key`: a whole section stands for each of its keys."""
    out = set()
    for entry in entries:
        # a per-method stage's run lists its own method's entry (`methods.${key}`), which is all it reads of the
        # section (tests/test_selection_behaviour.py)
        entry = "methods.entries" if entry == "methods.${key}" else entry
        section, _, key = entry.partition(".")
        out |= {f"{section}.{f.name}" for f in fields(SECTIONS[section])} if not key else {entry}
    return out


@pytest.mark.parametrize("stage", STAGES)
def test_dvc_params_are_exactly_the_settings_a_stage_reads(stage):
    declared = leaf_keys(dvc_stage(stage).get("params", []))
    read = keys_read(stage)
    assert declared == read, f"dvc.yaml stage {stage}: lists {sorted(declared - read)} it never reads, " \
                             f"misses {sorted(read - declared)}"


@pytest.mark.parametrize("stage", STAGES)
def test_stage_commands_carry_paths_and_the_world_seed_only(stage):
    cmd = dvc_stage(stage)["cmd"]
    options = re.findall(r"--([a-z-]+)", cmd)
    allowed = {f.name.replace("_", "-") for f in fields(STAGES[stage].options)} | {"world-seed", "cache"}
    assert set(options) <= allowed, f"{stage} passes {sorted(set(options) - allowed)}"
    rest = re.sub(r"\$\{(item(\.\w+)?|key)\}", "", cmd).replace("${world.seeds[0]}", "").replace("${cache}", "")
    assert "${" not in rest, cmd


def test_every_stage_that_fits_or_runs_programs_keeps_them_in_the_one_cache_folder():
    assert yaml.safe_load((ROOT / "pipelines" / "vars.yaml").read_text()) == {"cache": ".cache"}
    assert "/.cache/" in (ROOT / ".gitignore").read_text().split()
    for path in PIPELINE:  # every file reads the one setting
        vars_ = yaml.safe_load(path.read_text())["vars"]
        assert ("pipelines/vars.yaml" if path == PIPELINE[0] else "../vars.yaml") in vars_, path
    for name, stage in STAGES.items():
        passed = re.findall(r"--cache (\S+)", dvc_stage(name)["cmd"])
        assert passed == (["${cache}"] if stage.cached else []), name
