"""Write the code dependencies of every stage in dvc.yaml: exactly the project files the stage's command loads.

A stage's `deps` in dvc.yaml list the data it reads (written by hand, with
the command that reads it) and the project code it runs. The code part is
generated here: a fresh interpreter imports the command line and the stage's
module, and every project module it then holds is a dependency, named by its
subpackage (`taskseq/learn`) or, for the package's own modules and the stage
modules, by its file (`taskseq/stages/select.py`). So a change to code a stage
never loads does not re-run it, and one it does load always does.

    python scripts/stage_deps.py           # rewrite dvc.yaml's code deps
    python scripts/stage_deps.py --check   # exit 1 and name every stage whose code deps differ

Run it after adding a stage or changing what a stage imports; tests/test_stages.py fails until dvc.yaml agrees.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DVC_YAML = ROOT / "dvc.yaml"

LOADED = """
import importlib, json, sys
importlib.import_module("taskseq.cli")
importlib.import_module("taskseq.stages." + sys.argv[1])
print(json.dumps(sorted(m.__file__ for n, m in sys.modules.items()
                        if (n == "taskseq" or n.startswith("taskseq.")) and getattr(m, "__file__", None))))
"""
STAGE = re.compile(r"^  (\w+):\s*$")
CODE_DEP = re.compile(r"^(\s+)- taskseq/\S+\s*$")


def loaded_files(stage: str) -> list[str]:
    """The project files a fresh interpreter loads to run the stage, relative to the repository."""
    out = subprocess.run([sys.executable, "-c", LOADED, stage], capture_output=True, text=True, cwd=ROOT)
    if out.returncode != 0:
        last = (out.stderr.strip().splitlines() or ["(no message)"])[-1]
        raise RuntimeError(f"importing stage {stage} with {sys.executable} failed: {last}; run this script in the "
                           "project's environment (. .venv/bin/activate)")
    return [str(Path(f).resolve().relative_to(ROOT)) for f in json.loads(out.stdout)]


def code_deps(stage: str) -> list[str]:
    """The stage's code dependencies as dvc.yaml lists them: a subpackage whole, the package's own modules and the
    stage modules by file."""
    deps = set()
    for path in loaded_files(stage):
        parts = path.split("/")
        deps.add("/".join(parts[:2]) if len(parts) > 2 and parts[1] != "stages" else path)
    return sorted(deps)


def rewrite(text: str, deps: dict[str, list[str]]) -> str:
    """dvc.yaml's text with each named stage's run of `- taskseq/...` lines replaced by its deps."""
    lines, out, stage, done = text.splitlines(keepends=True), [], None, set()
    i = 0
    while i < len(lines):
        match = STAGE.match(lines[i])
        if match:
            stage = match.group(1)
        code = CODE_DEP.match(lines[i])
        if code and stage in deps:
            if stage in done:
                raise ValueError(f"dvc.yaml: stage {stage} lists its code deps in more than one run of lines")
            while i < len(lines) and CODE_DEP.match(lines[i]):
                i += 1
            out += [f"{code.group(1)}- {d}\n" for d in deps[stage]]
            done.add(stage)
            continue
        out.append(lines[i])
        i += 1
    missing = sorted(set(deps) - done)
    if missing:
        raise ValueError(f"dvc.yaml: no code deps found for {', '.join(missing)}; list at least one taskseq/ path")
    return "".join(out)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="change nothing; exit 1 if dvc.yaml differs")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    from taskseq.stages import STAGES

    text = DVC_YAML.read_text()
    try:
        new = rewrite(text, {stage: code_deps(stage) for stage in STAGES})
    except (RuntimeError, ValueError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if new == text:
        print("dvc.yaml: every stage's code deps are the files it loads")
        return 0
    if args.check:
        print("dvc.yaml: code deps differ from the files the stages load; run python scripts/stage_deps.py",
              file=sys.stderr)
        return 1
    tmp = DVC_YAML.with_suffix(".yaml.tmp")
    tmp.write_text(new)
    tmp.replace(DVC_YAML)
    print("dvc.yaml: code deps rewritten; review with git diff dvc.yaml")
    return 0


if __name__ == "__main__":
    sys.exit(main())
