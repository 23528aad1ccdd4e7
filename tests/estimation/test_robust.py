"""The robust losses of the least-squares engine: the weight each returns is the derivative of
its loss (iteratively re-weighted least squares weights a pair by rho'(s)), checked against a
central difference of rho itself, on both sides of the threshold c."""

from __future__ import annotations

import numpy as np
import pytest

from handeye.estimation.robust import DEFAULT_LOSS_SCALE, LOSSES, loss_terms


@pytest.mark.parametrize("c", [1.0, DEFAULT_LOSS_SCALE])
@pytest.mark.parametrize("loss", LOSSES)
def test_each_weight_is_the_derivative_of_its_loss(loss, c):
    s = np.concatenate([np.linspace(0.01, 0.9, 7) * c * c, np.linspace(1.1, 50.0, 9) * c * c])
    h = 1e-6 * s
    rho_plus, _ = loss_terms(s + h, loss, c)
    rho_minus, _ = loss_terms(s - h, loss, c)
    rho, weight = loss_terms(s, loss, c)
    np.testing.assert_allclose(weight, (rho_plus - rho_minus) / (2 * h), rtol=1e-7)
    assert np.all(rho <= s + 1e-12) and np.all(weight <= 1.0)  # robust: never above least squares
