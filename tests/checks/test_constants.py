"""Constants that have an independent derivation, checked against it (scipy.stats), so that a
changed value is caught even where no accuracy test moves with it."""

from __future__ import annotations

import math

import pytest
from scipy import stats

from handeye.checks import best_fit
from handeye.estimation import robust, whitening
from handeye.geometry import validation
from handeye.plugins import auto


def test_robust_loss_scale_is_the_95_percent_point_of_a_6_vector_norm():
    """c of the robust losses: sqrt of chi^2_6's 95% quantile (a pair longer is an outlier at 5%)."""
    assert robust.DEFAULT_LOSS_SCALE == pytest.approx(math.sqrt(stats.chi2.ppf(0.95, 6)), rel=1e-10)


def test_chi3_median_is_the_median_norm_of_a_standard_3_vector():
    """median |n| for n ~ N(0, I3): turns a median residual norm into a per-axis sigma."""
    assert whitening.CHI3_MEDIAN == pytest.approx(stats.chi.median(3), rel=1e-12)


def test_mad_to_sigma_is_one_over_the_normal_75_percent_point():
    """sigma = MAD_TO_SIGMA * median |x| for x ~ N(0, sigma^2)."""
    assert robust.MAD_TO_SIGMA == pytest.approx(1.0 / stats.norm.ppf(0.75), rel=1e-12)


def test_noise_sources_gain_is_half_the_1_percent_point_of_chi2_with_6_dof():
    """Auto's likelihood-ratio test of 8 variances against 2 at 1%: a gain in nats is half the
    chi^2 statistic."""
    from handeye.estimation.noise_sources import min_gain

    assert min_gain(8) == pytest.approx(stats.chi2.ppf(0.99, 6) / 2, abs=1e-9) == pytest.approx(8.4, abs=0.01)


def test_outlier_threshold_is_eight_robust_sigmas_and_shared():
    """8 robust sigmas (squared), one constant for auto's outlier step and the self-check."""
    assert robust.OUTLIER_CHI2 == 8.0**2
    assert auto.OUTLIER_CHI2 is robust.OUTLIER_CHI2 and best_fit.OUTLIER_CHI2 is robust.OUTLIER_CHI2
    # far beyond the chi^2_6 99.9% point, where heavier-tailed real residuals flagged clean pairs
    assert robust.OUTLIER_CHI2 > 2 * stats.chi2.ppf(0.999, 6)


def test_agreement_angle_covers_clean_pairs_at_ten_times_the_study_noise():
    """Two pairs agree when robot and camera turn by angles within AGREEMENT_ANGLE: at ten times
    the accuracy study's camera noise (0.02 rad per axis on each of two stations) the difference
    of the angles has a standard deviation of at most 0.02 * sqrt(2) rad; 5 deg is 3 of those."""
    assert validation.AGREEMENT_ANGLE == pytest.approx(math.radians(5.0))
    assert validation.AGREEMENT_ANGLE > 3 * 0.02 * math.sqrt(2)
