"""The documentation site builds strictly, covers the whole package, and the README agrees with reports/.

`mkdocs build --strict` turns every warning into a failure: a link to a missing page or
heading, a page left out of the navigation, a `:::` block naming a module that no longer
exists, a docstring mkdocstrings cannot parse. The Results page is generated from
`reports/` by docs/hooks.py, so the build also proves it can be made from what git holds.
"""

import csv
import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
README = ROOT / "README.md"


def _hooks():
    spec = importlib.util.spec_from_file_location("docs_hooks", DOCS / "hooks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_site_builds_without_a_warning(tmp_path):
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}  # the theme's end-of-life notice, not a build problem
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                          cwd=ROOT, env=env, capture_output=True, text=True)
    log = done.stdout + done.stderr
    assert done.returncode == 0, log
    assert "WARNING" not in log, log
    results = (tmp_path / "site" / "results" / "index.html").read_text()
    assert "Table I per primitive" in results
    api = (tmp_path / "site" / "api" / "learn" / "index.html").read_text()
    assert "CuttingPlaneSSVM" in api and "StepScorer" in api
    cli = (tmp_path / "site" / "reference" / "cli" / "index.html").read_text()
    assert "taskseq fold_models" in cli and "--selection" in cli
    for page in (tmp_path / "site").rglob("*.html"):
        assert "<!-- generated:" not in page.read_text(), f"{page}: a generated table was not filled in"


def test_the_results_page_holds_the_reports_as_they_are():
    hooks = _hooks()
    reports = ROOT / "reports"
    page = hooks.results_page(hooks._report_files())
    for name in ("summary.md", "table1.md", "failures.md"):
        assert (reports / name).read_text().strip() in page, name
    assert "crossval_sequences.csv" not in page  # DVC-cached, absent from a fresh clone


def test_the_teach_page_shows_the_teach_reports_as_they_are():
    """docs/teach.md's figures are the `teach` stage's reports, filled in at build time, never rows typed in."""
    hooks = _hooks()
    text = hooks.teach_results()
    rows = [line for line in (ROOT / "reports" / "teach" / "teach.md").read_text().splitlines() if line.startswith("|")]
    assert rows and all(row in text for row in rows)
    for seed in (ROOT / "reports" / "teach" / "teach_seeds.csv").read_text().splitlines()[1:]:
        world, k, held_out, arg = seed.split(",")[:4]
        assert f"| {world} | {held_out} |" in text and f" {arg} |" in text
    page = (DOCS / "teach.md").read_text()
    assert "<!-- generated: teach-results -->" in page
    assert not any(row in page for row in rows[2:])


def test_every_module_has_its_api_reference():
    """A subpackage's page renders its modules (show_submodules); top-level modules each need a block."""
    blocks = set()
    for page in (DOCS / "api").glob("*.md"):
        blocks |= set(re.findall(r"^::: (taskseq(?:\.\w+)*)\s*$", page.read_text(), re.M))
    package = ROOT / "taskseq"
    wanted = {f"taskseq.{p.name}" for p in package.iterdir() if (p / "__init__.py").is_file()}
    wanted |= {f"taskseq.{p.stem}" for p in package.glob("*.py") if p.stem != "__init__"}
    assert not wanted - blocks, f"missing from docs/api/: {sorted(wanted - blocks)}"
    assert not blocks - wanted - {"taskseq"}, f"docs/api/ names what taskseq/ lacks: {sorted(blocks - wanted)}"


def test_the_readme_is_a_short_front_page():
    text = README.read_text()
    assert len(text.splitlines()) < 200
    install = ("pip install -c requirements.lock uv && "
               "uv pip install --compile-bytecode -c requirements.lock -e '.[dev]'")
    for command in (f"{install} && dvc repro", f"{install} && python -m pytest -q"):
        assert command in text
    for target in re.findall(r"\]\(([^)#:]+)(?:#[^)]*)?\)", text):  # relative links: files of the repository
        assert (ROOT / target).exists(), f"README links to {target}, which does not exist"


VEIL_SECTION = "## People's demonstrations (VEIL-500)"


def _result_rows(text: str) -> list[str]:
    return [line for line in text.splitlines() if re.match(r"\| [^-|][^|]* \| \S*\d", line)]


def test_the_readme_results_are_rows_of_the_reports():
    """Rows before the people's-demonstrations section come from reports/summary.md, rows in it from
    reports/veil/tables.md: a README figure is always one the pipeline wrote."""
    text = README.read_text()
    assert VEIL_SECTION in text
    paper_world, _, rest = text.partition(VEIL_SECTION)
    veil_section = rest.split("\n## ", 1)[0]
    for rows, report in ((_result_rows(paper_world), "summary.md"), (_result_rows(veil_section), "veil/tables.md")):
        assert rows, f"the README shows no result rows from reports/{report}"
        lines = (ROOT / "reports" / report).read_text().splitlines()
        for row in rows:
            assert row in lines, f"README row not in reports/{report}: {row}"


def test_every_subcommand_is_on_the_cli_reference_page_with_every_option():
    import argparse

    from taskseq.cli import build_parser

    page = _hooks().cli_page()
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    for name, command in sub.choices.items():
        assert f"### taskseq {name} " in page, name
        for action in command._actions:
            for option in action.option_strings:
                assert option in page, f"{name} {option}"


def test_every_setting_of_params_yaml_is_on_the_parameters_page():
    import yaml

    page = _hooks().params_page()
    params = yaml.safe_load((ROOT / "params.yaml").read_text())
    for section, values in params.items():
        for key in values:
            assert f"`{section}.{key}`" in page, f"{section}.{key}"


def test_the_generated_tables_read_the_reports():
    hooks = _hooks()
    for name, make in hooks.GENERATED.items():
        assert "has not been written yet" not in make() and "holds no report yet" not in make(), name
    bench = (ROOT / "reports" / "bench.json").read_text()
    first = __import__("json").loads(bench)["train"]["runs"][0]
    assert f"{first['seconds']:.2f}" in hooks.bench_training()
    for report in (ROOT / "reports" / "mutation").glob("*.md"):
        assert f"`{report.stem}`" in hooks.mutation_scores()
    with (ROOT / "reports" / "failures.csv").open(newline="") as fh:
        exact = {(r["world_seed"], r["method"], r["task"]): r["programs"] for r in csv.DictReader(fh)
                 if r["kind"] == "exact"}
    stir = " | ".join(f"{exact[s, 'full', 'stir']} / {exact[s, 'relations', 'stir']}" for s in ("0", "3", "7"))
    assert f"| {stir} |" in hooks.exact_by_task()
    assert "| ours - full | " in hooks.failure_kinds() and "| chance |" not in hooks.failure_kinds()
    markers = set()
    for page in DOCS.rglob("*.md"):
        markers |= set(hooks.MARKER.findall(page.read_text()))
    assert markers == set(hooks.GENERATED), "a generated table that no page shows, or a marker without a table"


def test_the_layout_page_lists_every_module_and_names_only_paths_that_exist():
    hooks = _hooks()
    layout = hooks.package_layout()
    package = ROOT / "taskseq"
    for module in package.rglob("*.py"):
        if "__pycache__" in module.parts:
            continue
        rel = module.relative_to(package)
        inside = rel.relative_to(rel.parts[0]).as_posix() if len(rel.parts) > 1 else ""
        shown = f"`taskseq/{rel.as_posix()}`" if len(rel.parts) == 1 else f"`{inside}`"
        assert module.name == "__init__.py" or shown in layout, rel
    for sub in package.iterdir():
        if (sub / "__init__.py").is_file():
            assert f"### `taskseq/{sub.name}/`\n\n\n" not in layout, f"taskseq/{sub.name}/ has no summary: " \
                "give its __init__.py a docstring or docs/hooks.py's SUBPACKAGES an entry"
    page = (DOCS / "layout.md").read_text()
    around = page[page.index("## Around the package"):page.index("## Libraries")]
    for cell in re.findall(r"^\| ([^|]+) \|", around, re.M)[1:]:  # the table's first column, header left out
        for path in re.findall(r"`([^`]+)`", cell):
            assert (ROOT / path).exists(), f"docs/layout.md names {path}, which does not exist"
    scripts = around[around.index("`scripts/`"):].split("\n")[0]
    for script in (ROOT / "scripts").iterdir():
        if script.suffix in {".py", ".toml"}:
            assert f"`{script.name}`" in scripts, f"docs/layout.md does not name scripts/{script.name}"


# "about 20 minutes", "4 min", "1,057 s", "1 h 36 min": a duration as a reader would quote it
_DURATION = re.compile(r"\b(\d+(?:[.,]\d+)?(?: to \d+(?:[.,]\d+)?)?)\s*(h|hours?|min|minutes?|s|seconds?)\b")
_UNIT = {"h": "h", "hour": "h", "hours": "h", "min": "min", "minute": "min", "minutes": "min",
         "s": "s", "second": "s", "seconds": "s"}


def _quick_start_figures(text: str) -> dict[str, set[tuple[str, str]]]:
    """The durations each quick-start command is said to take, keyed by the command's last word.

    The quick start of README.md and of docs/index.md introduce the same two commands, each
    with a sentence saying how long it takes. A figure belongs to the command whose code block
    follows its sentence, so the two pages can be compared command by command.
    """
    section = text[text.index("## Quick start"):]
    section = section[:section.index("\n## ", 4)]
    figures: dict[str, set[tuple[str, str]]] = {}
    prose = ""
    for chunk in re.split(r"(```bash\n.*?```)", section, flags=re.S):
        if chunk.startswith("```bash"):
            command = chunk.strip("`\n").split()[-1]  # `repro` or `-q`
            figures[command] = {(n, _UNIT[u]) for n, u in _DURATION.findall(prose)}
            prose = ""
        else:
            prose = chunk
    return figures


def test_readme_and_the_sites_front_page_give_the_same_running_times():
    """README.md and docs/index.md both say how long the install and run, and the tests, take.

    They drifted apart once (half an hour against 15 minutes). Each page must state a time for
    each command, and the same one.
    """
    readme = _quick_start_figures(README.read_text())
    index = _quick_start_figures((DOCS / "index.md").read_text())
    assert set(readme) == set(index) == {"repro", "-q"}, (readme, index)
    for command in readme:
        assert readme[command], f"README.md's quick start gives no time for the command ending {command}"
        assert readme[command] == index[command], \
            f"the command ending {command}: README.md says {readme[command]}, docs/index.md {index[command]}"


def test_the_duration_reader_sees_a_disagreement():
    page = ("## Quick start\n\nRun it (about {} on 2 cores):\n\n```bash\ndvc repro\n```\n\n"
            "Tests:\n\n```bash\npytest -q\n```\n\n## Next\n")
    assert _quick_start_figures(page.format("20 minutes")) == {"repro": {("20", "min")}, "-q": set()}
    assert _quick_start_figures(page.format("20 min")) == _quick_start_figures(page.format("20 minutes"))
    assert _quick_start_figures(page.format("half an hour")) != _quick_start_figures(page.format("20 min"))
    assert _quick_start_figures(page.format("15 min")) != _quick_start_figures(page.format("20 min"))


def test_the_project_files_say_how_to_cite_and_license_it():
    import tomllib

    import yaml

    citation = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    assert citation["cff-version"] == "1.2.0" and citation["type"] == "software"
    paper = citation["references"][0]
    assert paper["title"].startswith("Synthesizing Manipulation Sequences for Under-Specified Tasks")
    assert [a["family-names"] for a in paper["authors"]] == ["Sung", "Selman", "Saxena"] and paper["year"] == 2014
    assert "BSD 3-Clause" in (ROOT / "LICENSE").read_text()
    assert tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["license"] == {"file": "LICENSE"}
    readme = README.read_text()
    assert "(LICENSE)" in readme and "(CITATION.cff)" in readme


_DATED = re.compile(r"\b(?:\d{1,2} )?(?:January|February|March|April|June|July|August|September|October|November|"
                    r"December) 20\d\d\b|\b20\d\d-\d\d-\d\d\b|Later that day|/work/")


def test_the_docs_and_docstrings_hold_no_dated_run_log():
    """History goes to CHANGELOG.md; pages and docstrings say how things are (generated tables may show dates)."""
    paths = [README, *DOCS.rglob("*.md"), *(ROOT / "taskseq").rglob("*.py")]
    found = [f"{p.relative_to(ROOT)}: {m.group(0)}" for p in paths for m in _DATED.finditer(p.read_text())]
    assert not found, found


def test_the_model_page_names_every_family_and_the_papers_short_name_for_it():
    from taskseq.learn.mrf import ALIASES, CLIQUE_FAMILIES, EDGE_FAMILIES

    rows = re.findall(r"^\| `(\w+)` \| (\w+) \| (edge|clique) \|", (DOCS / "model.md").read_text(), re.M)
    assert {family: short for family, short, _ in rows} == ALIASES
    assert tuple(family for family, _, kind in rows if kind == "edge") == EDGE_FAMILIES
    assert tuple(family for family, _, kind in rows if kind == "clique") == CLIQUE_FAMILIES
