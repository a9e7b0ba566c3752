"""The built-in methods of Table I, in the tables' order: the paper's rows, then ours with relation features.

The paper's baselines and ablations take no C of their own: the baselines are
not structural SVMs (their C is the `crossval` section's), and the ablations
(`only_edge`, `only_clique`) take the full model's, as the paper compares them.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..evaluate.methods import ChanceMethod, MulticlassMethod, ScorerMethod, SymbolicMethod
from .spec import Build, MethodSpec, register

# the paper's rows of Table I; every other method is an addition beside them. Its baselines come first.
PAPER_METHODS = ("chance", "multiclass", "symb_plan_svm", "symb_plan_manual", "only_edge", "only_clique", "full")
BASELINES = PAPER_METHODS[:4]
PAPER_MODEL = "full"  # the paper's own model, as published


@dataclass(frozen=True)
class DaggerSettings:
    """Of the DAgger methods: rounds of rolling the planner out, asking the demonstrator and refitting."""

    dagger_rounds: int = 1

    def __post_init__(self) -> None:
        if self.dagger_rounds < 1:
            raise ValueError(f"dagger_rounds must be at least 1, got {self.dagger_rounds}")


register(MethodSpec("chance", "chance", lambda b: ChanceMethod(seed=b.crossval.chance_seed), C_from=None))
register(MethodSpec("multiclass", "multiclass", lambda b: MulticlassMethod(C=b.crossval.multiclass_C,
                                                                          tol=b.crossval.multiclass_tol), C_from=None))
register(MethodSpec("symb_plan_svm", "symb-plan-svm", lambda b: SymbolicMethod(
    goals="svm", C=b.crossval.ranking_C, horizon=b.horizon, name="symb_plan_svm"), C_from=None))
register(MethodSpec("symb_plan_manual", "symb-plan-manual", lambda b: SymbolicMethod(
    goals="manual", horizon=b.horizon, name="symb_plan_manual"), C_from=None))
register(MethodSpec("only_edge", "only edge features", lambda b: b.mrf("edge"), C_from=PAPER_MODEL))
register(MethodSpec("only_clique", "only clique features", lambda b: b.mrf("clique"), C_from=PAPER_MODEL))
register(MethodSpec("full", "ours - full", lambda b: b.mrf("full")))
# beyond the paper: relation features, then those with one kind of training data beyond the logs each; their rows
# sit below the paper-faithful ones in every table
register(MethodSpec("relations", "ours + relations", lambda b: b.mrf("relations")))
register(MethodSpec("chained", "ours + relations + chained starts",
                    lambda b: b.mrf("relations", chained_starts=True)))


def _dagger(b: Build) -> ScorerMethod:
    return b.mrf("relations", dagger_rounds=b.settings.dagger_rounds)


register(MethodSpec("dagger", "ours + relations + dagger", _dagger, settings=DaggerSettings))
