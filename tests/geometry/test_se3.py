"""Property tests of handeye.geometry.se3 (hypothesis): exp/log, stable rotation angle, inverse,
projection onto SO(3), Gram-Schmidt, quaternions."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from handeye.geometry.se3 import (
    gram_schmidt,
    inverse,
    make_pose,
    matrix_from_quat,
    orthonormality_error,
    project_to_so3,
    quat_from_matrix,
    random_poses,
    random_rotations,
    rotation_angle,
    skew,
    so3_exp,
    so3_log,
    vee,
)

finite = st.floats(-1.0, 1.0, allow_nan=False)
unit_vectors = st.tuples(finite, finite, finite).map(np.array).filter(lambda v: np.linalg.norm(v) > 1e-3).map(
    lambda v: v / np.linalg.norm(v))
seeds = st.integers(0, 2**32 - 1)


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' formula written out, independent of so3_exp."""
    K = skew(axis)
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


@given(unit_vectors, st.floats(0.0, np.pi - 1e-6))
def test_exp_log_roundtrip(axis, angle):
    w = angle * axis
    R = so3_exp(w)
    np.testing.assert_allclose(R, _rotation(axis, angle), atol=1e-13)
    np.testing.assert_allclose(so3_log(R), w, atol=1e-9)
    assert orthonormality_error(R) < 1e-14
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-14)


@given(seeds)
def test_log_exp_roundtrip_on_random_rotations(seed):
    R = random_rotations(5, np.random.default_rng(seed))
    np.testing.assert_allclose(so3_exp(so3_log(R)), R, atol=1e-12)
    assert np.all(np.linalg.norm(so3_log(R), axis=1) <= np.pi + 1e-12)


@given(unit_vectors, st.floats(-12.0, -3.0))
def test_rotation_angle_tiny(axis, log_angle):
    angle = 10.0**log_angle
    R = _rotation(axis, angle)
    assert rotation_angle(R) == pytest.approx(angle, rel=1e-9)
    # arccos((tr R - 1) / 2) would give 0 or ~1e-8 here: the point of the stable formula
    np.testing.assert_allclose(rotation_angle(so3_exp(angle * axis)), angle, rtol=1e-9)


@given(unit_vectors, st.floats(1e-8, 1e-3))
def test_rotation_angle_near_pi(axis, gap):
    angle = np.pi - gap
    R = _rotation(axis, angle)
    assert rotation_angle(R) == pytest.approx(angle, abs=1e-12)
    assert rotation_angle(_rotation(axis, np.pi)) == pytest.approx(np.pi, abs=1e-12)


@given(unit_vectors, st.floats(0.0, np.pi))
def test_rotation_angle_is_in_range_and_symmetric(axis, angle):
    R = _rotation(axis, angle)
    assert 0.0 <= rotation_angle(R) <= np.pi
    assert rotation_angle(R.T) == pytest.approx(rotation_angle(R), abs=1e-14)
    assert rotation_angle(R) == pytest.approx(angle, abs=1e-12)


def test_rotation_angle_vectorised():
    R = random_rotations(7, np.random.default_rng(0)).reshape(7, 3, 3)
    stacked = np.stack([R, R])
    assert rotation_angle(stacked).shape == (2, 7)
    np.testing.assert_allclose(rotation_angle(stacked)[1], np.linalg.norm(so3_log(R), axis=1), atol=1e-12)


@given(seeds, st.floats(1e-3, 1e4))
def test_inverse(seed, scale):
    T = random_poses(6, np.random.default_rng(seed), translation_scale=scale)
    T_before = T.copy()
    Ti = inverse(T)
    np.testing.assert_allclose(T @ Ti, np.broadcast_to(np.eye(4), T.shape), atol=1e-12 * max(1.0, scale))
    np.testing.assert_allclose(Ti, np.linalg.inv(T), atol=1e-12 * max(1.0, scale))
    np.testing.assert_array_equal(Ti[:, 3], np.broadcast_to([0.0, 0.0, 0.0, 1.0], (6, 4)))
    np.testing.assert_array_equal(T, T_before)
    np.testing.assert_allclose(inverse(Ti), T, atol=1e-12 * max(1.0, scale))


@given(seeds)
def test_project_to_so3_of_rotation_is_itself(seed):
    R = random_rotations(5, np.random.default_rng(seed))
    np.testing.assert_allclose(project_to_so3(R), R, atol=1e-13)


@given(seeds, st.floats(1e-3, 10.0))
def test_project_to_so3_gives_a_nearest_rotation(seed, scale):
    rng = np.random.default_rng(seed)
    M = scale * rng.standard_normal((4, 3, 3))
    P = project_to_so3(M)
    assert np.all(orthonormality_error(P) < 1e-12)
    np.testing.assert_allclose(np.linalg.det(P), 1.0, atol=1e-12)
    # no random rotation is closer to M in Frobenius norm
    others = random_rotations(50, rng)
    for Mi, Pi in zip(M, P):
        assert np.linalg.norm(Mi - Pi) <= np.min(np.linalg.norm(others - Mi, axis=(1, 2))) + 1e-12


@given(seeds)
def test_gram_schmidt_is_a_rotation_keeping_the_first_column(seed):
    rng = np.random.default_rng(seed)
    M = rng.standard_normal((5, 3, 3))
    G = gram_schmidt(M)
    assert np.all(orthonormality_error(G) < 1e-12)
    np.testing.assert_allclose(np.linalg.det(G), 1.0, atol=1e-12)  # also for det(M) < 0
    c1 = M[:, :, 0] / np.linalg.norm(M[:, :, 0], axis=1, keepdims=True)
    np.testing.assert_allclose(G[:, :, 0], c1, atol=1e-12)
    # the second column lies in the span of the first two columns of M, on c2's side
    assert np.all(np.sum(G[:, :, 1] * M[:, :, 1], axis=1) > 0)
    normal = np.cross(M[:, :, 0], M[:, :, 1])
    np.testing.assert_allclose(np.sum(G[:, :, 1] * normal, axis=1), 0.0, atol=1e-9)


@given(seeds)
def test_gram_schmidt_of_rotation_is_itself(seed):
    R = random_rotations(4, np.random.default_rng(seed))
    np.testing.assert_allclose(gram_schmidt(R), R, atol=1e-13)


@given(st.tuples(finite, finite, finite).map(np.array))
def test_skew_vee(v):
    np.testing.assert_array_equal(vee(skew(v)), v)
    np.testing.assert_allclose(skew(v) @ np.array([0.3, -1.0, 2.0]), np.cross(v, [0.3, -1.0, 2.0]), atol=1e-15)
    np.testing.assert_array_equal(skew(v), -skew(v).T)


@given(seeds)
def test_quaternion_roundtrip(seed):
    R = random_rotations(5, np.random.default_rng(seed))
    q = quat_from_matrix(R)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-14)
    np.testing.assert_allclose(matrix_from_quat(q), R, atol=1e-13)
    np.testing.assert_allclose(matrix_from_quat(-q), R, atol=1e-13)


def test_quaternion_order_is_xyzw():
    R = _rotation(np.array([0.0, 0.0, 1.0]), np.pi / 2)
    np.testing.assert_allclose(quat_from_matrix(R), [0.0, 0.0, np.sqrt(0.5), np.sqrt(0.5)], atol=1e-15)


def test_make_pose_shapes():
    T = make_pose(np.broadcast_to(np.eye(3), (2, 5, 3, 3)), np.ones((2, 5, 3)))
    assert T.shape == (2, 5, 4, 4)
    np.testing.assert_array_equal(T[..., 3, :], np.broadcast_to([0.0, 0.0, 0.0, 1.0], (2, 5, 4)))
