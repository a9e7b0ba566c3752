"""The people's-demonstrations figure: next step and closed loop per method, from the experiment's report.

One PNG beside `tables.md`, drawn from `report.json`'s own numbers (nothing recomputed), so it shows
exactly what the tables say: left, the share of next steps whose verb and arguments are the
person's (mean over folds, the bar; sd over folds, the whisker); right, the share of the derived
goal the closed-loop runs reach under each method's `feasible` policy (mean over folds; whiskers:
the 95% bootstrap interval over environments), with the people's own sequences as a dashed line.
"""

from __future__ import annotations

from pathlib import Path

from ..report.figures import save_png


def _label(name: str, labels: dict[str, str]) -> str:
    return labels.get(name, name)


def results_png(report: dict, labels: dict[str, str], path: Path | str, policy: str = "feasible") -> None:
    """Draw `report` (`experiment.summarize`'s) into `path`; methods without a figure (a planner's next step,
    an objective set with no goal) are left out of that panel."""
    import matplotlib

    matplotlib.use("Agg")  # files only, no screen
    import matplotlib.pyplot as plt

    order = list(report["settings"]["methods"])  # the settings' order, whatever order the report's keys are in
    rank = {name: i for i, name in enumerate(order)}
    next_step = sorted(((name, parts["both"]) for name, parts in report["next_step"].items()
                        if parts["both"]["mean"] is not None), key=lambda item: rank.get(item[0], len(order)))
    loop = []
    for key, figures in report["closed_loop"].items():
        name, _, run_policy = key.partition("/")
        if run_policy == policy and figures["goal_share"]["mean"] is not None:
            loop.append((name, figures["goal_share"]["mean"], report["goal_share_intervals"].get(key)))
    loop.sort(key=lambda item: rank.get(item[0], len(order)))
    people = report["closed_loop"].get("people", {}).get("goal_share", {}).get("mean")
    fig, (left, right) = plt.subplots(1, 2, figsize=(10.4, 0.45 * max(len(next_step), len(loop)) + 1.6), dpi=120)
    rows = range(len(next_step))
    left.barh(rows, [100 * f["mean"] for _, f in next_step], xerr=[100 * f["sd"] for _, f in next_step],
              color="tab:blue", capsize=3)
    left.set_yticks(rows, [_label(n, labels) for n, _ in next_step], fontsize=7)
    left.set_xlabel("next step, verb and arguments right (%)")
    rows = range(len(loop))
    means = [100 * m for _, m, _ in loop]
    # the interval resamples environments, the bar is the mean over folds: with folds of unequal size the mean may
    # lie outside the interval, where the whisker on that side is drawn empty
    low = [max(0.0, m - 100 * iv["low"]) if iv else 0.0 for m, (_, _, iv) in zip(means, loop, strict=True)]
    high = [max(0.0, 100 * iv["high"] - m) if iv else 0.0 for m, (_, _, iv) in zip(means, loop, strict=True)]
    right.barh(rows, means, xerr=[low, high], color="tab:green", capsize=3)
    right.set_yticks(rows, [_label(n, labels) for n, _, _ in loop], fontsize=7)
    if people is not None:
        right.axvline(100 * people, color="black", linestyle="--", linewidth=1, label="people (leave one out)")
        right.legend(fontsize=7, loc="upper right")
    right.set_xlabel(f"goal reached, closed loop, {policy} policy (%)")
    for ax in (left, right):
        ax.invert_yaxis()
        ax.set_xlim(0, 100)
        ax.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    save_png(fig, path)
