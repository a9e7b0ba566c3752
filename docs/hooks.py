"""Build-time hook of the documentation site: the Results page, made from `reports/` as it is.

The page is the pipeline's own `reports/summary.md`, followed by the Markdown tables the
`aggregate` and `crossval` stages write, each included as the file stands, and links to the
report files themselves. Nothing on it is copied by hand, so a build after `dvc repro` shows
that run's numbers. The DVC-cached per-program tables (the names DVC lists in the
`.gitignore` beside them) are left out: they are large, and a fresh clone does not have them
until `dvc repro` has run, while every other report is committed.
"""

from __future__ import annotations

from pathlib import Path

from mkdocs.config.defaults import MkDocsConfig
from mkdocs.structure.files import File, Files

REPORTS = Path(__file__).resolve().parents[1] / "reports"
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
                                               "scenes/transfer.md", "scenes/drawn/failures.md")))
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
    """Add the Results page and the report files it shows and links."""
    report_files = _report_files()
    files.append(File.generated(config, f"{SITE}/index.md", content=results_page(report_files)))
    for rel in report_files:
        files.append(File.generated(config, f"{SITE}/{rel.as_posix()}", abs_src_path=str(REPORTS / rel)))
    return files
