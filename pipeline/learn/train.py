"""Fitting the MRF with the SSVM: the glue a stage calls, with a progress bar."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits
from tqdm import tqdm

from ..features.context import StepContext
from .mrf import MRFModel
from .ssvm import CuttingPlaneSSVM


@dataclass
class Fit:
    model: MRFModel
    ssvm: CuttingPlaneSSVM
    seconds: float  # wall time of every fit that led to this one
    steps: int  # training steps of the last fit

    @property
    def w(self) -> np.ndarray:
        return self.ssvm.w_


def fit_mrf(contexts: list[StepContext], features: str = "full", C: float = 3.0, tol: float = 1e-3,
            max_iter: int = 2000, n_slacks: int = 4, progress: bool = False) -> Fit:
    model = MRFModel(features)
    # a bar on a terminal only: logs of CI and DVC stay readable
    bar = tqdm(total=max_iter, desc=f"ssvm {features}", unit="it", disable=None if progress else True,
               leave=False, mininterval=0.5)

    def tick(it) -> None:
        bar.update(1)
        bar.set_postfix(gap=f"{it.gap:.3g}", constraints=it.n_constraints)

    start = time.perf_counter()
    ssvm = CuttingPlaneSSVM(model, C=C, tol=tol, max_iter=max_iter, n_slacks=n_slacks, progress=tick)
    # one BLAS thread: a multi-threaded BLAS may sum in another order, and the weights must be the same
    # bytes whether this runs in the main process or in a joblib worker (whose BLAS threads differ)
    try:
        with threadpool_limits(limits=1):
            ssvm.fit(contexts, [x.gold for x in contexts])
    finally:
        bar.close()
    return Fit(model, ssvm, time.perf_counter() - start, len(contexts))
