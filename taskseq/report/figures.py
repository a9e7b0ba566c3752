"""Figures of the reports as PNG files: the confusion matrix and line plots with error bars.

Written through `taskseq.runtime.atomic`, like every output, so a stage stopped part way
leaves each figure whole (old or new) and says which it replaced.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..runtime.atomic import atomic_file
from ..sim.primitives import ALL_PRIMITIVES


def save_png(fig, path: Path | str) -> None:
    """Write the figure atomically, without the software version (same bytes across Matplotlib patches)."""
    import matplotlib.pyplot as plt

    with atomic_file(path) as tmp:
        fig.savefig(tmp, format="png", metadata={"Software": None})
    plt.close(fig)


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
    save_png(fig, path)


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
    save_png(fig, path)


def scaling_png(steps: list[int], stage_seconds: dict[str, tuple[list[int], list[float]]],
                ms_per_step: dict[str, list[float]], tol: float, path: str) -> None:
    """Left: each stage's wall time against steps (the sizes it was measured at) on log-log axes, with a dotted
    line of slope 1 through the slowest stage at the smallest size (a stage steeper than it grows worse than
    linearly). Right: training time per step against steps (a line per measure, e.g. wall and CPU time), flat
    when training grows linearly."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(9.6, 3.8), dpi=120)
    for label, (x, seconds) in stage_seconds.items():
        left.plot(x, seconds, marker="o", label=label)
    top = max(seconds[0] for x, seconds in stage_seconds.values() if x and x[0] == steps[0])
    left.plot(steps, [top * n / steps[0] for n in steps], linestyle=":", color="grey", label="linear")
    for ax in (left, right):
        ax.set_xscale("log")
        ax.set_xticks(steps, [str(n) for n in steps])
        ax.minorticks_off()
    left.set_yscale("log")
    left.set_xlabel("steps in the world")
    left.set_ylabel("wall time (s)")
    left.set_title("time per stage", fontsize=9)
    left.grid(alpha=0.3, which="both")
    left.legend(fontsize=6, loc="upper left")
    for label, values in ms_per_step.items():
        right.plot(steps, values, marker="o", label=label)
    right.set_ylim(0, max(max(v) for v in ms_per_step.values()) * 1.3)
    right.legend(fontsize=7, loc="upper left")
    right.set_xlabel("steps in the world")
    right.set_ylabel("ms of training per step")
    right.set_title(f"training time per step (full model, gap {tol:g})", fontsize=9)
    right.grid(alpha=0.3, which="both")
    fig.tight_layout()
    save_png(fig, path)
