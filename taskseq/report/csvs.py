"""Long CSV files of the stages' results: one row per observation, numbers with fixed decimals."""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from ..sim.primitives import ALL_PRIMITIVES

# Digits of the rates (%) in the noise and feedback files, per world and over worlds: the results page rounds them
# to one decimal, and from two it rounded twice (79.7467 to 79.75 to 79.8); from four it rounds as the exact rates do.
RATE_DECIMALS = 4


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


OUTCOME_COLUMNS = ("scenario", "task", "status", "prim_correct", "arg_correct", "goal_reached", "safe", "success",
                   "failure", "program")
SEQUENCE_COLUMNS = ("method", "fold", *OUTCOME_COLUMNS)


def outcome_row(s) -> dict[str, Any]:
    """One closed-loop program (a `SequenceOutcome`) as a table row."""
    return {"scenario": s.scenario_id, "task": s.task, "status": s.status, "prim_correct": s.prim_correct,
            "arg_correct": s.arg_correct, "goal_reached": s.goal_reached, "safe": s.safe, "success": s.success,
            "failure": s.failure, "program": " ".join(s.actions)}


def sequence_rows(results: list) -> list[dict[str, Any]]:
    """Every closed-loop program of a cross-validation, one row each (crossval `FoldResult`s)."""
    return [{"method": r.method, "fold": r.fold, **outcome_row(s)} for r in results for s in r.sequences or []]


STEP_COLUMNS = ("method", "fold", "scenario", "sequence", "step", "primitive", "prim_correct", "arg_correct")
# the figures of a method trained on one world and run in another (the scenes stages' transfer), per program kind
TRANSFER_COLUMNS = ("sequence_arg", "sequence_prim", "success", "goal_reached")


def step_rows(results: list, contexts: list, meta: list, predicts_args: dict[str, bool]) -> list[dict[str, Any]]:
    """Every teacher-forced step of a cross-validation, one row each: the demonstrated primitive and whether the
    method got the primitive, and the primitive with its arguments, right (empty for a method without arguments)."""
    rows = []
    for r in results:
        for i, y in zip(r.step_index, r.step_predictions, strict=True):
            x, m = contexts[i], meta[i]
            rows.append({"method": r.method, "fold": r.fold, "scenario": m.scenario_id, "sequence": m.sequence_id,
                         "step": m.step, "primitive": ALL_PRIMITIVES[x.gold[0]], "prim_correct": y[0] == x.gold[0],
                         "arg_correct": tuple(y) == tuple(x.gold) if predicts_args[r.method] else None})
    return rows


def read_csv_rows(path: Path) -> list[dict[str, str]]:
    """A stage's CSV as rows of strings; a missing file names the stage to run."""
    if not path.exists():
        raise FileNotFoundError(f"{path}: missing; run the stage that writes it for this world seed")
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))
