"""Matrix and vector products summed in one fixed order: the same bits on every x86-64 processor.

Why not `@`: NumPy hands float64 `@`, `dot` and `matmul` to OpenBLAS, which
picks its kernels when it loads, from the processor it finds (Haswell,
SkylakeX, Sandybridge, ...). The kernels block and order their sums
differently, so one product differs in its last bits from one processor to the
next: the score tables of a batch came out as four different sets of bits
under `OPENBLAS_CORETYPE` Haswell, SkylakeX, Sandybridge and Prescott, and
`w . w` as three. Through the oracle's argmax (near ties) and the learner's
objectives (its stopping test and the QP's tolerance) those bits can reach the
learned weights.

These kernels add the terms of every entry in the order k = 0, 1, 2, ...,
each term one IEEE multiply then one add: Numba neither fuses them into an FMA
nor reorders the sum unless asked for `fastmath`, so the result is the same
whatever instructions the processor offers (tests/test_processor_independence.py).
On the learner's tall, narrow, mostly zero products they run within a small
factor of single-threaded BLAS (docs/speed.md gives the fit times).
"""

from __future__ import annotations

import numpy as np
from numba import njit


def matmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """`np.matmul(a, b)` for float64 `a` of two or more axes (leading axes broadcast), `b` a vector or a stack."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    vector = b.ndim == 1
    if vector:
        b = b[:, None]
    if a.ndim < 2 or a.shape[-1] != b.shape[-2]:
        raise ValueError(f"matmul: shapes {a.shape} and {b.shape} do not match")
    (m, k), n = a.shape[-2:], b.shape[-1]
    if b.ndim == 2:  # one matrix for every row of `a`: its rows as one matrix (each entry summed alike)
        rows = a.shape[:-1]
        a3, b3 = np.ascontiguousarray(a.reshape(-1, k))[None], np.ascontiguousarray(b)[None]
    elif a.shape[:-2] == b.shape[:-2]:  # a matrix per item, the batch shapes equal: nothing to broadcast
        rows = a.shape[:-1]
        a3, b3 = np.ascontiguousarray(a.reshape(-1, m, k)), np.ascontiguousarray(b.reshape(-1, k, n))
    else:
        batch = np.broadcast_shapes(a.shape[:-2], b.shape[:-2])
        rows = batch + (m,)
        # C order for both: one compiled signature, and the inner loop reads b's rows contiguously
        a3 = np.ascontiguousarray(np.broadcast_to(a, batch + (m, k)).reshape(-1, m, k))
        b3 = np.ascontiguousarray(np.broadcast_to(b, batch + (k, n)).reshape(-1, k, n))
    out = np.zeros((a3.shape[0], a3.shape[1], n))
    _matmul(a3, b3, out)
    out = out.reshape(rows + (n,))
    return out[..., 0] if vector else out


def dot(a: np.ndarray, b: np.ndarray) -> float:
    """The inner product of two float64 vectors, summed from the first entry to the last."""
    a, b = np.ascontiguousarray(a, dtype=np.float64), np.ascontiguousarray(b, dtype=np.float64)
    if a.ndim != 1 or a.shape != b.shape:
        raise ValueError(f"dot: needs two vectors of one length, got shapes {a.shape} and {b.shape}")
    return float(_dot(a, b))


@njit(cache=True)
def _matmul(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    """out[s] += a[s] @ b[s] (`out` zeros on entry), each entry's terms added in k order.

    A term whose factor from `a` is zero is skipped: feature rows are mostly
    zeros (77% of the relation rows), and adding 0 * b changes no sum but the
    sign of a zero. Which terms are skipped depends on the data only, so the
    order stays fixed. Row by row with the zero terms skipped, the relation
    product ran four times faster than the dense loop.
    """
    for s in range(a.shape[0]):
        for i in range(a.shape[1]):
            for k in range(a.shape[2]):
                x = a[s, i, k]
                if x != 0.0:
                    for j in range(b.shape[2]):
                        out[s, i, j] += x * b[s, k, j]


@njit(cache=True)
def _dot(a: np.ndarray, b: np.ndarray) -> float:
    total = 0.0
    for k in range(a.shape[0]):
        total += a[k] * b[k]
    return total
