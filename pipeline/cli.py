"""The `taskseq` command line: one subcommand per pipeline stage, plus tools.

Stages take their settings as options; `dvc.yaml` passes them from
`params.yaml`, so the command a stage runs is the command a user can type.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from .io import write_json_atomic

Handler = Callable[[argparse.Namespace], int]


def _generate(args: argparse.Namespace) -> int:
    from .logs.generate import generate

    counts = generate(args.seed, args.output)
    if args.run:
        args.run.metrics({"demonstrations": sum(counts.values()), "files": len(counts)})
    print(f"wrote {sum(counts.values())} demonstrations in {len(counts)} files to {args.output}")
    return 0


def _replay(args: argparse.Namespace) -> int:
    from .logs.validate import LogError, check_record, log_files, read_records

    n_ok, problems = 0, []
    try:
        files = log_files(Path(args.input))
    except FileNotFoundError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    for path in files:
        try:
            for item in read_records(path):
                try:
                    check_record(item)
                    n_ok += 1
                except LogError as err:
                    problems.append(str(err))
        except LogError as err:  # unreadable line: the rest of that file cannot be trusted
            problems.append(str(err))
    for p in problems:
        print(p, file=sys.stderr)
    print(f"{n_ok} demonstrations replay exactly; {len(problems)} with problems")
    return 1 if problems else 0


def _ingest(args: argparse.Namespace) -> int:
    from .logs.ingest import dataset_summary, load_logs, write_tables
    from .logs.validate import LogError

    try:
        tables, records = load_logs(args.input)
    except (LogError, FileNotFoundError) as err:
        print(f"error: {err}", file=sys.stderr)
        print("nothing was written", file=sys.stderr)
        return 1
    summary = dataset_summary(tables)
    write_tables(tables, args.output)
    if args.metrics:
        write_json_atomic(args.metrics, summary)
    if args.run:
        from .track.mlflow_runs import flatten

        args.run.metrics({k: v for k, v in flatten(summary).items() if isinstance(v, (int, float))})
    print(
        f"ingested {summary['sequences']} sequences ({summary['steps']} steps, {summary['scenarios']} scenarios, "
        f"{summary['environments']} environments) into {args.output}"
    )
    return 0


def _features(args: argparse.Namespace) -> int:
    from .features.dataset import build_steps, write_features
    from .learn.mrf import candidate_index
    from .logs.ingest import read_tables, records_from_tables

    records = records_from_tables(read_tables(args.input))
    contexts, meta = build_steps(records)
    write_features(contexts, meta, args.output)
    n_cand = sum(len(candidate_index(c.n)[0]) for c in contexts)
    if args.run:
        args.run.metrics({"steps": len(contexts), "candidates": n_cand, "sequences": len(records)})
    print(f"wrote {len(contexts)} steps ({n_cand} candidates) from {len(records)} sequences to {args.output}")
    return 0


def _train(args: argparse.Namespace) -> int:
    import csv
    import io

    from .evaluate.metrics import step_accuracy
    from .features.dataset import read_features
    from .io import write_text_atomic
    from .learn.persist import save_model
    from .learn.train import fit_mrf

    contexts, _ = read_features(args.features)
    fit = fit_mrf(contexts, args.feature_set, C=args.C, tol=args.tol, max_iter=args.max_iter,
                  n_slacks=args.n_slacks, progress=True)
    params = {"C": args.C, "tol": args.tol, "max_iter": args.max_iter, "n_slacks": args.n_slacks,
              "n_steps": len(contexts)}
    save_model(args.model, fit.model, fit.w, params)
    acc = step_accuracy(contexts, fit.ssvm.predict(contexts))
    last = fit.ssvm.history_[-1]
    metrics = {
        "train_average_prim": acc["average/prim"],
        "train_average_arg": acc["average/arg"],
        "train_done_arg": acc.get("done/arg", float("nan")),
        "iterations": fit.ssvm.n_iter_,
        "converged": bool(fit.ssvm.converged_),
        "primal_objective": fit.ssvm.primal_objective_,
        "dual_objective": fit.ssvm.dual_objective_,
        "relative_gap": last.gap / max(1.0, abs(last.best_primal)),
    }
    if args.metrics:
        write_json_atomic(args.metrics, metrics)
    if args.curve:
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(["iteration", "primal", "best_primal", "dual", "gap", "n_constraints"])
        for it in fit.ssvm.history_:
            writer.writerow([it.iteration, f"{it.primal:.8g}", f"{it.best_primal:.8g}", f"{it.dual:.8g}",
                             f"{it.gap:.8g}", it.n_constraints])
        write_text_atomic(args.curve, buf.getvalue())
    if args.run:
        args.run.metrics({**{k: float(v) for k, v in metrics.items()}, "seconds": fit.seconds})
        for path in (args.curve, args.model):
            args.run.artifact(path)
    state = "converged" if fit.ssvm.converged_ else "stopped at max_iter"
    print(f"trained {args.feature_set} model on {len(contexts)} steps: {fit.ssvm.n_iter_} iterations ({state}), "
          f"{fit.seconds:.1f} s; teacher-forced training accuracy prim {acc['average/prim']:.1f}% "
          f"arg {acc['average/arg']:.1f}%; saved {args.model}")
    return 0


def _load_environment(path: Path, record: int) -> tuple[dict, dict]:
    """(objects, state) from a JSON environment file or a record of a JSON Lines log."""
    import json

    from .logs.validate import LogError, check_references, check_schema, read_records

    if path.suffix == ".jsonl":
        items = list(read_records(path))
        if not 1 <= record <= len(items):
            raise ValueError(f"{path}: has {len(items)} records, no record {record}")
        item = items[record - 1]
        check_schema(item)
        check_references(item)
        return item.record["objects"], item.record["steps"][0]["state"]
    try:
        env = json.loads(path.read_text())
    except (OSError, ValueError) as err:
        raise ValueError(f"{path}: cannot read the environment: {err}") from None
    for key in ("objects", "state"):
        if key not in env:
            raise LogError(path, 1, key, "an environment file needs 'objects' and 'state' (as in the log format)")
    return env["objects"], env["state"]


def _plan(args: argparse.Namespace) -> int:
    import json

    from .learn.persist import load_model
    from .logs.records import spec_from_dict, state_from_dict
    from .plan.planner import plan
    from .sim.tasks import Task

    try:
        model, w, _ = load_model(args.model)
        objects, state_dict = _load_environment(args.env, args.record)
        specs = {o["id"]: spec_from_dict(o) for o in objects}
        state = state_from_dict(specs, state_dict)
        task = Task.parse(args.task)
        task.check_objects(state)
    except (ValueError, FileNotFoundError, KeyError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    program = plan(model, w, state, task, max_steps=args.max_steps, top_k=args.top_k)
    names = {o: s.name for o, s in specs.items()}

    def label(action) -> str:
        return f"{action}  [{', '.join(names[a] for a in action.args)}]" if action.args else str(action)

    if args.json:
        print(json.dumps({
            "task": str(task), "status": program.status, "goal_reached": program.goal_reached,
            "steps": [{"action": str(s.action), "score": s.score, "unsafe": s.unsafe,
                       "alternatives": [[str(a), sc] for a, sc in s.alternatives]} for s in program.steps],
            "error": program.error,
        }, indent=2))
    else:
        print(f"program for {task}:")
        for k, s in enumerate(program.steps, start=1):
            alts = "; ".join(f"{a} {sc:.2f}" for a, sc in s.alternatives)
            warn = f"  UNSAFE: {', '.join(s.unsafe)}" if s.unsafe else ""
            print(f"{k:3d}. {label(s.action):55s} score {s.score:8.2f}   next best: {alts}{warn}")
        print(f"status: {program.status}; goal {'reached' if program.goal_reached else 'not reached'}"
              + (f"; {program.error}" if program.error else ""))
    return 0 if program.success else 1


def _conditions_run(args: argparse.Namespace, conditions: list) -> list:
    from functools import partial

    from .evaluate.crossval import scenarios_from_records
    from .evaluate.methods import MRFMethod
    from .evaluate.robustness import evaluate_conditions
    from .features.dataset import read_features
    from .logs.ingest import read_tables, records_from_tables

    contexts, meta = read_features(args.features)
    scenarios = scenarios_from_records(records_from_tables(read_tables(args.processed)))
    make = partial(MRFMethod, features="full", C=args.C, tol=args.tol, max_iter=args.max_iter,
                   n_slacks=args.n_slacks, store=_store(args))
    return evaluate_conditions(make, contexts, meta, scenarios, conditions, n_folds=args.folds,
                               fold_seed=args.fold_seed, group_by=args.group_by, max_steps=args.max_steps,
                               seed=args.seed, n_jobs=args.n_jobs)


def _rates(outcomes: list) -> dict[str, float]:
    import numpy as np

    return {
        "sequence_arg": 100.0 * float(np.mean([o.arg_correct for o in outcomes])),
        "sequence_prim": 100.0 * float(np.mean([o.prim_correct for o in outcomes])),
        "success": 100.0 * float(np.mean([o.success for o in outcomes])),
    }


def _noise(args: argparse.Namespace) -> int:
    import numpy as np

    from .evaluate.robustness import Condition
    from .io import write_text_atomic
    from .report.tables import line_plot_png

    conditions = [Condition("noise", r, s) for r in args.rates for s in range(args.seeds)]
    results = _conditions_run(args, conditions)
    runs = []
    for c in conditions:
        runs.append({"rate": c.a, "seed": c.b, **_rates([o for cc, o in results if cc == c])})
    lines = ["rate,seed,sequence_arg,sequence_prim,success"]
    lines += [f"{r['rate']},{r['seed']},{r['sequence_arg']:.2f},{r['sequence_prim']:.2f},{r['success']:.2f}"
              for r in runs]
    write_text_atomic(args.output / "noise_runs.csv", "\n".join(lines) + "\n")
    summary = ["rate,sequence_arg,sequence_arg_std,sequence_prim,success"]
    means, stds = [], []
    for r in args.rates:
        arg = [x["sequence_arg"] for x in runs if x["rate"] == r]
        prim = [x["sequence_prim"] for x in runs if x["rate"] == r]
        succ = [x["success"] for x in runs if x["rate"] == r]
        means.append(float(np.mean(arg)))
        stds.append(float(np.std(arg)))
        summary.append(f"{r},{np.mean(arg):.2f},{np.std(arg):.2f},{np.mean(prim):.2f},{np.mean(succ):.2f}")
    write_text_atomic(args.output / "noise.csv", "\n".join(summary) + "\n")
    if args.run:
        for r, mean, std in zip(args.rates, means, stds, strict=True):
            with args.run.child(f"noise r={r}", {"rate": r}) as child:
                child.metrics({"sequence_arg": mean, "sequence_arg_std": std})
    line_plot_png({"ours - full (mean, std over seeds)": (list(args.rates), means, stds)},
                  str(args.output / "noise.png"), "Sequence accuracy (arg) with binary attributes flipped",
                  "probability of flipping each binary attribute", "% sequences correct",
                  reference={"paper": ([0.0, 0.1, 0.4], [69.7, 55.8, 38.1])})
    if args.run:
        for f in ("noise.csv", "noise_runs.csv", "noise.png"):
            args.run.artifact(args.output / f)
    print("\n".join(summary))
    return 0


def _feedback(args: argparse.Namespace) -> int:
    from .evaluate.robustness import Condition
    from .io import write_text_atomic
    from .report.tables import line_plot_png

    ns = [args.max_steps if n == "all" else int(n) for n in args.n]
    conditions = [Condition("feedback", k, n) for k in args.k for n in ns]
    results = _conditions_run(args, conditions)
    lines = ["k,n,sequence_arg,sequence_prim,success"]
    series = {}
    for k in args.k:
        ys = []
        for n in ns:
            r = _rates([o for cc, o in results if cc == Condition("feedback", k, n)])
            ys.append(r["sequence_arg"])
            lines.append(f"{k},{n},{r['sequence_arg']:.2f},{r['sequence_prim']:.2f},{r['success']:.2f}")
            if args.run:
                with args.run.child(f"feedback k={k} n={n}", {"k": k, "n": n}) as child:
                    child.metrics(r)
        series[f"top {k}"] = (list(range(len(ns))), ys, None)
    write_text_atomic(args.output / "feedback.csv", "\n".join(lines) + "\n")
    labels = ["all" if n == args.max_steps else str(n) for n in ns]
    line_plot_png(series, str(args.output / "feedback.png"), "Sequence accuracy (arg) with an observer's feedback",
                  "steps with feedback", "% sequences correct", xticks=list(range(len(ns))), xticklabels=labels)
    if args.run:
        for f in ("feedback.csv", "feedback.png"):
            args.run.artifact(args.output / f)
    print("\n".join(lines))
    return 0


def _recipes(args: argparse.Namespace) -> int:
    from functools import partial

    from .evaluate.methods import MRFMethod
    from .evaluate.recipes import RECIPES, evaluate_recipes
    from .features.dataset import read_features

    contexts, meta = read_features(args.features)
    make = partial(MRFMethod, features="full", C=args.C, tol=args.tol, max_iter=args.max_iter,
                   n_slacks=args.n_slacks, store=_store(args))
    outcomes = evaluate_recipes(make, contexts, meta, max_steps=args.max_steps)
    descriptions = {(r.name, r.env_id): r.description for r in RECIPES}
    rows = []
    for o in outcomes:
        rows.append({"recipe": o.recipe, "env_id": o.env_id, "description": descriptions[(o.recipe, o.env_id)],
                     "feedback": o.feedback, "success": o.success,
                     "programs": [{"task": t, "status": st, "success": ok} for t, st, ok in o.programs]})
    totals = {"no_feedback": sum(o.success for o in outcomes if not o.feedback),
              "feedback_first_step": sum(o.success for o in outcomes if o.feedback), "recipes": len(RECIPES)}
    write_json_atomic(args.output / "recipes.json", {"totals": totals, "runs": rows})
    if args.run:
        for name in dict.fromkeys(o.recipe for o in outcomes):
            mine = [o for o in outcomes if o.recipe == name]
            with args.run.child(name, {"recipe": name}) as child:
                child.metrics({"success_no_feedback": sum(o.success for o in mine if not o.feedback),
                               "success_feedback": sum(o.success for o in mine if o.feedback)})
        args.run.metrics({k: float(v) for k, v in totals.items()})
        args.run.artifact(args.output / "recipes.json")
    for o in outcomes:
        print(f"{o.recipe:24s} {o.env_id} feedback={'yes' if o.feedback else 'no ':3s} "
              f"{'SUCCESS' if o.success else 'failed '}  " + " -> ".join(f"{t} [{st}]" for t, st, _ in o.programs))
    print(f"success: {totals['no_feedback']}/{totals['recipes']} without feedback, "
          f"{totals['feedback_first_step']}/{totals['recipes']} with one feedback at the start of each program")
    return 0


def _store(args: argparse.Namespace) -> str | None:
    """The fold-model store to load from, if one was named and exists."""
    store = getattr(args, "model_store", None)
    if store is not None and not Path(store).is_dir():
        print(f"warning: model store {store} does not exist; models will be trained", file=sys.stderr)
        return None
    return None if store is None else str(store)


def _folds(args: argparse.Namespace) -> int:
    import time
    from functools import partial

    from .evaluate.crossval import scenarios_from_records
    from .evaluate.fold_models import train_fold_models, training_jobs
    from .evaluate.methods import MRFMethod
    from .features.dataset import read_features
    from .logs.ingest import read_tables, records_from_tables

    contexts, meta = read_features(args.features)
    scenarios = scenarios_from_records(records_from_tables(read_tables(args.processed)))
    jobs = training_jobs(meta, scenarios, args.folds, args.seed, args.group_by)
    make = partial(MRFMethod, C=args.C, tol=args.tol, max_iter=args.max_iter, n_slacks=args.n_slacks)
    print(f"training {len(jobs)} fold models ({args.folds} folds grouped by {args.group_by}, recipes) "
          f"with {args.n_jobs} jobs")
    start = time.perf_counter()
    records = train_fold_models(make, contexts, meta, jobs, args.output, n_jobs=args.n_jobs, verbose=5)
    wall = time.perf_counter() - start
    metrics = {"models": len(records), "wall_seconds": wall,
               "fit_seconds": sum(r["seconds"] for r in records),
               "iterations": sum(r["iterations"] for r in records),
               "all_converged": all(r["converged"] for r in records)}
    if args.metrics:
        write_json_atomic(args.metrics, {**metrics, "per_model": [
            {k: r[k] for k in ("features", "uses", "steps", "iterations", "converged", "seconds",
                               "primal_objective", "dual_objective")} for r in records]})
    if args.run:
        args.run.metrics({k: float(v) for k, v in metrics.items()})
    print(f"trained {len(records)} models in {wall:.1f} s ({metrics['fit_seconds']:.1f} s of fitting, "
          f"{metrics['iterations']} iterations); written to {args.output}")
    return 0


def _report(args: argparse.Namespace) -> int:
    from .io import write_text_atomic
    from .report.summary import build_summary

    text = build_summary(args.reports, METHOD_LABELS)
    write_text_atomic(args.output, text + "\n")
    if args.run:
        args.run.artifact(args.output)
    print(f"wrote {args.output}")
    return 0


def _pddl(args: argparse.Namespace) -> int:
    from .evaluate.crossval import scenarios_from_records
    from .logs.ingest import read_tables, records_from_tables
    from .plan.symbolic.files import write_pddl

    scenarios = scenarios_from_records(records_from_tables(read_tables(args.processed)))
    counts = write_pddl(scenarios, args.output, horizon=args.horizon)
    if args.run:
        args.run.metrics(counts)
        args.run.artifact(Path(args.output) / "domain.pddl")
    print(f"wrote the domain, {counts['problems']} problems and {counts['plans']} shortest plans to {args.output}"
          + (f"; {counts['no_plan']} without a plan within horizon {args.horizon}" if counts["no_plan"] else ""))
    return 0


def _bench(args: argparse.Namespace) -> int:
    from .bench import format_bench, run_bench
    from .logs.ingest import read_tables, records_from_tables

    records = records_from_tables(read_tables(args.processed))
    result = run_bench(records, C=args.C, tol=args.tol, max_iter=args.max_iter, n_slacks=args.n_slacks,
                       repeats=args.repeats)
    write_json_atomic(args.output, result)
    print(format_bench(result))
    print(f"written to {args.output}")
    return 0


METHOD_LABELS = {
    "chance": "chance",
    "multiclass": "multiclass",
    "symb_plan_svm": "symb-plan-svm",
    "symb_plan_manual": "symb-plan-manual",
    "only_edge": "only edge features",
    "only_clique": "only clique features",
    "full": "ours - full",
}


def _crossval(args: argparse.Namespace) -> int:
    import csv
    import io
    from functools import partial

    from .evaluate.crossval import Demonstrations, cross_validate, scenarios_from_records
    from .evaluate.methods import ChanceMethod, MRFMethod, MulticlassMethod, SymbolicMethod
    from .evaluate.metrics import confusion, summarize
    from .features.dataset import read_features
    from .io import write_text_atomic
    from .logs.ingest import read_tables, records_from_tables
    from .report.tables import confusion_png, table_rows, to_csv, to_latex, to_markdown

    contexts, meta = read_features(args.features)
    records = records_from_tables(read_tables(args.processed))
    scenarios = scenarios_from_records(records)
    mrf = partial(MRFMethod, C=args.C, tol=args.tol, max_iter=args.max_iter, n_slacks=args.n_slacks,
                  store=_store(args))
    methods = {
        "chance": partial(ChanceMethod, seed=args.chance_seed),
        "multiclass": partial(MulticlassMethod, C=args.multiclass_C),
        "symb_plan_svm": partial(SymbolicMethod, goals="svm", C=args.ranking_C, name="symb_plan_svm"),
        "symb_plan_manual": partial(SymbolicMethod, goals="manual", name="symb_plan_manual"),
        "only_edge": partial(mrf, features="edge", name="only_edge"),
        "only_clique": partial(mrf, features="clique", name="only_clique"),
        "full": partial(mrf, features="full", name="full"),
    }
    unknown = set(args.methods) - set(methods)
    if unknown:
        print(f"error: unknown methods {sorted(unknown)}; known: {', '.join(methods)}", file=sys.stderr)
        return 2
    methods = {k: v for k, v in methods.items() if k in args.methods}
    print(f"cross-validating {', '.join(methods)} over {args.folds} folds grouped by {args.group_by} "
          f"({len(scenarios)} scenarios, {len(contexts)} steps, {args.n_jobs} jobs)")
    recorded = frozenset(sorted(scenarios)[:: max(1, len(scenarios) // args.recordings)][: args.recordings]
                         if args.recordings else [])
    results = cross_validate(methods, contexts, meta, scenarios, Demonstrations.from_records(records),
                             n_folds=args.folds, seed=args.seed, group_by=args.group_by, max_steps=args.max_steps,
                             n_jobs=args.n_jobs, verbose=5, keep_programs={"full": recorded})
    predicts_args = {k: v().predicts_args for k, v in methods.items()}
    summary = summarize(results, contexts, predicts_args)
    rows = table_rows(summary, METHOD_LABELS)
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out / "table1.csv", to_csv(rows))
    write_text_atomic(out / "table1.md", to_markdown(rows))
    caption = (f"{args.folds}-fold cross-validation grouped by {args.group_by} on {len(scenarios)} scenarios: "
               "percentage of primitives (prim) and of primitives with arguments (arg) right, teacher-forced, "
               "and of closed-loop sequences equal to a demonstration.")
    write_text_atomic(out / "table1.tex", to_latex(rows, caption))
    write_json_atomic(out / "crossval.json", summary)
    metrics = {}
    for name, entry in summary.items():
        m = {"average_prim": entry["steps"].get("average/prim"), "average_arg": entry["steps"].get("average/arg")}
        for key in ("sequence/prim", "sequence/arg", "success"):
            if key in entry:
                m[key.replace("/", "_")] = entry[key]
        metrics[name] = {k: v for k, v in m.items() if v is not None}
    write_json_atomic(out / "metrics.json", metrics)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["method", "fold", "scenario", "task", "status", "prim_correct", "arg_correct", "goal_reached",
                "safe", "success", "program"])
    for r in results:
        for s in r.sequences or []:
            w.writerow([r.method, r.fold, s.scenario_id, s.task, s.status, int(s.prim_correct), int(s.arg_correct),
                        int(s.goal_reached), int(s.safe), int(s.success), " ".join(s.actions)])
    write_text_atomic(out / "crossval_sequences.csv", buf.getvalue())
    if args.run:
        for name, entry in summary.items():
            with args.run.child(name, {"method": name}) as child:
                child.metrics({k.replace("/", "_"): v for k, v in entry["steps"].items()})
                child.metrics({k: v for k, v in entry.items() if k in ("sequence/prim", "sequence/arg", "success",
                                                                        "goal_reached")})
    if "full" in methods:
        full = [r for r in results if r.method == "full"]
        index = [i for r in full for i in r.step_index]
        preds = [y for r in full for y in r.step_predictions]
        confusion_png(confusion([contexts[i] for i in index], preds), str(out / "confusion.png"),
                      "full model, teacher-forced, cross-validated")
    if recorded:
        from .plan.symbolic.files import file_stem
        from .track.recordings import record_program

        for r in results:
            for sid, (steps, status) in r.programs.items():
                path = out / "recordings" / f"{file_stem(sid)}.rrd"
                record_program(path, sid, scenarios[sid].initial, scenarios[sid].task, steps, status,
                               scenarios[sid].demonstrations[0])
                if args.run:
                    args.run.artifact(path, "recordings")
    if args.run:
        for f in ("table1.csv", "table1.md", "table1.tex", "metrics.json", "confusion.png"):
            args.run.artifact(out / f)
    print(to_markdown(rows))
    return 0


def _feedback_steps(value: str) -> str:
    """A number of steps with feedback, or 'all'."""
    if value != "all" and not value.isdigit():
        raise argparse.ArgumentTypeError(f"expected a whole number of steps or 'all', got {value!r}")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="taskseq",
        description="Learn to sequence manipulation primitives for under-specified tasks (unrolled MRF + SSVM).",
    )
    parser.add_argument("--no-mlflow", action="store_true",
                        help="do not record pipeline stages in MLflow (default: record, see README)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def add(name: str, help_: str, handler: Handler) -> argparse.ArgumentParser:
        p = sub.add_parser(name, help=help_, description=help_)
        p.set_defaults(handler=handler)
        return p

    p = add("generate", "simulate the demonstrator and write demonstration logs (JSON Lines)", _generate)
    p.add_argument("--seed", type=int, default=0, help="seed of scenario draws and position jitter (default 0)")
    p.add_argument("--output", type=Path, default=Path("data/raw"), help="folder of *.jsonl logs (replaced)")

    p = add("replay", "re-execute every logged sequence and report states or goals that differ", _replay)
    p.add_argument("input", type=Path, help="folder of *.jsonl logs")

    p = add("ingest", "validate logs and write them as Parquet tables plus dataset metrics", _ingest)
    p.add_argument("--input", type=Path, default=Path("data/raw"), help="folder of *.jsonl logs")
    p.add_argument("--output", type=Path, default=Path("data/processed"), help="folder of Parquet tables (replaced)")
    p.add_argument("--metrics", type=Path, default=Path("reports/dataset.json"), help="dataset counts as JSON")

    p = add("features", "build every teacher-forced step's candidates and features from the Parquet tables", _features)
    p.add_argument("--input", type=Path, default=Path("data/processed"), help="folder of Parquet tables")
    p.add_argument("--output", type=Path, default=Path("data/features"), help="feature folder (replaced)")

    def training_options(p: argparse.ArgumentParser) -> None:
        p.add_argument("--C", type=float, default=3.0, help="slack weight, C * sum of slacks (default 3.0)")
        p.add_argument("--tol", type=float, default=1e-3, help="relative primal-dual gap to stop at (default 1e-3)")
        p.add_argument("--max-iter", type=int, default=2000, help="cutting-plane iterations at most (default 2000)")
        p.add_argument("--n-slacks", type=int, default=4,
                       help="slack groups of the cutting plane, one cut each per iteration; 1 is the classic "
                            "1-slack algorithm, the optimum is the same for every value (default 4)")

    def store_option(p: argparse.ArgumentParser) -> None:
        p.add_argument("--model-store", type=Path, default=None,
                       help="folder written by `taskseq folds`: models trained on the same steps with the same "
                            "settings are loaded from it instead of trained again (default: train)")

    p = add("train", "fit the MRF weights with the 1-slack structural SVM on every step", _train)
    p.add_argument("--features", type=Path, default=Path("data/features"), help="feature folder")
    p.add_argument("--feature-set", choices=("full", "edge", "clique"), default="full",
                   help="families of the score: all six, edge terms only, or clique terms only")
    training_options(p)
    p.add_argument("--model", type=Path, default=Path("models/mrf.npz"), help="model file to write (.npz)")
    p.add_argument("--metrics", type=Path, default=Path("reports/train.json"), help="training metrics (JSON)")
    p.add_argument("--curve", type=Path, default=Path("reports/train_curve.csv"), help="objective per iteration")

    p = add("plan", "plan a program for a task in an environment with a trained model", _plan)
    p.add_argument("--model", type=Path, default=Path("models/mrf.npz"), help="model file (.npz)")
    p.add_argument("--env", type=Path, required=True,
                   help="environment: a JSON file with 'objects' and 'state', or a .jsonl log")
    p.add_argument("--record", type=int, default=1, help="with a .jsonl log: which record (line) to take, from 1")
    p.add_argument("--task", required=True, help='the task, e.g. "pour(obj27)" or "pick_and_place(obj40,obj04)"')
    p.add_argument("--max-steps", type=int, default=20, help="stop after this many primitives (default 20)")
    p.add_argument("--top-k", type=int, default=3, help="candidates shown per step (default 3)")
    p.add_argument("--json", action="store_true", help="print the program as JSON")

    def fold_options(p: argparse.ArgumentParser) -> None:
        """Inputs and fold assignment, shared by `crossval` and `folds` so their folds agree."""
        p.add_argument("--features", type=Path, default=Path("data/features"), help="feature folder")
        p.add_argument("--processed", type=Path, default=Path("data/processed"), help="folder of Parquet tables")
        p.add_argument("--folds", type=int, default=6, help="number of folds (default 6)")
        p.add_argument("--group-by", choices=("scenario", "environment"), default="scenario",
                       help="keep whole scenarios, or whole environments (unseen environments), in one fold")
        p.add_argument("--seed", type=int, default=0, help="seed of the fold assignment")

    p = add("crossval", "cross-validate every method and write Table I, metrics and a confusion matrix", _crossval)
    fold_options(p)
    p.add_argument("--methods", nargs="+", default=list(METHOD_LABELS), help="methods to run")
    p.add_argument("--chance-seed", type=int, default=0, help="seed of the chance baseline")
    p.add_argument("--multiclass-C", type=float, default=1.0, help="C of the multiclass SVM")
    p.add_argument("--ranking-C", type=float, default=1.0, help="C of the role-ranking SVMs (symb-plan-svm)")
    training_options(p)
    store_option(p)
    p.add_argument("--max-steps", type=int, default=20, help="step cap of closed-loop runs")
    p.add_argument("--n-jobs", type=int, default=1, help="folds run in parallel (joblib)")
    p.add_argument("--recordings", type=int, default=0,
                   help="Rerun recordings of the full model's programs, spread over the scenarios (default 0)")
    p.add_argument("--output", type=Path, default=Path("reports"), help="folder for the tables and metrics")

    def robustness_options(p: argparse.ArgumentParser) -> None:
        p.add_argument("--features", type=Path, default=Path("data/features"), help="feature folder")
        p.add_argument("--processed", type=Path, default=Path("data/processed"), help="folder of Parquet tables")
        p.add_argument("--folds", type=int, default=6, help="number of folds (default 6)")
        p.add_argument("--group-by", choices=("scenario", "environment"), default="scenario")
        p.add_argument("--fold-seed", type=int, default=0, help="seed of the fold assignment")
        training_options(p)
        store_option(p)
        p.add_argument("--max-steps", type=int, default=20, help="step cap of closed-loop runs")
        p.add_argument("--n-jobs", type=int, default=1, help="folds run in parallel (joblib)")
        p.add_argument("--output", type=Path, default=Path("reports"), help="folder for CSV and PNG")

    p = add("noise", "sequence accuracy of the full model with binary attributes flipped at test time", _noise)
    robustness_options(p)
    p.add_argument("--rates", type=float, nargs="+", default=[0.0, 0.1, 0.2, 0.3, 0.4],
                   help="flip probabilities")
    p.add_argument("--seeds", type=int, default=3, help="noise draws per rate")
    p.add_argument("--seed", type=int, default=0, help="seed of the noise draws")

    p = add("feedback", "sequence accuracy when an observer picks among the top k at the first n steps", _feedback)
    robustness_options(p)
    p.add_argument("--k", type=int, nargs="+", default=[2, 3], help="candidates offered to the observer")
    p.add_argument("--n", nargs="+", type=_feedback_steps, default=["0", "1", "2", "3", "5", "all"],
                   help="steps with feedback (a number or 'all')")
    p.set_defaults(seed=0)

    p = add("recipes", "chain programs into recipes in environments held out from training", _recipes)
    p.add_argument("--features", type=Path, default=Path("data/features"), help="feature folder")
    training_options(p)
    store_option(p)
    p.add_argument("--max-steps", type=int, default=20, help="step cap of each program")
    p.add_argument("--output", type=Path, default=Path("reports"), help="folder for recipes.json")

    p = add("folds", "train every MRF model the evaluation stages use, once, into a model store", _folds)
    fold_options(p)
    training_options(p)
    p.add_argument("--n-jobs", type=int, default=os.cpu_count() or 1,
                   help="models trained in parallel (joblib; default: one per CPU)")
    p.add_argument("--output", type=Path, required=True, help="model store folder to write (replaced)")
    p.add_argument("--metrics", type=Path, default=None, help="training times and objectives (JSON)")

    p = add("report", "write reports/summary.md: every result next to the paper's figures", _report)
    p.add_argument("--reports", type=Path, default=Path("reports"), help="folder of the stages' results")
    p.add_argument("--output", type=Path, default=Path("reports/summary.md"), help="Markdown file to write")

    p = add("pddl", "write the PDDL domain, a problem per scenario and its shortest plan (SAT)", _pddl)
    p.add_argument("--processed", type=Path, default=Path("data/processed"), help="folder of Parquet tables")
    p.add_argument("--output", type=Path, default=Path("data/pddl"), help="folder to write (replaced)")
    p.add_argument("--horizon", type=int, default=12, help="longest plan searched (default 12)")

    p = add("bench", "time training, per-step inference (10 to 100 objects) and features memory", _bench)
    p.add_argument("--processed", type=Path, default=Path("data/processed"), help="folder of Parquet tables")
    training_options(p)
    p.add_argument("--repeats", type=int, default=50, help="timed repetitions per environment size")
    p.add_argument("--output", type=Path, default=Path("reports/bench.json"), help="results (JSON)")
    return parser


# Pipeline stages: each opens one MLflow run (see pipeline/track/mlflow_runs.py).
STAGES = ("generate", "ingest", "features", "train", "pddl", "folds", "crossval", "noise", "feedback", "recipes",
          "report")


class _StageFailed(Exception):
    def __init__(self, code: int) -> None:
        super().__init__(f"stage ended with exit code {code}")
        self.code = code


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    args.run = None
    if args.command not in STAGES or args.no_mlflow:
        return args.handler(args)
    from .track.mlflow_runs import stage_run

    params = {k: v for k, v in vars(args).items() if k not in ("handler", "run", "command", "no_mlflow")}
    inputs = [Path(getattr(args, k)) for k in ("input", "features", "processed") if getattr(args, k, None)]
    try:
        with stage_run(args.command, params, inputs) as run:
            args.run = run
            code = args.handler(args)
            if code:
                raise _StageFailed(code)  # the run is marked FAILED on the way out
    except _StageFailed as failed:
        return failed.code
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
