"""reports/summary.md: every result of the pipeline next to the paper's figure."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

from . import paper


def _f(v: Any) -> str:
    return "-" if v is None else (f"{v:.1f}" if isinstance(v, float) else str(v))


def _load(path: Path) -> Any:
    return json.loads(path.read_text()) if path.exists() else None


def build_summary(reports: Path, labels: dict[str, str]) -> str:
    out = ["# Results", "", "Every number below comes from `dvc repro` (files in `reports/`); the paper's figures",
           "are Sung, Selman and Saxena's, on their own 127 sequences from OpenRAVE.", ""]
    ds = _load(reports / "dataset.json")
    if ds:
        out += ["## Dataset", "", "| figure | paper | here |", "|---|---:|---:|"]
        out += [f"| {k} | {v} | {ds.get(k)} |" for k, v in paper.DATASET.items()]
        out.append("")
    cv = _load(reports / "crossval.json")
    if cv:
        out += ["## Table I (6-fold cross-validation)", "",
                "| method | avg prim | paper | avg arg | paper | seq prim | paper | seq arg | paper | success |",
                "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
        for name in labels:
            if name not in cv:
                continue
            e, label = cv[name], labels[name]
            p = paper.TABLE1.get(label, (None,) * 4)
            out.append(f"| {label} | {_f(e['steps'].get('average/prim'))} | {_f(p[0])} | "
                       f"{_f(e['steps'].get('average/arg'))} | {_f(p[1])} | {_f(e.get('sequence/prim'))} | "
                       f"{_f(p[2])} | {_f(e.get('sequence/arg'))} | {_f(p[3])} | {_f(e.get('success'))} |")
        out += ["", "Per primitive: `reports/table1.md` and `reports/table1.tex`; confusion matrix: "
                "`reports/confusion.png`.", ""]
    noise = reports / "noise.csv"
    if noise.exists():
        rows = list(csv.DictReader(noise.open()))
        out += ["## Attribute noise (sequence arg, full model)", "", "| flip rate | here (mean ± std) | paper |",
                "|---:|---:|---:|"]
        for r in rows:
            rate = float(r["rate"])
            out.append(f"| {rate:g} | {float(r['sequence_arg']):.1f} ± {float(r['sequence_arg_std']):.1f} | "
                       f"{_f(paper.NOISE.get(rate))} |")
        out += ["", "![noise](noise.png)", ""]
    fb = reports / "feedback.csv"
    if fb.exists():
        rows = list(csv.DictReader(fb.open()))
        out += ["## Human feedback (sequence arg, full model)", "", "| top k | steps with feedback | here | paper |",
                "|---:|---:|---:|---:|"]
        for r in rows:
            n = r["n"]
            key_n = "all" if int(n) >= 20 else n
            out.append(f"| {r['k']} | {key_n} | {float(r['sequence_arg']):.1f} | "
                       f"{_f(paper.FEEDBACK.get((int(r['k']), key_n)))} |")
        out += ["", "![feedback](feedback.png)", ""]
    rec = _load(reports / "recipes.json")
    if rec:
        t = rec["totals"]
        out += ["## Recipes (environments held out from training)", "", "| | here | paper |", "|---|---:|---:|",
                f"| no feedback | {t['no_feedback']}/{t['recipes']} | {paper.RECIPES['no_feedback']}/12 |",
                f"| one feedback at the start of each program | {t['feedback_first_step']}/{t['recipes']} | "
                f"{paper.RECIPES['feedback_first_step']}/12 |", ""]
    train = _load(reports / "train.json")
    bench = _load(reports / "bench.json")
    if train or bench:
        out += ["## Training and speed", ""]
        if train:
            out.append(f"Full model on all steps: {train['iterations']} cutting-plane iterations, relative gap "
                       f"{train['relative_gap']:.2g}, teacher-forced training accuracy "
                       f"{train['train_average_prim']:.1f}% (prim), {train['train_average_arg']:.1f}% (arg).")
        if bench:
            runs = {(r["tol"], r["n_slacks"]): r for r in bench["train"]["runs"]}
            timing = "; ".join(f"{r['seconds']:.1f} s to a relative gap of {tol:g} ({r['iterations']} iterations, "
                               f"{slacks} slack group{'s' if slacks > 1 else ''})"
                               for (tol, slacks), r in runs.items())
            latency = ", ".join(f"{v['inference_ms']:.2f} ms at {n} objects" for n, v in bench["latency"].items())
            out.append(f"`taskseq bench` (its own run, {bench['machine']['cpus']} CPUs): training {timing}; "
                       f"per-step inference {latency}.")
        out.append("")
    return "\n".join(out)
