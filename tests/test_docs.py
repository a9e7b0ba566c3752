"""The documentation site builds strictly, covers the whole package, and the README agrees with reports/.

`mkdocs build --strict` turns every warning into a failure: a link to a missing page or
heading, a page left out of the navigation, a `:::` block naming a module that no longer
exists, a docstring mkdocstrings cannot parse. The Results page is generated from
`reports/` by docs/hooks.py, so the build also proves it can be made from what git holds.
"""

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


def test_the_results_page_holds_the_reports_as_they_are():
    hooks = _hooks()
    reports = ROOT / "reports"
    page = hooks.results_page(hooks._report_files())
    for name in ("summary.md", "table1.md", "failures.md"):
        assert (reports / name).read_text().strip() in page, name
    assert "crossval_sequences.csv" not in page  # DVC-cached, absent from a fresh clone


def test_every_module_has_its_api_reference():
    """A subpackage's page renders its modules (show_submodules); top-level modules each need a block."""
    blocks = set()
    for page in (DOCS / "api").glob("*.md"):
        blocks |= set(re.findall(r"^::: (pipeline(?:\.\w+)*)\s*$", page.read_text(), re.M))
    package = ROOT / "taskseq"
    wanted = {f"taskseq.{p.name}" for p in package.iterdir() if (p / "__init__.py").is_file()}
    wanted |= {f"taskseq.{p.stem}" for p in package.glob("*.py") if p.stem != "__init__"}
    assert not wanted - blocks, f"missing from docs/api/: {sorted(wanted - blocks)}"
    assert not blocks - wanted - {"taskseq"}, f"docs/api/ names what taskseq/ lacks: {sorted(blocks - wanted)}"


def test_the_readme_is_a_short_front_page():
    text = README.read_text()
    assert len(text.splitlines()) < 200
    for command in ("pip install -c requirements.lock -e '.[dev]' && dvc repro",
                    "pip install -c requirements.lock -e '.[dev]' && python -m pytest -q"):
        assert command in text
    for target in re.findall(r"\]\(([^)#:]+)(?:#[^)]*)?\)", text):  # relative links: files of the repository
        assert (ROOT / target).exists(), f"README links to {target}, which does not exist"


def test_the_readme_results_are_rows_of_the_summary():
    summary = (ROOT / "reports" / "summary.md").read_text().splitlines()
    rows = [line for line in README.read_text().splitlines() if re.match(r"\| [^-|][^|]* \| \d", line)]
    assert rows, "the README shows no result rows"
    for row in rows:
        assert row in summary, f"README row not in reports/summary.md: {row}"
