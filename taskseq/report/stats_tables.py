"""The intervals and paired comparisons of `taskseq.report.stats` as CSV and Markdown tables."""

from __future__ import annotations

from collections.abc import Sequence

from .csvs import csv_text
from .stats import FIGURES, TEST, Comparison, Interval

HEADINGS = {"average_prim": "avg prim", "average_arg": "avg arg", "sequence_prim": "seq prim",
            "sequence_arg": "seq arg", "success": "success"}
ROLES = {"paper": "the paper's model", "baseline": "the best baseline", "shipped": "the shipped planner"}


def bootstrap_text(resamples: int, seed: int, confidence: float, n_worlds: int) -> str:
    """One paragraph naming how the intervals were computed."""
    return (f"{100 * confidence:g}% percentile intervals from a two-level (cluster) bootstrap: {resamples} resamples "
            f"(seed {seed}), each drawing the {n_worlds} world seeds with replacement, then each drawn world's "
            "scenarios with replacement (a scenario with all its steps), and recomputing the figure as Table I does "
            "(each world's pooled rate, averaged over the drawn worlds).")


def test_text(confidence: float) -> str:
    """One paragraph naming the paired test and the interval of a difference."""
    return ("Programs of two methods are paired by world and scenario. Test: " + TEST + ", `scipy.stats.binomtest`; "
            "p-values also Holm-adjusted over every comparison of this table. The difference's "
            f"{100 * confidence:g}% interval comes from the bootstrap resamples of `table1_ci.md` (the same draws for "
            "both methods).")


def intervals_csv(rows: Sequence[Interval]) -> str:
    return csv_text(["method", "figure", "value", "low", "high"], (r.__dict__ for r in rows),
                    {"value": 2, "low": 2, "high": 2})


def intervals_markdown(rows: Sequence[Interval], labels: dict[str, str], method: str, confidence: float) -> str:
    """Table I's figures with their intervals, a row per method in the tables' order."""
    cell = {(r.method, r.figure): f"{r.value:.1f} [{r.low:.1f}, {r.high:.1f}]" for r in rows}
    present = set(m for m, _ in cell)
    methods = [m for m in labels if m in present] + sorted(present - set(labels))
    out = [f"# Table I with {100 * confidence:g}% confidence intervals", "", method, "",
           "| method | " + " | ".join(HEADINGS[f] for f in FIGURES) + " |", "|---|" + "---:|" * len(FIGURES)]
    out += [f"| {labels.get(m, m)} | " + " | ".join(cell.get((m, f), "-") for f in FIGURES) + " |" for m in methods]
    return "\n".join(out) + "\n"


def comparisons_csv(rows: Sequence[Comparison]) -> str:
    columns = ["method", "against", "role", "figure", "rate", "against_rate", "difference", "low", "high", "better",
               "worse", "pairs", "p_value", "p_holm"]
    return csv_text(columns, (r.__dict__ for r in rows),
                    {"rate": 2, "against_rate": 2, "difference": 2, "low": 2, "high": 2})


def p_text(p: float) -> str:
    """A p-value as the tables print it: two significant digits, or "< 1e-4"."""
    return f"{p:.2g}" if p >= 1e-4 else "< 1e-4"


def comparisons_markdown(rows: Sequence[Comparison], labels: dict[str, str], method: str) -> str:
    """Each added method against the paper's model, the best baseline and (when given) the shipped planner, a row
    per figure."""
    out = ["# Paired comparisons", "", method, "",
           "| method | against | figure | method % | against % | difference [interval] | only method right | "
           "only other right | p | p (Holm) |", "|---|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        against = f"{labels.get(r.against, r.against)} ({ROLES.get(r.role, r.role)})"
        out.append(f"| {labels.get(r.method, r.method)} | {against} | {HEADINGS[r.figure]} | {r.rate:.1f} | "
                   f"{r.against_rate:.1f} | {r.difference:+.1f} [{r.low:+.1f}, {r.high:+.1f}] | {r.better} | "
                   f"{r.worse} | {p_text(r.p_value)} | {p_text(r.p_holm)} |")
    return "\n".join(out) + "\n"
