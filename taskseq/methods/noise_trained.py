"""ours + relations + noisy training: the relations model, trained also on steps seen with wrong attributes.

At test time under attribute noise (`noise` stage) the robot's detectors
report some binary attributes wrongly, the same ones at every step of a run;
a model trained only on correct attributes puts large weights on single
attributes (a container that is movable and empty) and follows a wrong one.
This method adds `noise_copies` copies of its training steps in which
each binary attribute of each object is flipped with probability
`noise_rate` (`features.perception.noisy_copies`), labelled with the
demonstrated step, so the weights spread over attributes and relations that
agree. Both settings were chosen on the development world under noise
(`scripts/noise_training.py`, docs/model.md); C is chosen by `select` as
for every MRF method.
"""

from __future__ import annotations

from dataclasses import dataclass

from taskseq.evaluate.methods import ScorerMethod
from taskseq.methods.spec import Build, MethodSpec, register


@dataclass(frozen=True)
class NoiseTraining:
    """How the copies of the training steps are seen: chosen on the development world (docs/model.md)."""

    noise_rate: float = 0.1  # each binary attribute flipped with this probability in a copy
    noise_copies: int = 3  # copies of the training steps

    def __post_init__(self) -> None:
        if not 0.0 <= self.noise_rate <= 1.0:
            raise ValueError(f"noise_rate must lie in [0, 1] (a probability of flipping an attribute), got "
                             f"{self.noise_rate}")
        if self.noise_copies < 0:
            raise ValueError(f"noise_copies must be at least 0, got {self.noise_copies}")


def make(b: Build) -> ScorerMethod:
    return b.mrf("relations", noise_rate=b.settings.noise_rate, noise_copies=b.settings.noise_copies)


SPEC = register(MethodSpec("noise_trained", "ours + relations + noisy training", make, settings=NoiseTraining))
