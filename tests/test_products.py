"""`learn.products.matmul` sums every entry in one order, whatever the shapes it is handed.

It is read with a matrix for every row of a batch, with a matrix per step,
and with several weight matrices side by side; each way must give the bits of
the plain loop that adds a[..., i, k] * b[..., k, j] for k = 0, 1, 2, ... and
skips the zero terms of `a` (the sum the score tables' kernel makes too).
"""

from __future__ import annotations

import numpy as np
import pytest

from taskseq.learn.products import dot, matmul


def _reference(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The sum as the kernel promises it, one entry at a time in Python."""
    batch = np.broadcast_shapes(a.shape[:-2], b.shape[:-2])
    a, b = np.broadcast_to(a, batch + a.shape[-2:]), np.broadcast_to(b, batch + b.shape[-2:])
    out = np.zeros(batch + (a.shape[-2], b.shape[-1]))
    for idx in np.ndindex(*batch):
        for i in range(a.shape[-2]):
            for j in range(b.shape[-1]):
                total = 0.0
                for k in range(a.shape[-1]):
                    if a[idx + (i, k)] != 0.0:
                        total += a[idx + (i, k)] * b[idx + (k, j)]
                out[idx + (i, j)] = total
    return out


def _sparse(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """Values of mixed magnitude (sums that round) with a third of them zero, as feature rows are."""
    x = rng.normal(size=shape) * 10.0 ** rng.integers(-3, 4, size=shape)
    x[rng.random(shape) < 0.35] = 0.0
    return x


@pytest.mark.parametrize(("a_shape", "b_shape"), [
    ((7, 5), (5, 3)),  # two matrices
    ((4, 6, 5), (5, 3)),  # a matrix for every row of a batch
    ((4, 6, 5), (4, 5, 3)),  # a matrix per item, the batch shapes equal
    ((1, 6, 5), (4, 5, 3)),  # broadcast over the batch
    ((3, 4, 6, 5), (4, 5, 2)),  # broadcast over a leading axis
])
def test_every_shape_gives_the_bits_of_the_ordered_loop(a_shape, b_shape):
    rng = np.random.default_rng(len(a_shape) * 10 + len(b_shape))
    a, b = _sparse(rng, a_shape), _sparse(rng, b_shape)
    out = matmul(a, b)
    expected = _reference(a, b)
    assert out.shape == np.matmul(a, b).shape
    assert out.tobytes() == expected.tobytes()


def test_a_vector_and_a_view_give_the_bits_of_their_copies():
    rng = np.random.default_rng(3)
    a, v = _sparse(rng, (4, 6, 5)), _sparse(rng, (5,))
    assert matmul(a, v).tobytes() == _reference(a, v[:, None])[..., 0].tobytes()
    wide = _sparse(rng, (9, 5))
    assert matmul(a[:, ::2], wide.T).tobytes() == matmul(np.ascontiguousarray(a[:, ::2]),
                                                          np.ascontiguousarray(wide.T)).tobytes()


def test_columns_side_by_side_sum_as_each_alone():
    """The two slots' weights in one product give each slot's table as its own product does."""
    rng = np.random.default_rng(5)
    rows, w1, w2 = _sparse(rng, (40, 9)), _sparse(rng, (7, 9)), _sparse(rng, (7, 9))
    both = matmul(rows, np.concatenate([w1.T, w2.T], axis=1))
    assert both[:, :7].tobytes() == matmul(rows, w1.T).tobytes()
    assert both[:, 7:].tobytes() == matmul(rows, w2.T).tobytes()


def test_shapes_that_do_not_match_are_named():
    with pytest.raises(ValueError, match=r"shapes \(3, 4\) and \(5, 2\)"):
        matmul(np.zeros((3, 4)), np.zeros((5, 2)))
    with pytest.raises(ValueError, match="two vectors of one length"):
        dot(np.zeros(3), np.zeros(4))
