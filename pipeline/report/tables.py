"""Table I of the paper from cross-validation results: long CSV, Markdown, LaTeX (booktabs)."""

from __future__ import annotations

import csv
import io
from typing import Any

import numpy as np

from ..sim.primitives import ALL_PRIMITIVES, PRIMITIVES

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


def confusion_png(matrix: np.ndarray, path: str, title: str) -> None:
    """Row-normalised confusion matrix of the primitives (and done) as a PNG."""
    import matplotlib

    matplotlib.use("Agg")  # files only, no screen
    import matplotlib.pyplot as plt

    matrix = np.asarray(matrix, dtype=float)
    rates = matrix / np.maximum(matrix.sum(axis=1, keepdims=True), 1)
    fig, ax = plt.subplots(figsize=(6.4, 5.6), dpi=120)
    im = ax.imshow(rates, cmap="Blues", vmin=0, vmax=1)
    labels = list(ALL_PRIMITIVES)
    ax.set_xticks(range(len(labels)), labels, rotation=45, ha="right", fontsize=8)
    ax.set_yticks(range(len(labels)), labels, fontsize=8)
    for i in range(len(labels)):
        for j in range(len(labels)):
            if matrix[i, j]:
                ax.text(j, i, f"{rates[i, j]:.2f}", ha="center", va="center", fontsize=6,
                        color="white" if rates[i, j] > 0.5 else "black")
    ax.set_xlabel("predicted")
    ax.set_ylabel("demonstrated")
    ax.set_title(title, fontsize=9)
    fig.colorbar(im, ax=ax, fraction=0.046)
    fig.tight_layout()
    fig.savefig(path, metadata={"Software": None})
    plt.close(fig)


def line_plot_png(series: dict[str, tuple[list[float], list[float], list[float] | None]], path: str, title: str,
                  xlabel: str, ylabel: str, xticks: list[float] | None = None, xticklabels: list[str] | None = None,
                  reference: dict[str, tuple[list[float], list[float]]] | None = None) -> None:
    """Lines with optional error bars (x, y, spread per series), and dashed reference lines (the paper's)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.6, 3.8), dpi=120)
    for label, (x, y, err) in series.items():
        ax.errorbar(x, y, yerr=err, marker="o", capsize=3, label=label)
    for label, (x, y) in (reference or {}).items():
        ax.plot(x, y, linestyle="--", marker="x", alpha=0.7, label=label)
    if xticks is not None:
        ax.set_xticks(xticks, xticklabels)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_ylim(0, 100)
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, metadata={"Software": None})
    plt.close(fig)
