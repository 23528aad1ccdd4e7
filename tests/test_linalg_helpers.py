"""The fast linear-algebra helpers give numpy's own numbers, bit for bit, where they claim to."""

from __future__ import annotations

import numpy as np
import pytest

from handeye.geometry.linalg import row_norms, row_sums_of_squares


@pytest.mark.parametrize("rows", [1, 16, 255, 256, 5000])
@pytest.mark.parametrize("columns", [1, 2, 3, 6, 7, 8, 12])
def test_row_sums_of_squares_are_numpys_bits(rows, columns):
    """Column by column (many rows, fewer than 8 columns) or numpy's reduction: the same bits as
    np.add.reduce(x * x, axis=1), on contiguous and strided arrays, at scales from 1e-9 to 1e7."""
    rng = np.random.default_rng(rows * 100 + columns)
    for scale in (1e-9, 1.0, 1e7):
        x = rng.normal(size=(rows, columns + 3))[:, :columns] * scale  # a strided view
        for a in (x, np.ascontiguousarray(x)):
            assert np.array_equal(row_sums_of_squares(a), np.add.reduce(a * a, axis=1))
            assert np.array_equal(row_norms(a), np.sqrt(np.add.reduce(a * a, axis=1)))
    np.testing.assert_allclose(row_norms(x), np.linalg.norm(x, axis=1), rtol=1e-15)
