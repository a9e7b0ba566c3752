"""People's demonstrations (`taskseq serve`) as a data source: read by the same validator as every log.

A folder with no log yet is a valid, empty source: the pipeline runs the
same with it as without it. A file with a problem is reported on stderr and
left out, where it is (`ingest.load_people_logs`); the others are used.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from .ingest import dataset_summary, load_people_logs

EMPTY = {"environments": 0, "scenarios": 0, "sequences": 0, "steps": 0}


def people_records(folder: Path | str) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Every record of the folder's usable logs, checked as `taskseq ingest --people` checks them, and their
    counts; each file left out is named on stderr with its problem."""
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"{folder}: no such folder of people's demonstrations (it may be empty)")
    records, summary = [], dict(EMPTY)
    if any(folder.glob("*.jsonl")):
        tables, items, skipped = load_people_logs(folder)
        for err in skipped:
            print(f"left out {err.path} (the file stays where it is): {err}", file=sys.stderr)
        if items:
            records, summary = [item.record for item in items], dataset_summary(tables)
    assisted = [r for r in records if "corrected" in r]
    summary.update(
        participants=len({r["participant"] for r in records if "participant" in r}),
        assisted_sequences=len(assisted),
        corrected_sequences=sum(1 for r in assisted if r["corrected"]),
        corrections=sum(len(r["corrected"]) for r in assisted),
    )
    return records, summary
