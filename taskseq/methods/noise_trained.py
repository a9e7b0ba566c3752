"""ours + relations + noisy training: the relations model, trained also on steps seen with wrong attributes.

At test time under attribute noise (`noise` stage) the robot's detectors
report some binary attributes wrongly, the same ones at every step of a run;
a model trained only on correct attributes puts large weights on single
attributes (a container that is movable and empty) and follows a wrong one.
This method adds `train.noise_copies` copies of its training steps in which
each binary attribute of each object is flipped with probability
`train.noise_rate` (`features.perception.noisy_copies`), labelled with the
demonstrated step, so the weights spread over attributes and relations that
agree. Both settings were chosen on the development world under noise
(`scripts/noise_training.py`, docs/model.md); C is chosen by `select` as
for every MRF method.
"""

from __future__ import annotations

from taskseq.evaluate.methods import MRFMethod
from taskseq.evaluate.registry import MethodSettings, register


@register("noise_trained", label="ours + relations + noisy training")
def make(settings: MethodSettings) -> MRFMethod:
    learner = settings.learner
    return MRFMethod(features="relations", noise_rate=learner.noise_rate, noise_copies=learner.noise_copies,
                     name="noise_trained", store=settings.store, **learner.ssvm)
