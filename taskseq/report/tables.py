"""Table I of the paper from cross-validation results: long CSV, Markdown, LaTeX (booktabs)."""

from __future__ import annotations

import csv
import io
from typing import Any

from ..sim.primitives import PRIMITIVES

COLUMNS = (*PRIMITIVES, "average", "sequence")
SHORT = {"follow_traj_circle": "traj\\_circle", "follow_traj_pour": "traj\\_pour"}


def table_rows(summary: dict[str, dict], labels: dict[str, str]) -> list[dict[str, Any]]:
    """Long form: one row per (method, column) with prim and arg in percent, None where undefined."""
    rows = []
    for name, entry in summary.items():
        for col in COLUMNS:
            if col == "sequence":
                prim, arg = entry.get("sequence/prim"), entry.get("sequence/arg")
            else:
                prim, arg = entry["steps"].get(f"{col}/prim"), entry["steps"].get(f"{col}/arg")
            rows.append({"method": labels.get(name, name), "column": col, "prim": prim, "arg": arg})
    return rows


def _fmt(v: float | None) -> str:
    return "-" if v is None else f"{v:.1f}"


def to_csv(rows: list[dict[str, Any]]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["method", "column", "prim", "arg"])
    for r in rows:
        w.writerow([r["method"], r["column"], "" if r["prim"] is None else f"{r['prim']:.2f}",
                    "" if r["arg"] is None else f"{r['arg']:.2f}"])
    return buf.getvalue()


def _grid(rows: list[dict[str, Any]]) -> tuple[list[str], dict[tuple[str, str, str], float | None]]:
    """Methods in order, and every cell's value by (method, column, prim|arg|prim_sd|arg_sd)."""
    methods = list(dict.fromkeys(r["method"] for r in rows))
    cell = {(r["method"], r["column"], k): r.get(k) for r in rows for k in ("prim", "arg", "prim_sd", "arg_sd")}
    return methods, cell


def _best(methods: list[str], cell: dict, col: str, k: str) -> float | None:
    vals = [cell[(m, col, k)] for m in methods if cell[(m, col, k)] is not None]
    return max(vals) if vals else None


def _row(methods: list[str], cell: dict, m: str, bold: str, pm: str = " ± ") -> list[str]:
    """Formatted prim and arg cells of method m (`mean{pm}sd` where rows carry a spread); `bold` is a
    format with {} for the best mean of a column."""
    vals = []
    for c in COLUMNS:
        for k in ("prim", "arg"):
            v, sd = cell[(m, c, k)], cell[(m, c, f"{k}_sd")]
            text = _fmt(v) + (f"{pm}{sd:.1f}" if v is not None and sd is not None else "")
            vals.append(bold.format(text) if v is not None and v == _best(methods, cell, c, k) else text)
    return vals


def to_markdown(rows: list[dict[str, Any]]) -> str:
    methods, cell = _grid(rows)
    head = "| method | " + " | ".join(f"{c} prim | {c} arg" for c in COLUMNS) + " |"
    sep = "|---|" + "---:|" * (2 * len(COLUMNS))
    lines = [head, sep] + [f"| {m} | " + " | ".join(_row(methods, cell, m, "**{}**")) + " |" for m in methods]
    return "\n".join(lines) + "\n"


def to_latex(rows: list[dict[str, Any]], caption: str) -> str:
    """A booktabs table laid out like the paper's Table I, the best value of each column in bold."""
    methods, cell = _grid(rows)
    spec = "l" + "cc" * len(COLUMNS)
    names = [SHORT.get(c, c.replace("_", "\\_")) for c in COLUMNS]
    out = [
        "\\begin{table*}",
        "\\centering",
        f"\\caption{{{caption}}}",
        "\\resizebox{\\linewidth}{!}{%",
        f"\\begin{{tabular}}{{@{{}}{spec}@{{}}}}",
        "\\toprule",
        " & " + " & ".join(f"\\multicolumn{{2}}{{c}}{{{n}}}" for n in names) + " \\\\",
        "".join(f"\\cmidrule(lr){{{2 + 2 * i}-{3 + 2 * i}}}" for i in range(len(COLUMNS))),
        " & " + " & ".join(["prim & arg"] * len(COLUMNS)) + " \\\\",
        "\\midrule",
    ]
    for m in methods:
        label = m.replace("_", "\\_")
        out.append(f"\\textit{{{label}}} & " + " & ".join(_row(methods, cell, m, "\\textbf{{{}}}", " $\\pm$ "))
                   + " \\\\")
    out += ["\\bottomrule", "\\end{tabular}}", "\\end{table*}"]
    return "\n".join(out) + "\n"
