"""Write the code dependencies of every stage of the pipeline (dvc.yaml and its parts, pipelines/*/dvc.yaml) and of
veil/dvc.yaml (exactly the project files it loads), and the methods' labels.

A stage's `deps` list the data it reads (written by hand, with the command
that reads it) and the project code it runs. The code part is generated here:
the command line and the stage's entry modules are imported as in a fresh
interpreter (`IMPORT_SERVER`), and every project module it then holds is a
dependency, named by its subpackage (`taskseq/learn`) or, for the package's
own modules, the stage modules, the methods' and VEIL's modules, by its file
(`taskseq/stages/select.py`). So a change to code a stage never loads does not
re-run it, and one it does load always does.

A stage of dvc.yaml enters through its module, `taskseq.stages.<name>`, and
the modules of the methods it runs (`Stage.runs`: every method, or those
whose entry of params.yaml's `methods` names the stage's experiment), which a
stage imports only when it asks for them (`taskseq.methods.method_spec`). A
stage run once per method (`Stage.per_method`: `choose_C`) is a `foreach` over
those methods: its deps list what every run loads, and each item, written here
too, is that method's own module, which its run's deps name as `${item}`. A
stage of veil/dvc.yaml is the `taskseq veil` sub-command of its name, which
imports what it needs when it runs (so that `taskseq --help` stays quick):
its entry modules are those its function imports, read from the function's
source, and from the functions of `taskseq/veil/command.py` it calls.

It also writes `taskseq/methods/labels.json`, every method's label from its
spec: the stages that only write tables read labels there instead of
importing every method's module, so a change to one method's code does not
re-run them (a stage that loads `taskseq/methods/spec.py` lists the file).

    python scripts/stage_deps.py           # rewrite the code deps of every dvc.yaml and the labels
    python scripts/stage_deps.py --check   # exit 1 and name every file whose code deps differ

Run it after adding a stage or a method, changing a method's label, what a stage imports or which experiments a
method's entry of params.yaml names; tests/test_stages.py fails until the files agree.
"""

from __future__ import annotations

import argparse
import ast
import atexit
import importlib
import importlib.util
import inspect
import json
import os
import re
import select
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
VEIL_YAML = ROOT / "veil" / "dvc.yaml"
SELECTION = ROOT / "reports" / "selection.json"  # the select stage's file: which method ships
LABELS = "taskseq/methods/labels.json"  # every method's label (`taskseq.methods.spec.LABELS_FILE`), written here too

# A server that answers each request (a JSON list of modules, one line) with the project files a fresh interpreter
# loads when it imports them (one line of JSON). Each request is imported in a child the server forks, which holds
# nothing of the project; the child also names the third-party modules it loaded, and the server imports those
# itself once it has answered, so the next children find NumPy, SciPy, pandas and the like loaded (a fresh
# interpreter spent about 1.2 s of its 1.3 s on them). The project files a child loads are those a fresh interpreter
# would: no project module is ever imported in the server. Its answers go out on a copy of its stdout, with stdout
# itself sent to /dev/null, so a module that prints cannot put the answers out of step.
IMPORT_SERVER = r"""
import importlib, json, os, sys, traceback
answers = os.fdopen(os.dup(1), "w")
os.dup2(os.open(os.devnull, os.O_WRONLY), 1)
for line in sys.stdin:
    read, write = os.pipe()
    sys.stdout.flush()
    sys.stderr.flush()
    pid = os.fork()
    if pid == 0:
        code = 1
        try:
            os.close(read)
            try:
                for name in json.loads(line):
                    importlib.import_module(name)
                held = list(sys.modules.items())
                answer = {"files": sorted(m.__file__ for n, m in held
                                          if n.split(".")[0] == "taskseq" and getattr(m, "__file__", None)),
                          "others": [n for n, _ in held if n.split(".")[0] != "taskseq"]}
            except BaseException:
                answer = {"error": traceback.format_exc().strip().splitlines()[-1]}
            with os.fdopen(write, "w") as out:
                out.write(json.dumps(answer))
            code = 0
        finally:
            os._exit(code)
    os.close(write)
    with os.fdopen(read) as got:
        text = got.read()
    _, status = os.waitpid(pid, 0)
    try:
        answer = json.loads(text) if status == 0 else {"error": f"the child importing them ended with status {status}"}
    except ValueError:
        answer = {"error": "the child importing them gave no whole answer"}
    others = answer.pop("others", [])
    answers.write(json.dumps(answer) + "\n")
    answers.flush()
    for name in others:
        if name not in sys.modules and not name.startswith("__"):
            try:
                importlib.import_module(name)
            except BaseException:
                pass
"""
ANSWER_WITHIN = 300  # seconds a request may take before the server is taken for stuck
STAGE = re.compile(r"^  (\w+):\s*$")
CODE_DEP = re.compile(r"^(\s+)- (?:\.\./)?taskseq/\S+\s*$")
BY_FILE = {"stages", "veil", "methods"}  # subpackages whose modules are listed one by one
VEIL_STAGES = ("import", "evaluate", "train")  # veil/dvc.yaml's stages: `taskseq veil` sub-commands


_server: subprocess.Popen | None = None


def _stop_server() -> None:
    if _server is not None and _server.poll() is None:
        _server.stdin.close()
        try:
            _server.wait(timeout=10)
        except subprocess.TimeoutExpired:
            _server.kill()


def loaded_files(entries: list[str]) -> list[str]:
    """The project files a fresh interpreter loads when it imports `entries`, relative to the repository."""
    global _server
    if _server is None or _server.poll() is not None:
        # one thread for the numerical libraries: the server forks, and a child holds only the thread that forked
        env = {**os.environ, **dict.fromkeys(("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"), "1")}
        _server = subprocess.Popen([sys.executable, "-c", IMPORT_SERVER], stdin=subprocess.PIPE,
                                   stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, cwd=ROOT, env=env)
        atexit.register(_stop_server)
    try:
        _server.stdin.write(json.dumps(entries) + "\n")
        _server.stdin.flush()
        ready, _, _ = select.select([_server.stdout], [], [], ANSWER_WITHIN)
        line = _server.stdout.readline() if ready else ""
    except OSError as err:
        line, problem = "", f"the import server stopped ({err})"
    else:
        problem = "the import server stopped" if ready else f"no answer within {ANSWER_WITHIN} s"
    answer = json.loads(line) if line else {"error": problem}
    if "error" in answer:
        _stop_server()
        raise RuntimeError(f"importing {', '.join(entries)} with {sys.executable} failed: {answer['error']}; run this "
                           "script in the project's environment (. .venv/bin/activate)")
    return [str(Path(f).resolve().relative_to(ROOT)) for f in answer["files"]]


def grouped(paths: list[str]) -> list[str]:
    """Files as dvc.yaml lists them: a subpackage whole, the package's own modules and those of `BY_FILE` by file,
    the methods' package whole when every module of it is loaded."""
    deps = set()
    for path in paths:
        parts = path.split("/")
        deps.add("/".join(parts[:2]) if len(parts) > 2 and parts[1] not in BY_FILE else path)
    methods = {str(p.relative_to(ROOT)) for p in (ROOT / "taskseq" / "methods").glob("*.py")}
    if methods <= deps:
        deps = deps - methods | {"taskseq/methods"}
    elif "taskseq/methods/spec.py" in deps:
        deps.add(LABELS)  # the labels `method_labels` reads instead of the methods' modules
    return sorted(deps)


def code_deps(stage: str) -> list[str]:
    """A stage of dvc.yaml's code dependencies: what importing it loads, and the modules of the methods it runs
    (for a stage run once per method, the part every run shares: each run's own module is its foreach item)."""
    from taskseq.methods.spec import added_modules
    from taskseq.stages import STAGES

    run = [] if STAGES[stage].per_method else methods_run(stage)
    methods = [f"taskseq.methods.{name}" for name in run if name in added_modules()]
    return grouped(loaded_files(["taskseq.cli", f"taskseq.stages.{stage}", *methods]))


def method_modules(stage: str) -> dict[str, str]:
    """A stage run once per method (`Stage.per_method`): each method's one file beyond what every run loads, its
    foreach item in dvc.yaml (the built-in methods' module for those that have none of their own)."""
    from taskseq.methods.spec import added_modules
    from taskseq.settings import Params

    shared = set(loaded_files(["taskseq.cli", f"taskseq.stages.{stage}"]))
    entries = Params.load(ROOT / "params.yaml").methods
    out = {}
    for name in methods_run(stage):
        if entries.entry(name) is None:  # each run lists its own entry among its params (methods.${key})
            raise ValueError(f"stage {stage} runs once for method {name}, which has no entry in params.yaml's "
                             f"methods section; add one ({name}: {{}} keeps its defaults)")
        own = [f"taskseq.methods.{name}"] if name in added_modules() else []
        extra = sorted(set(loaded_files(["taskseq.cli", f"taskseq.stages.{stage}", *own])) - shared)
        if len(extra) > 1:
            raise ValueError(f"method {name} loads {', '.join(extra)}: a stage run once per method depends on one "
                             "file of each; keep a method's code in its own module")
        out[name] = extra[0] if extra else "taskseq/methods/builtin.py"
    return out


def methods_run(stage: str) -> list[str]:
    """The methods whose modules the stage loads when it runs (`Stage.runs`): every one, those params.yaml's
    `methods` section gives its experiment, or the shipped one.

    The shipped method is `train.method`, or when that says best the method reports/selection.json ranks first
    (every method select ranks while there is no such file): a stage that fits it alone then re-runs for a change
    to its module only. Should select rank another first, the file changes with it, the stage's deps name the
    old module, and the stage, run by DVC, stops before any work and asks for this script
    (`taskseq.runtime.dvc_deps`).
    """
    from taskseq.methods import method_names
    from taskseq.selection import read_selection
    from taskseq.settings import Params
    from taskseq.stages import STAGES

    runs, params = STAGES[stage].runs, Params.load(ROOT / "params.yaml")
    if runs == "all":
        return method_names()
    if runs == "shipped":
        if params.train.method != "best":
            return [params.train.method]
        shipped = read_selection(SELECTION).method if SELECTION.exists() else None
        if shipped:
            return [shipped]
        runs = "select"
    named = [name for name, entry in params.methods.entries if runs and runs in entry.experiments]
    if runs == "select" and params.train.method not in ("best", *named):
        named.append(params.train.method)  # select gives the shipped method its C
    return named


def _imported_when_run(function, module, seen: set[str]) -> set[str]:
    """The project modules `function` imports in its body, and those of the functions of its module it calls."""
    seen.add(function.__name__)
    names = set()
    for node in ast.walk(ast.parse(inspect.getsource(function))):
        if isinstance(node, ast.ImportFrom) and node.level:
            base = importlib.util.resolve_name("." * node.level + (node.module or ""), module.__package__)
            names.add(base)
            spec = importlib.util.find_spec(base)
            if spec is not None and spec.submodule_search_locations:  # a package: its names may be modules
                names |= {f"{base}.{a.name}" for a in node.names if importlib.util.find_spec(f"{base}.{a.name}")}
        elif isinstance(node, ast.ImportFrom | ast.Import):
            names |= {a.name for a in node.names if a.name.startswith("taskseq")}
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("taskseq"):
                names.add(node.module)
        elif isinstance(node, ast.Name) and node.id not in seen:
            called = getattr(module, node.id, None)
            if inspect.isfunction(called) and called.__module__ == module.__name__:
                names |= _imported_when_run(called, module, seen)
    return names


def veil_code_deps(stage: str) -> list[str]:
    """A stage of veil/dvc.yaml's code dependencies, as that file names them (from the folder `veil/`)."""
    command = importlib.import_module("taskseq.veil.command")
    entries = sorted(_imported_when_run(command.SUBCOMMANDS[stage].run, command, set()))
    files = loaded_files(["taskseq.cli", "taskseq.tool_commands", "taskseq.veil.command", *entries])
    return [f"../{d}" for d in grouped(files)]


def labels_json() -> str:
    """The text of the labels file: every method's label from its spec, in the tables' order."""
    from taskseq.methods.spec import spec_labels

    return json.dumps(spec_labels(), indent=2, ensure_ascii=False) + "\n"


def _stages(lines: list[str]) -> list[str | None]:
    """The stage each line of dvc.yaml belongs to (None before the first)."""
    out, stage = [], None
    for line in lines:
        match = STAGE.match(line)
        stage = match.group(1) if match else stage
        out.append(stage)
    return out


def rewrite(text: str, deps: dict[str, list[str]]) -> str:
    """dvc.yaml's text with each named stage's run of `- taskseq/...` lines replaced by its deps."""
    lines, out, done = text.splitlines(keepends=True), [], set()
    stages = _stages(lines)
    i = 0
    while i < len(lines):
        code, stage = CODE_DEP.match(lines[i]), stages[i]
        if code and stage in deps:
            if stage in done:
                raise ValueError(f"stage {stage} lists its code deps in more than one run of lines")
            while i < len(lines) and CODE_DEP.match(lines[i]):
                i += 1
            out += [f"{code.group(1)}- {d}\n" for d in deps[stage]]
            done.add(stage)
            continue
        out.append(lines[i])
        i += 1
    missing = sorted(set(deps) - done)
    if missing:
        raise ValueError(f"no code deps found for {', '.join(missing)}; list at least one taskseq/ path")
    return "".join(out)


def rewrite_items(text: str, items: dict[str, dict[str, str]]) -> str:
    """dvc.yaml's text with the `foreach` mapping of each named stage replaced by `items[stage]` (name: value)."""
    lines, out, done = text.splitlines(keepends=True), [], set()
    stages = _stages(lines)
    i = 0
    while i < len(lines):
        line, stage = lines[i], stages[i]
        out.append(line)
        i += 1
        if stage in items and line.strip() == "foreach:":
            indent = len(line) - len(line.lstrip()) + 2
            while i < len(lines) and len(lines[i]) - len(lines[i].lstrip()) >= indent and lines[i].strip():
                i += 1
            out += [f"{' ' * indent}{name}: {value}\n" for name, value in items[stage].items()]
            done.add(stage)
    missing = sorted(set(items) - done)
    if missing:
        raise ValueError(f"no foreach mapping found for {', '.join(missing)}")
    return "".join(out)


def stages_in(text: str) -> list[str]:
    """The stages a dvc.yaml's text defines, in its order."""
    return [stage for stage in dict.fromkeys(_stages(text.splitlines())) if stage]


def _dvc_yaml(text: str) -> str:
    """A pipeline file's text with the code deps (and per-method items) of the stages it defines."""
    from taskseq.stages import STAGES

    here = [stage for stage in stages_in(text) if stage in STAGES]
    text = rewrite(text, {stage: code_deps(stage) for stage in here})
    return rewrite_items(text, {stage: method_modules(stage) for stage in here if STAGES[stage].per_method})


def misplaced(texts: dict[Path, str]) -> str | None:
    """Why the pipeline's files (path: text) do not define every stage of `taskseq.stages` exactly once, if so."""
    from taskseq.stages import STAGES

    where: dict[str, list[str]] = {}
    for path, text in texts.items():
        for stage in stages_in(text):
            where.setdefault(stage, []).append(str(path.relative_to(ROOT)))
    problems = [f"stage {s} is in no dvc.yaml of the pipeline: add it to dvc.yaml or a part (pipelines/NAME/"
                f"dvc.yaml)" for s in STAGES if s not in where]
    problems += [f"stage {s} is in {' and '.join(files)}: keep it in one" for s, files in where.items()
                 if len(files) > 1]
    problems += [f"{files[0]}: stage {s} has no module taskseq/stages/{s}.py" for s, files in where.items()
                 if s not in STAGES]
    return "; ".join(problems) or None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="change nothing; exit 1 if a file differs")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    from taskseq.runtime.dvc_deps import pipeline_files

    pipeline = pipeline_files(ROOT)
    problem = misplaced({path: path.read_text() for path in pipeline})
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        return 2
    files = {**dict.fromkeys(pipeline, _dvc_yaml),
             VEIL_YAML: lambda text: rewrite(text, {stage: veil_code_deps(stage) for stage in VEIL_STAGES}),
             ROOT / LABELS: lambda text: labels_json()}
    differ = []
    for path, written in files.items():
        text = path.read_text() if path.exists() else ""
        try:
            new = written(text)
        except (RuntimeError, ValueError) as err:
            print(f"error: {path.relative_to(ROOT)}: {err}", file=sys.stderr)
            return 2
        name = path.relative_to(ROOT)
        if new == text:
            print(f"{name}: as the code says")
            continue
        differ.append(name)
        if not args.check:
            tmp = path.with_suffix(path.suffix + ".tmp")
            tmp.write_text(new)
            tmp.replace(path)
            print(f"{name}: rewritten; review with git diff {name}")
    if differ and args.check:
        print(f"{', '.join(map(str, differ))}: differ from what the code says (the files the stages load, the "
              "methods' labels); run python scripts/stage_deps.py", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
