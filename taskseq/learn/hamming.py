"""The Hamming loss of a step's labelling (primitive, a1, a2), as terms that add to the score tables.

Loss-augmented inference maximises score plus loss; with the loss split by
part it adds to the tables the oracle already maximises over, so the paper
world's model (`learn.mrf`) and a domain's (`veil.mrf`) find the most violated
labelling with the same search as the best one. -1 marks an empty slot.
"""

from __future__ import annotations

import numpy as np


def hamming_terms(gold: np.ndarray | None, n_steps: int, n_prim: int, n_objects: int
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per step: the loss of each primitive (S, n_prim), of each object in slot 1 and 2 (S, N), and of leaving
    slot 1 or 2 empty (S,); all zeros without `gold` (S, 3) (plain inference)."""
    S, N = n_steps, n_objects
    if gold is None:
        return np.zeros((S, n_prim)), np.zeros((S, N)), np.zeros((S, N)), np.zeros(S), np.zeros(S)
    return ((np.arange(n_prim)[None, :] != gold[:, :1]).astype(float),
            (np.arange(N)[None, :] != gold[:, 1:2]).astype(float),
            (np.arange(N)[None, :] != gold[:, 2:3]).astype(float),
            (gold[:, 1] != -1).astype(float), (gold[:, 2] != -1).astype(float))
