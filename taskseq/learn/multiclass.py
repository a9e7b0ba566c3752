"""A multiclass problem as a structured model: one weight block per class.

With 0/1 loss and the 1-slack SSVM this is the Crammer-Singer multiclass SVM,
which is how the learner is checked against scikit-learn's `LinearSVC`.
"""

from __future__ import annotations

import numpy as np


class MulticlassModel:
    """x: feature vector of length `n_features`; y: class index in [0, n_classes)."""

    def __init__(self, n_features: int, n_classes: int) -> None:
        self.n_features = n_features
        self.n_classes = n_classes
        self.size_joint_feature = n_features * n_classes

    def joint_feature(self, x: np.ndarray, y: int) -> np.ndarray:
        out = np.zeros(self.size_joint_feature)
        out[y * self.n_features : (y + 1) * self.n_features] = x
        return out

    def loss(self, y: int, y_hat: int) -> float:
        return float(y != y_hat)

    def _scores(self, x: np.ndarray, w: np.ndarray) -> np.ndarray:
        return w.reshape(self.n_classes, self.n_features) @ x

    def inference(self, x: np.ndarray, w: np.ndarray) -> int:
        return int(np.argmax(self._scores(x, w)))

    def loss_augmented_inference(self, x: np.ndarray, y: int, w: np.ndarray) -> int:
        scores = self._scores(x, w) + 1.0
        scores[y] -= 1.0
        return int(np.argmax(scores))
