"""Long CSV files of the stages' results: one row per observation, numbers with fixed decimals."""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable, Sequence
from typing import Any


def _cell(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, bool):
        return str(int(v))
    if isinstance(v, float):
        return f"{v:.8g}"
    return str(v)


def csv_text(columns: Sequence[str], rows: Iterable[dict[str, Any]], decimals: dict[str, int] | None = None) -> str:
    """A CSV with a header; `decimals` fixes the digits of some float columns, others print as `%.8g`."""
    decimals = decimals or {}
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for r in rows:
        w.writerow([f"{r[c]:.{decimals[c]}f}" if c in decimals and r[c] is not None else _cell(r[c])
                    for c in columns])
    return buf.getvalue()


SEQUENCE_COLUMNS = ("method", "fold", "scenario", "task", "status", "prim_correct", "arg_correct", "goal_reached",
                    "safe", "success", "failure", "program")


def sequences_csv(results: list) -> str:
    """Every closed-loop program of a cross-validation, one row each (crossval `FoldResult`s)."""
    rows = ({"method": r.method, "fold": r.fold, "scenario": s.scenario_id, "task": s.task, "status": s.status,
             "prim_correct": s.prim_correct, "arg_correct": s.arg_correct, "goal_reached": s.goal_reached,
             "safe": s.safe, "success": s.success, "failure": s.failure, "program": " ".join(s.actions)}
            for r in results for s in r.sequences or [])
    return csv_text(SEQUENCE_COLUMNS, rows)
