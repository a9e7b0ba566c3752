"""reports/summary.md: every result of the pipeline next to the paper's figure."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

from ..evaluate.failures import FAILURES
from . import paper
from .seeds import failure_shares


def _f(v: Any) -> str:
    return "-" if v is None else (f"{v:.1f}" if isinstance(v, float) else str(v))


def _load(path: Path) -> Any:
    return json.loads(path.read_text()) if path.exists() else None


def _pm(entry: dict[str, Any], key: str) -> str:
    v = entry.get(key)
    return "-" if v is None else f"{v:.1f} ± {entry.get(f'{key}_sd', 0.0):.1f}"


def _failure_rows(reports: Path) -> list[dict[str, Any]]:
    path = reports / "failures.csv"
    if not path.exists():
        return []
    with path.open(newline="") as fh:
        return [{**r, "world_seed": int(r["world_seed"]), "programs": int(r["programs"])} for r in csv.DictReader(fh)]


def build_summary(reports: Path, labels: dict[str, str]) -> str:
    out = ["# Results", "",
           "Every number below comes from `dvc repro` (files in `reports/`). Each is the mean ± sample",
           "standard deviation over the world seeds of `params.yaml` (independent draws of the simulated benchmark);",
           "per-seed values are in `reports/*_seeds.csv` and `reports/worlds/<seed>/`. The paper's figures are",
           "Sung, Selman and Saxena's, on their own 127 sequences from OpenRAVE.", ""]
    ds = _load(reports / "dataset.json")
    if ds:
        seeds = list(ds)
        out += ["## Dataset", "", "| figure | paper | " + " | ".join(f"seed {s}" for s in seeds) + " |",
                "|---|---:|" + "---:|" * len(seeds)]
        out += [f"| {k} | {v} | " + " | ".join(str(ds[s].get(k)) for s in seeds) + " |"
                for k, v in paper.DATASET.items()]
        out.append("")
    sel = _load(reports / "selection.json")
    if sel:
        if "settings" not in sel:
            raise ValueError(f"{reports / 'selection.json'}: no `settings` (each method's C): a file of an older "
                             "format; run `taskseq select` again")
        chosen = sel["settings"]
        tried = "; ".join(f"{labels.get(m, m)} C = {c['C']:g} (" + ", ".join(
            f"{r['C']:g}: {r['sequence_arg']:.1f}" for r in c["candidates"]) + ")" for m, c in chosen.items())
        out += ["## Settings", "", f"Each MRF method's C, chosen by 6-fold cross-validation on the development "
                f"world (seed {sel['dev_seed']}, never reported), by {sel['criterion']}; the paper's ablations take "
                f"the full model's (sequence arg per C tried: {tried})."]
        if "methods" in sel:
            ranked = ", ".join(f"{labels.get(r['method'], r['method'])} {r['sequence_arg']:.1f}"
                               for r in sel["methods"])
            out.append(f"Each at its C, the same folds rank the MRF methods by sequence arg ({ranked}); the shipped "
                       f"planner (`models/mrf.npz`, what `taskseq plan` runs) is the first, "
                       f"{labels.get(sel['method'], sel['method'])}.")
        out.append("")
    metrics = _load(reports / "crossval_means.json")
    if metrics:
        out += ["## Table I (6-fold cross-validation, mean ± sd over world seeds)", "",
                "| method | avg prim | paper | avg arg | paper | seq prim | paper | seq arg | paper | success |",
                "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
        for name in labels:
            if name not in metrics:
                continue
            e, label = metrics[name], labels[name]
            p = paper.TABLE1.get(label, (None,) * 4)
            out.append(f"| {label} | {_pm(e, 'average_prim')} | {_f(p[0])} | {_pm(e, 'average_arg')} | {_f(p[1])} | "
                       f"{_pm(e, 'sequence_prim')} | {_f(p[2])} | {_pm(e, 'sequence_arg')} | {_f(p[3])} | "
                       f"{_pm(e, 'success')} |")
        out += ["", "Per primitive: `reports/table1.md` and `reports/table1.tex`; per seed: "
                "`reports/table1_seeds.csv`, `reports/crossval_seeds.csv`.", ""]
    ci, comparisons = reports / "table1_ci.md", reports / "comparisons.md"
    if ci.exists() and comparisons.exists():  # the stats stage's tables, one heading level down
        out += ["## Confidence intervals and paired comparisons", ""]
        for path in (ci, comparisons):
            out += [("##" + line if line.startswith("# ") else line) for line in path.read_text().splitlines()]
            out.append("")
    failures = _failure_rows(reports)
    if failures and any(r["method"] == "full" for r in failures):
        shares = failure_shares(failures, "full")
        kinds = sorted(((v[0], k) for k, v in shares.items() if k in FAILURES and v[0] > 0), reverse=True)[:3]
        lead = "; ".join(f"{k.replace('_', ' ')} {v:.1f}%" for v, k in kinds)
        out += ["## Why programs fail", "", f"Leading failure kinds of the full model (share of its programs): {lead}. "
                f"Exact matches {shares['exact'][0]:.1f}%, other successful programs "
                f"{shares['other_success'][0]:.1f}%. Per method and task: `reports/failures.md`.", ""]
    noise = reports / "noise.csv"
    if noise.exists():
        rows = list(csv.DictReader(noise.open()))
        out += ["## Attribute noise (sequence arg, mean ± sd over world seeds)", "",
                "| method | flip rate | here | paper |", "|---|---:|---:|---:|"]
        for r in rows:
            rate = float(r["rate"])
            out.append(f"| {labels.get(r['method'], r['method'])} | {rate:g} | {float(r['sequence_arg']):.1f} ± "
                       f"{float(r['sequence_arg_sd']):.1f} | {_f(paper.NOISE.get(rate))} |")
        out += ["", "![noise](noise.png)", ""]
    fb = reports / "feedback.csv"
    if fb.exists():
        rows = list(csv.DictReader(fb.open()))
        out += ["## Human feedback (sequence arg, mean ± sd over world seeds)", "",
                "| method | top k | steps with feedback | here | paper |", "|---|---:|---:|---:|---:|"]
        for r in rows:
            out.append(f"| {labels.get(r['method'], r['method'])} | {r['k']} | {r['n']} | "
                       f"{float(r['sequence_arg']):.1f} ± {float(r['sequence_arg_sd']):.1f} | "
                       f"{_f(paper.FEEDBACK.get((int(r['k']), r['n'])))} |")
        out += ["", "![feedback](feedback.png)", ""]
    rec = _load(reports / "recipes.json")
    if rec:
        out += ["## Recipes (environments held out from training; successes per world seed)", "",
                "| method | feedback | here | paper |", "|---|---|---:|---:|"]
        for m, r in rec["methods"].items():
            n = r["recipes"]
            for key, what in (("no_feedback", "none"), ("feedback_first_step", "at the start of each program")):
                cells = ", ".join(f"{t[key]}/{n}" for t in r["per_seed"].values())
                out.append(f"| {labels.get(m, m)} | {what} | {cells} | {paper.RECIPES[key]}/12 |")
        out.append("")
    out += _scenes(reports, metrics or {}, labels)
    train = _load(reports / "train.json")
    bench = _load(reports / "bench.json")
    if train or bench:
        out += ["## Training and speed", ""]
        if train:
            shipped = labels.get(train.get("method", "full"), train.get("method", "full"))
            out.append(f"Shipped planner ({shipped}) on all steps: {train['iterations']} cutting-plane iterations "
                       f"(last fit), relative gap "
                       f"{train['relative_gap']:.2g}, teacher-forced training accuracy "
                       f"{train['train_average_prim']:.1f}% (prim), {train['train_average_arg']:.1f}% (arg).")
        if bench:
            timing = "; ".join(f"{r.get('features', 'full')} model {r['seconds']:.1f} s to a relative gap of "
                               f"{r['tol']:g} ({r['iterations']} iterations, {_slacks(r['n_slacks'])})"
                               for r in bench["train"]["runs"])
            latency = ", ".join(f"{v['inference_ms']:.2f} ms at {n} objects"
                                for n, v in sorted(bench["latency"].items(), key=lambda item: int(item[0])))
            out.append(f"`taskseq bench` (its own run, {bench['machine']['cpus']} CPUs, C = {bench['train']['C']:g}): "
                       f"training {timing}; "
                       f"per-step inference {latency}.")
        out.append("")
    return "\n".join(out)


def _scenes(reports: Path, paper_shaped: dict[str, Any], labels: dict[str, str]) -> list[str]:
    """Rooms never seen in training: Table I with whole rooms held out, paper-shaped and drawn, and the transfer."""
    held_out = _load(reports / "scenes" / "paper" / "crossval_means.json") or {}
    drawn = _load(reports / "scenes" / "drawn" / "crossval_means.json") or {}
    if not held_out and not drawn:
        return []
    transfer = _load(reports / "scenes" / "transfer.json") or {}
    worlds = _load(reports / "scenes" / "drawn" / "worlds.json") or {}
    rooms = sorted({w["environments"] for w in worlds.values()})
    size = f"of {' or '.join(map(str, rooms))} rooms " if rooms else ""
    out = ["## Rooms never seen in training (sequence arg, mean ± sd over world seeds)", "",
           f"Folds that hold out whole rooms, in the paper-shaped world and in a world {size}drawn by the same "
           "seed (furniture, objects and sizes the catalog never had); the last two columns train on every step of "
           "the paper-shaped world and run in the drawn one. Success (goal reached safely) in brackets.", "",
           "| method | scenario folds | paper-shaped rooms held out | drawn rooms held out | "
           "paper-shaped to drawn rooms |", "|---|---:|---:|---:|---:|"]
    for name in labels:
        cells = [_pm(table.get(name, {}), "sequence_arg") + _success(table.get(name, {}))
                 for table in (paper_shaped, held_out, drawn, transfer)]
        if any(c.startswith(tuple("0123456789")) for c in cells[1:]):
            out.append(f"| {labels[name]} | " + " | ".join(cells) + " |")
    out += ["", "Per primitive: `reports/scenes/paper/table1.md`, `reports/scenes/drawn/table1.md`; why programs fail "
            "there: `failures.md` beside them; noise and feedback in drawn rooms: `reports/scenes/drawn/noise.csv`, "
            "`feedback.csv`; what drawing the rooms cost: `reports/scenes/drawn/worlds.json`; intervals and paired "
            "comparisons (with the shipped planner too) in drawn rooms held out: "
            "`reports/scenes/drawn/table1_ci.md`, `comparisons.md`; for the transfer: the same in "
            "`reports/scenes/transfer/`.", ""]
    return out


def _success(entry: dict[str, Any]) -> str:
    return f" ({entry['success']:.1f})" if entry.get("success") is not None else ""


def _slacks(n_slacks: int) -> str:
    return "a slack per step" if n_slacks == 0 else f"{n_slacks} slack group{'s' if n_slacks > 1 else ''}"
