"""Results over world seeds: each figure as the mean over seeds with its spread, per-seed values kept.

The spread is the sample standard deviation over world seeds (n - 1 in the
denominator; 0 with a single seed): how much a figure moves when the world is
drawn again, which is what a reader of one table needs to know.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..evaluate.failures import KINDS
from ..evaluate.metrics import headline_metrics
from ..methods import method_labels
from .csvs import read_csv_rows

HEADLINE = ("average_prim", "average_arg", "sequence_prim", "sequence_arg", "success", "goal_reached")


def mean_sd(values: Sequence[float]) -> tuple[float, float]:
    """Mean and sample standard deviation; raises on an empty list, sd 0 for one value."""
    if len(values) == 0:
        raise ValueError("mean_sd: no values")
    v = np.asarray(values, dtype=float)
    return float(v.mean()), float(v.std(ddof=1)) if len(v) > 1 else 0.0


def _num(path: Path, row: int, field: str, text: str) -> float | None:
    if text == "":
        return None
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"{path}: record {row}, field {field!r}: not a number: {text!r}") from None


def world_dirs(worlds: Path, seeds: Sequence[int]) -> dict[int, Path]:
    return {s: Path(worlds) / str(s) for s in seeds}


def table1_over_seeds(dirs: dict[int, Path]) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Per-seed long rows (with `world_seed`) and mean ± sd rows of Table I (prim, arg per method and column)."""
    per_seed: list[dict[str, Any]] = []
    for seed, d in dirs.items():
        path = d / "table1.csv"
        for i, r in enumerate(read_csv_rows(path), start=2):
            per_seed.append({"world_seed": seed, "method": r["method"], "column": r["column"],
                             "prim": _num(path, i, "prim", r["prim"]), "arg": _num(path, i, "arg", r["arg"])})
    keys = list(dict.fromkeys((r["method"], r["column"]) for r in per_seed))
    mean_rows = []
    for method, column in keys:
        mine = [r for r in per_seed if (r["method"], r["column"]) == (method, column)]
        row: dict[str, Any] = {"method": method, "column": column}
        for k in ("prim", "arg"):
            vals = [r[k] for r in mine if r[k] is not None]
            m, s = mean_sd(vals) if vals else (None, None)
            row[k], row[f"{k}_sd"] = m, s
        mean_rows.append(row)
    return per_seed, mean_rows


def json_over_seeds(dirs: dict[int, Path], name: str) -> dict[int, Any]:
    """Each seed's JSON result file `name`; a missing one names the file and the seed."""
    out = {}
    for seed, d in dirs.items():
        path = d / name
        if not path.exists():
            raise FileNotFoundError(f"{path}: missing; run the stage that writes it for world seed {seed}")
        out[seed] = json.loads(path.read_text())
    return out


def crossval_over_seeds(dirs: dict[int, Path]) -> dict[int, dict[str, Any]]:
    """Each seed's `crossval.json` (the per-method summary of its cross-validation)."""
    return json_over_seeds(dirs, "crossval.json")


def recipes_over_seeds(dirs: dict[int, Path]) -> dict[str, Any]:
    """Per method, the recipes succeeded per seed (with and without feedback), and their mean, sd and minimum."""
    recipes = json_over_seeds(dirs, "recipes.json")
    first = next(iter(recipes.values()))["methods"]
    by_method = {}
    for m in first:
        totals = {k: [r["methods"][m]["totals"][k] for r in recipes.values()]
                  for k in ("no_feedback", "feedback_first_step")}
        by_method[m] = {
            "recipes": first[m]["totals"]["recipes"],
            "per_seed": {str(s): r["methods"][m]["totals"] for s, r in recipes.items()},
            "mean": {k: mean_sd(v)[0] for k, v in totals.items()},
            "sd": {k: mean_sd(v)[1] for k, v in totals.items()},
            "min": {k: min(v) for k, v in totals.items()},
        }
    return {"methods": by_method}


def headline_over_seeds(summaries: dict[int, dict[str, Any]]) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Per (seed, method) rows of the headline figures, and per method their mean and sd over seeds."""
    rows = []
    for seed, summary in summaries.items():
        for method, figures in headline_metrics(summary).items():
            rows.append({"world_seed": seed, "method": method, **{k: figures.get(k) for k in HEADLINE}})
    means: dict[str, Any] = {}
    for method in dict.fromkeys(r["method"] for r in rows):
        mine = [r for r in rows if r["method"] == method]
        out = {}
        for k in HEADLINE:
            vals = [r[k] for r in mine if r[k] is not None]
            if vals:
                out[k], out[f"{k}_sd"] = mean_sd(vals)
                out[f"{k}_min"] = float(min(vals))
        means[method] = out
    return rows, means


def failures_over_seeds(summaries: dict[int, dict[str, Any]]) -> list[dict[str, Any]]:
    """Long rows (world_seed, method, task, kind, programs); task `all` sums the tasks."""
    rows = []
    for seed, summary in summaries.items():
        for method, entry in summary.items():
            if "programs" not in entry:
                continue
            rows += [{"world_seed": seed, "method": method, "task": "all", "kind": k, "programs": n}
                     for k, n in entry["programs"].items()]
            for task, t in entry.get("per_task", {}).items():
                rows += [{"world_seed": seed, "method": method, "task": task, "kind": k, "programs": n}
                         for k, n in t["programs"].items()]
    return rows


def failure_shares(rows: list[dict[str, Any]], method: str, task: str = "all") -> dict[str, tuple[float, float]]:
    """Per kind, the mean and sd over seeds of its share of the method's programs, in percent."""
    seeds = sorted({r["world_seed"] for r in rows if r["method"] == method and r["task"] == task})
    out = {}
    for kind in KINDS:
        shares = []
        for s in seeds:
            mine = [r for r in rows if (r["world_seed"], r["method"], r["task"]) == (s, method, task)]
            total = sum(r["programs"] for r in mine)
            shares.append(100.0 * sum(r["programs"] for r in mine if r["kind"] == kind) / max(total, 1))
        out[kind] = mean_sd(shares) if shares else (0.0, 0.0)
    return out


def curve_over_seeds(dirs: dict[int, Path], name: str, keys: Sequence[str],
                     values: Sequence[str]) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """A per-seed CSV (noise.csv, feedback.csv) stacked with `world_seed`, and its mean ± sd per key."""
    per_seed = []
    for seed, d in dirs.items():
        path = d / name
        for i, r in enumerate(read_csv_rows(path), start=2):
            per_seed.append({"world_seed": seed, **{k: r[k] for k in keys},
                             **{v: _num(path, i, v, r[v]) for v in values}})
    out = []
    for key in dict.fromkeys(tuple(r[k] for k in keys) for r in per_seed):
        mine = [r for r in per_seed if tuple(r[k] for k in keys) == key]
        row: dict[str, Any] = dict(zip(keys, key, strict=True))
        for v in values:
            row[v], row[f"{v}_sd"] = mean_sd([r[v] for r in mine])
        out.append(row)
    return per_seed, out


def failures_markdown(rows: list[dict[str, Any]], methods: list[str], n_seeds: int) -> str:
    """Share of programs of each kind (mean ± sd over world seeds, %), per method, then per task of the full model."""
    head = "| {} | " + " | ".join(k.replace("_", " ") for k in KINDS) + " |"
    sep = "|---|" + "---:|" * len(KINDS)
    out = [f"Programs by kind, % of each method's closed-loop programs, mean ± sd over {n_seeds} world seeds.", "",
           head.format("method"), sep]
    for m in methods:
        shares = failure_shares(rows, m)
        out.append(f"| {method_labels().get(m, m)} | " + " | ".join(f"{a:.1f} ± {s:.1f}" for a, s in shares.values())
                   + " |")
    if "full" in methods:
        out += ["", "The full model per task:", "", head.format("task"), sep]
        for task in sorted({r["task"] for r in rows if r["method"] == "full" and r["task"] != "all"}):
            shares = failure_shares(rows, "full", task)
            out.append(f"| {task} | " + " | ".join(f"{a:.1f} ± {s:.1f}" for a, s in shares.values()) + " |")
    return "\n".join(out) + "\n"


def headline_groups(means: dict[str, Any], noise: list[dict[str, Any]], feedback: list[dict[str, Any]],
                    recipes: dict[str, Any]) -> dict[str, Any]:
    """The figures a reader looks for first, mean over world seeds, grouped by experiment (`reports/metrics.json`).

    Closed-loop sequence accuracy (arg) of every method with its sd and success; the
    noise curve; feedback with one step and at every step; recipes succeeded (where there are any). The
    other figures and their spreads stay in the files they come from.
    """
    return {
        "crossval": {m: {k: f[k] for k in ("sequence_arg", "sequence_arg_sd", "success") if k in f}
                     for m, f in means.items() if "sequence_arg" in f},
        "noise": {m: {f"rate_{float(r['rate']):g}": r["sequence_arg"] for r in noise if r["method"] == m}
                  for m in dict.fromkeys(r["method"] for r in noise)},
        "feedback": {m: {f"top{r['k']}_n{r['n']}": r["sequence_arg"] for r in feedback
                         if r["method"] == m and r["n"] in ("1", "all")}
                     for m in dict.fromkeys(r["method"] for r in feedback)},
        **({"recipes": {m: r["mean"] for m, r in recipes["methods"].items()}} if recipes else {}),
    }


def plot_columns(rows: list[dict[str, Any]], x: str, series: Sequence[str], value: str,
                 labels: dict[str, str]) -> tuple[list[str], list[dict[str, Any]]]:
    """Long rows as one column per series (e.g. per method and k) against `x`: one line each in `dvc plots`."""
    def name(r: dict[str, Any]) -> str:
        return " ".join(labels.get(str(r[k]), f"{k} {r[k]}") for k in series)

    columns = list(dict.fromkeys(name(r) for r in rows))
    wide: dict[Any, dict[str, Any]] = {}
    for r in rows:
        wide.setdefault(r[x], {x: r[x]})[name(r)] = r[value]
    return [x, *columns], list(wide.values())
