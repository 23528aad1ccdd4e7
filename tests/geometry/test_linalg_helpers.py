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


def test_numpys_linalg_gufuncs_called_directly_give_its_bits():
    """solve, eigvalsh, eigh_stack, svd, det and einsum: numpy's own routines without their
    wrappers, so numpy's bits (single matrices and stacks, well and badly conditioned)."""
    from handeye.geometry.linalg import det, eigh_stack, eigvalsh, einsum, solve, svd

    rng = np.random.default_rng(7)
    for n in (3, 6, 12, 19):
        for condition in (1.0, 1e8):
            A = rng.normal(size=(n, n)) @ np.diag(np.geomspace(1.0, condition, n)) @ rng.normal(size=(n, n))
            S = A + A.T
            b = rng.normal(size=n)
            assert np.array_equal(solve(A, b), np.linalg.solve(A, b))
            assert np.array_equal(eigvalsh(S), np.linalg.eigvalsh(S))
            assert np.array_equal(det(A), np.linalg.det(A))
            stack = rng.normal(size=(5, n, n))
            for mine, numpys in zip(eigh_stack(stack + np.swapaxes(stack, 1, 2)),
                                    np.linalg.eigh(stack + np.swapaxes(stack, 1, 2))):
                assert np.array_equal(mine, numpys)
            for mine, numpys in zip(svd(stack), np.linalg.svd(stack)):
                assert np.array_equal(mine, numpys)
            assert np.array_equal(det(stack), np.linalg.det(stack))
            assert np.array_equal(einsum("ij,ij->j", A, A), np.einsum("ij,ij->j", A, A))


def test_numpys_linalg_gufuncs_raise_its_errors():
    """A singular system raises LinAlgError as np.linalg.solve does, and the SVD of NaNs its
    non-convergence, not a warning and NaNs."""
    from handeye.geometry.linalg import solve, svd

    with pytest.raises(np.linalg.LinAlgError, match="Singular matrix"):
        solve(np.zeros((3, 3)), np.ones(3))
    with pytest.raises(np.linalg.LinAlgError, match="SVD did not converge"):
        svd(np.full((3, 3), np.nan))


def test_median_leaves_its_input_alone():
    """median sorts a copy: the caller's array (which ravel may hand it) keeps its order."""
    from handeye.geometry.linalg import median

    for n in (5, 6, 1001, 1002):
        x = np.random.default_rng(n).normal(size=n)
        before = x.copy()
        assert median(x) == np.median(x)
        assert np.array_equal(x, before)
