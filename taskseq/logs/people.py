"""People's demonstrations (`taskseq serve`) as a data source: read by the same validator as every log.

A folder with no log yet is a valid, empty source: the pipeline runs the
same with it as without it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .ingest import dataset_summary, load_logs

EMPTY = {"environments": 0, "scenarios": 0, "sequences": 0, "steps": 0}


def people_records(folder: Path | str) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Every record of the folder's logs, checked as `taskseq ingest` checks them, and their counts."""
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"{folder}: no such folder of people's demonstrations (it may be empty)")
    if not any(folder.glob("*.jsonl")):
        records, summary = [], dict(EMPTY)
    else:
        tables, items = load_logs(folder)
        records, summary = [item.record for item in items], dataset_summary(tables)
    assisted = [r for r in records if "corrected" in r]
    summary.update(
        participants=len({r["participant"] for r in records if "participant" in r}),
        assisted_sequences=len(assisted),
        corrected_sequences=sum(1 for r in assisted if r["corrected"]),
        corrections=sum(len(r["corrected"]) for r in assisted),
    )
    return records, summary
