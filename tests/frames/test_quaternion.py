"""Quaternions: scalar-first [qw, qx, qy, qz], Hamilton product, active rotation, qw >= 0.

Oracles: SciPy's ``Rotation`` (scalar_first=True), the rotation matrix of the paper's Eq. 3
written out below in its homogeneous form, and a Hamilton product written in scalar/vector
form ``(pw qw - p.q, pw q + qw p + p x q)`` with the sandwich ``v' = q (0, v) q*``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from satsight.errors import SatsightError
from satsight.frames.quaternion import (
    angle_between_quaternions_rad,
    canonical_quaternion,
    matrix_from_quaternion,
    quaternion_conjugate,
    quaternion_from_axis_angle,
    quaternion_from_matrix,
    quaternion_multiply,
    rotate_vectors,
)

ATOL = 1e-12  # pure float64 algebra on unit-size numbers
ANGLE_ATOL_RAD = 1e-12
# canonical_quaternion writes a |qw| <= 1e-12 (too small to decide the sign) as non-negative,
# which can move that component by up to 2e-12.
CANONICAL_ATOL = 2e-12 + ATOL
PROPERTY = settings(max_examples=60, deadline=None)

IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])
I_UNIT = np.array([0.0, 1.0, 0.0, 0.0])
J_UNIT = np.array([0.0, 0.0, 1.0, 0.0])
K_UNIT = np.array([0.0, 0.0, 0.0, 1.0])

_component = st.floats(min_value=-1.0, max_value=1.0, allow_nan=False, allow_subnormal=False)


@st.composite
def raw_quaternions(draw: st.DrawFn) -> np.ndarray:
    """Any non-degenerate 4-vector (not normalised, either sign of qw)."""
    q = np.array([draw(_component) for _ in range(4)])
    assume(np.linalg.norm(q) > 1e-3)
    return q


@st.composite
def unit_quaternions(draw: st.DrawFn) -> np.ndarray:
    q = draw(raw_quaternions())
    return q / np.linalg.norm(q)


@st.composite
def vectors(draw: st.DrawFn, scale: float = 100.0) -> np.ndarray:
    c = st.floats(min_value=-scale, max_value=scale, allow_nan=False, allow_subnormal=False)
    return np.array([draw(c) for _ in range(3)])


@st.composite
def unit_axes(draw: st.DrawFn) -> np.ndarray:
    v = draw(vectors(scale=1.0))
    assume(np.linalg.norm(v) > 1e-3)
    return v / np.linalg.norm(v)


# --- independent oracles ---------------------------------------------------------------


def hamilton_oracle(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product in scalar/vector form."""
    pw, pv = p[0], p[1:]
    qw, qv = q[0], q[1:]
    return np.concatenate([[pw * qw - pv @ qv], pw * qv + qw * pv + np.cross(pv, qv)])


def sandwich_oracle(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Active rotation of v by the unit quaternion q: q (0, v) q*."""
    q_conj = q * np.array([1.0, -1.0, -1.0, -1.0])
    return hamilton_oracle(hamilton_oracle(q, np.concatenate([[0.0], v])), q_conj)[1:]


def eq3_matrix(q: np.ndarray) -> np.ndarray:
    """Paper Eq. 3: rotation matrix of the unit quaternion [qw, qx, qy, qz]."""
    qw, qx, qy, qz = q
    return np.array(
        [
            [
                qw**2 + qx**2 - qy**2 - qz**2,
                2 * (qx * qy - qw * qz),
                2 * (qx * qz + qw * qy),
            ],
            [
                2 * (qx * qy + qw * qz),
                qw**2 - qx**2 + qy**2 - qz**2,
                2 * (qy * qz - qw * qx),
            ],
            [
                2 * (qx * qz - qw * qy),
                2 * (qy * qz + qw * qx),
                qw**2 - qx**2 - qy**2 + qz**2,
            ],
        ]
    )


# --- Hamilton product --------------------------------------------------------------------


def test_basis_products_follow_hamilton_rules() -> None:
    # Hamilton: i j = k, j k = i, k i = j, i^2 = j^2 = k^2 = ijk = -1 (JPL would give j i = k).
    np.testing.assert_array_equal(quaternion_multiply(I_UNIT, J_UNIT), K_UNIT)
    np.testing.assert_array_equal(quaternion_multiply(J_UNIT, K_UNIT), I_UNIT)
    np.testing.assert_array_equal(quaternion_multiply(K_UNIT, I_UNIT), J_UNIT)
    np.testing.assert_array_equal(quaternion_multiply(J_UNIT, I_UNIT), -K_UNIT)
    for unit in (I_UNIT, J_UNIT, K_UNIT):
        np.testing.assert_array_equal(quaternion_multiply(unit, unit), -IDENTITY)
    ijk = quaternion_multiply(quaternion_multiply(I_UNIT, J_UNIT), K_UNIT)
    np.testing.assert_array_equal(ijk, -IDENTITY)


@PROPERTY
@given(raw_quaternions(), raw_quaternions())
def test_multiply_matches_scalar_vector_oracle(p: np.ndarray, q: np.ndarray) -> None:
    np.testing.assert_allclose(quaternion_multiply(p, q), hamilton_oracle(p, q), atol=ATOL)


@PROPERTY
@given(unit_quaternions(), unit_quaternions())
def test_product_of_unit_quaternions_is_unit(p: np.ndarray, q: np.ndarray) -> None:
    assert np.linalg.norm(quaternion_multiply(p, q)) == pytest.approx(1.0, abs=ATOL)


@PROPERTY
@given(unit_quaternions(), unit_quaternions())
def test_multiply_matches_scipy_composition(p: np.ndarray, q: np.ndarray) -> None:
    expected = (
        Rotation.from_quat(p, scalar_first=True) * Rotation.from_quat(q, scalar_first=True)
    ).as_quat(scalar_first=True)
    np.testing.assert_allclose(
        canonical_quaternion(quaternion_multiply(p, q)), canonical_quaternion(expected), atol=ATOL
    )


def test_multiply_broadcasts_over_batches() -> None:
    rng = np.random.default_rng(1)
    p = rng.normal(size=(5, 4))
    q = rng.normal(size=(5, 4))
    batch = quaternion_multiply(p, q)
    assert batch.shape == (5, 4)
    for k in range(5):
        np.testing.assert_allclose(batch[k], hamilton_oracle(p[k], q[k]), atol=ATOL)
    one_by_many = quaternion_multiply(p[0], q)
    assert one_by_many.shape == (5, 4)
    np.testing.assert_allclose(one_by_many[3], hamilton_oracle(p[0], q[3]), atol=ATOL)


@PROPERTY
@given(unit_quaternions(), unit_quaternions())
def test_composition_matches_matrix_product(q_a_from_b: np.ndarray, q_b_from_c: np.ndarray) -> None:
    q_a_from_c = quaternion_multiply(q_a_from_b, q_b_from_c)
    np.testing.assert_allclose(
        matrix_from_quaternion(q_a_from_c),
        matrix_from_quaternion(q_a_from_b) @ matrix_from_quaternion(q_b_from_c),
        atol=ATOL,
    )


# --- canonical form ----------------------------------------------------------------------


@PROPERTY
@given(raw_quaternions(), st.floats(min_value=1e-3, max_value=1e3))
def test_canonical_is_unit_with_nonnegative_qw(q: np.ndarray, scale: float) -> None:
    c = canonical_quaternion(scale * q)
    assert np.linalg.norm(c) == pytest.approx(1.0, abs=ATOL)
    assert c[0] >= 0.0
    # Same rotation as the input: c is +-q / |q|.
    unit = q / np.linalg.norm(q)
    assert min(np.abs(c - unit).max(), np.abs(c + unit).max()) <= CANONICAL_ATOL


@PROPERTY
@given(raw_quaternions())
def test_q_and_minus_q_give_same_canonical_and_matrix(q: np.ndarray) -> None:
    np.testing.assert_array_equal(canonical_quaternion(q), canonical_quaternion(-q))
    np.testing.assert_allclose(matrix_from_quaternion(q), matrix_from_quaternion(-q), atol=ATOL)


@pytest.mark.parametrize(
    ("q", "expected"),
    [
        # qw == 0 (180-degree turns): the first non-zero vector component is made positive.
        ([0.0, -1.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]),
        ([0.0, 0.0, -0.6, 0.8], [0.0, 0.0, 0.6, -0.8]),
        ([-0.0, 0.0, 0.0, -2.0], [0.0, 0.0, 0.0, 1.0]),
        # A qw below 1e-12 does not decide the sign, and is written non-negative.
        ([-1e-13, 1.0, 0.0, 0.0], [1e-13, 1.0, 0.0, 0.0]),
        ([1e-13, -1.0, 0.0, 0.0], [1e-13, 1.0, 0.0, 0.0]),
        ([-3.0, 0.0, 4.0, 0.0], [0.6, 0.0, -0.8, 0.0]),
    ],
)
def test_canonical_sign_on_the_qw_zero_boundary(q: list[float], expected: list[float]) -> None:
    c = canonical_quaternion(np.array(q))
    np.testing.assert_allclose(c, expected, atol=ATOL)
    assert c[0] >= 0.0
    assert not np.signbit(c[0])  # not even -0.0
    np.testing.assert_array_equal(c, canonical_quaternion(-np.array(q)))


def test_canonical_works_on_batches() -> None:
    rng = np.random.default_rng(2)
    q = rng.normal(size=(4, 3, 4))
    c = canonical_quaternion(q)
    assert c.shape == q.shape
    np.testing.assert_allclose(np.linalg.norm(c, axis=-1), 1.0, atol=ATOL)
    assert np.all(c[..., 0] >= 0.0)


# --- matrices ----------------------------------------------------------------------------


@PROPERTY
@given(unit_quaternions())
def test_matrix_is_a_proper_rotation(q: np.ndarray) -> None:
    R = matrix_from_quaternion(q)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=ATOL)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=ATOL)


@PROPERTY
@given(unit_quaternions())
def test_matrix_matches_scipy(q: np.ndarray) -> None:
    expected = Rotation.from_quat(q, scalar_first=True).as_matrix()
    np.testing.assert_allclose(matrix_from_quaternion(q), expected, atol=ATOL)


@PROPERTY
@given(unit_quaternions())
def test_matrix_matches_paper_eq3(q: np.ndarray) -> None:
    np.testing.assert_allclose(matrix_from_quaternion(q), eq3_matrix(q), atol=ATOL)


def test_matrix_of_non_unit_quaternion_is_of_its_direction() -> None:
    q = np.array([1.0, 2.0, -3.0, 0.5])
    np.testing.assert_allclose(
        matrix_from_quaternion(7.0 * q), eq3_matrix(q / np.linalg.norm(q)), atol=ATOL
    )


@PROPERTY
@given(unit_quaternions())
def test_quaternion_matrix_quaternion_round_trip(q: np.ndarray) -> None:
    back = quaternion_from_matrix(matrix_from_quaternion(q))
    np.testing.assert_allclose(back, canonical_quaternion(q), atol=ATOL)
    assert back[0] >= 0.0


def test_matrix_quaternion_matrix_round_trip_batch() -> None:
    R = Rotation.random(50, rng=np.random.default_rng(3)).as_matrix()
    q = quaternion_from_matrix(R)
    assert q.shape == (50, 4)
    assert np.all(q[:, 0] >= 0.0)
    np.testing.assert_allclose(matrix_from_quaternion(q), R, atol=ATOL)
    # Batches keep their leading shape.
    assert quaternion_from_matrix(R.reshape(5, 10, 3, 3)).shape == (5, 10, 4)


@pytest.mark.parametrize(
    ("R", "expected"),
    [
        (np.diag([1.0, -1.0, -1.0]), [0.0, 1.0, 0.0, 0.0]),  # 180 deg about x
        (np.diag([-1.0, 1.0, -1.0]), [0.0, 0.0, 1.0, 0.0]),  # 180 deg about y
        (np.diag([-1.0, -1.0, 1.0]), [0.0, 0.0, 0.0, 1.0]),  # 180 deg about z
        (np.eye(3), [1.0, 0.0, 0.0, 0.0]),
    ],
)
def test_quaternion_from_matrix_known_cases(R: np.ndarray, expected: list[float]) -> None:
    np.testing.assert_allclose(quaternion_from_matrix(R), expected, atol=ATOL)


# --- the active rotation -----------------------------------------------------------------


def test_90_degrees_about_z_maps_x_to_y() -> None:
    q = quaternion_from_axis_angle([0.0, 0.0, 1.0], math.pi / 2)
    c45 = math.cos(math.radians(45.0))
    np.testing.assert_allclose(q, [c45, 0.0, 0.0, c45], atol=ATOL)
    x, y = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    np.testing.assert_allclose(matrix_from_quaternion(q) @ x, y, atol=ATOL)
    np.testing.assert_allclose(rotate_vectors(q, x), y, atol=ATOL)
    np.testing.assert_allclose(sandwich_oracle(q, x), y, atol=ATOL)
    # And y goes to -x: a right-handed (counter-clockwise seen from +z) turn.
    np.testing.assert_allclose(rotate_vectors(q, y), -x, atol=ATOL)


@PROPERTY
@given(unit_quaternions())
def test_conjugate_is_inverse(q: np.ndarray) -> None:
    q_conj = quaternion_conjugate(q)
    np.testing.assert_allclose(quaternion_multiply(q, q_conj), IDENTITY, atol=ATOL)
    np.testing.assert_allclose(quaternion_multiply(q_conj, q), IDENTITY, atol=ATOL)
    np.testing.assert_allclose(
        matrix_from_quaternion(q_conj), matrix_from_quaternion(q).T, atol=ATOL
    )


@PROPERTY
@given(unit_quaternions(), vectors())
def test_rotate_vectors_matches_sandwich_and_matrix(q: np.ndarray, v: np.ndarray) -> None:
    rotated = rotate_vectors(q, v)
    tol = ATOL * max(1.0, float(np.abs(v).max()))
    np.testing.assert_allclose(rotated, sandwich_oracle(q, v), atol=tol)
    np.testing.assert_allclose(rotated, matrix_from_quaternion(q) @ v, atol=tol)
    assert np.linalg.norm(rotated) == pytest.approx(np.linalg.norm(v), abs=tol)


def test_rotate_vectors_batches() -> None:
    rng = np.random.default_rng(4)
    q = rng.normal(size=(6, 4))
    v = rng.normal(size=(6, 3))
    one_q = rotate_vectors(q[0], v)
    per_vector = rotate_vectors(q, v)
    assert one_q.shape == per_vector.shape == (6, 3)
    for k in range(6):
        np.testing.assert_allclose(one_q[k], matrix_from_quaternion(q[0]) @ v[k], atol=ATOL)
        np.testing.assert_allclose(per_vector[k], matrix_from_quaternion(q[k]) @ v[k], atol=ATOL)


# --- axis-angle --------------------------------------------------------------------------


@PROPERTY
@given(unit_axes(), st.floats(min_value=-2 * math.pi, max_value=2 * math.pi))
def test_axis_angle_matches_scipy_rotvec(axis: np.ndarray, angle_rad: float) -> None:
    q = quaternion_from_axis_angle(axis, angle_rad)
    assert q[0] >= 0.0
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=ATOL)
    expected = Rotation.from_rotvec(axis * angle_rad).as_matrix()
    np.testing.assert_allclose(matrix_from_quaternion(q), expected, atol=ATOL)
    # The axis is the fixed direction of the rotation.
    np.testing.assert_allclose(rotate_vectors(q, axis), axis, atol=ATOL)


@PROPERTY
@given(unit_axes(), st.floats(min_value=0.0, max_value=2 * math.pi))
def test_angle_between_identity_and_axis_angle(axis: np.ndarray, angle_rad: float) -> None:
    q = quaternion_from_axis_angle(axis, angle_rad)
    expected = angle_rad if angle_rad <= math.pi else 2 * math.pi - angle_rad
    assert angle_between_quaternions_rad(IDENTITY, q) == pytest.approx(expected, abs=1e-9)


def test_axis_angle_normalises_the_axis_and_is_right_handed() -> None:
    q = quaternion_from_axis_angle([0.0, 0.0, 5.0], math.pi / 2)
    np.testing.assert_allclose(q, quaternion_from_axis_angle([0.0, 0.0, 1.0], math.pi / 2))
    # +90 deg about x maps y to z.
    q_x = quaternion_from_axis_angle([1.0, 0.0, 0.0], math.pi / 2)
    np.testing.assert_allclose(rotate_vectors(q_x, [0.0, 1.0, 0.0]), [0.0, 0.0, 1.0], atol=ATOL)


def test_axis_angle_batches() -> None:
    axes = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
    angles = np.array([0.1, 0.2, 0.3])
    per_axis = quaternion_from_axis_angle(axes, angles)
    assert per_axis.shape == (3, 4)
    for k in range(3):
        np.testing.assert_allclose(
            per_axis[k], quaternion_from_axis_angle(axes[k], angles[k]), atol=ATOL
        )
    # Many axes, one angle; one axis, many angles.
    many_axes = quaternion_from_axis_angle(axes, 0.3)
    np.testing.assert_allclose(many_axes[2], quaternion_from_axis_angle(axes[2], 0.3), atol=ATOL)
    many_angles = quaternion_from_axis_angle(axes[0], angles)
    np.testing.assert_allclose(
        many_angles[1], quaternion_from_axis_angle(axes[0], angles[1]), atol=ATOL
    )


# --- geodesic angle ----------------------------------------------------------------------


@PROPERTY
@given(unit_quaternions())
def test_angle_between_a_quaternion_and_itself_or_its_negative_is_zero(q: np.ndarray) -> None:
    assert angle_between_quaternions_rad(q, q) <= ANGLE_ATOL_RAD
    assert angle_between_quaternions_rad(q, -q) <= ANGLE_ATOL_RAD


@PROPERTY
@given(unit_quaternions(), unit_axes(), st.floats(min_value=1e-9, max_value=math.pi))
def test_angle_between_recovers_a_relative_turn(
    q: np.ndarray, axis: np.ndarray, angle_rad: float
) -> None:
    q2 = quaternion_multiply(q, quaternion_from_axis_angle(axis, angle_rad))
    got = angle_between_quaternions_rad(q, q2)
    assert got == pytest.approx(angle_rad, rel=1e-7, abs=1e-11)
    assert angle_between_quaternions_rad(q2, q) == pytest.approx(got, abs=ANGLE_ATOL_RAD)


# --- errors ------------------------------------------------------------------------------


@pytest.mark.parametrize("shape", [(3,), (5,), (2, 3), (4, 2)])
def test_bad_quaternion_shapes_raise(shape: tuple[int, ...]) -> None:
    bad = np.ones(shape)
    for fn in (canonical_quaternion, quaternion_conjugate, matrix_from_quaternion):
        with pytest.raises(SatsightError, match="4 components"):
            fn(bad)
    with pytest.raises(SatsightError, match="4 components"):
        quaternion_multiply(bad, IDENTITY)
    with pytest.raises(SatsightError, match="4 components"):
        rotate_vectors(bad, [1.0, 0.0, 0.0])


@pytest.mark.parametrize("q", [np.zeros(4), np.full(4, 1e-9)])
def test_zero_quaternion_raises(q: np.ndarray) -> None:
    with pytest.raises(SatsightError, match="zero length"):
        canonical_quaternion(q)
    with pytest.raises(SatsightError, match="zero length"):
        matrix_from_quaternion(q)
    with pytest.raises(SatsightError, match="zero length"):
        canonical_quaternion(np.stack([IDENTITY, q]))  # one bad row spoils the batch


@pytest.mark.parametrize(
    "R",
    [
        2.0 * np.eye(3),  # scaled
        np.diag([1.0, 1.0, -1.0]),  # reflection, det -1
        -np.eye(3),  # point inversion, det -1
        np.array([[1.0, 0.1, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]),  # shear
        np.zeros((3, 3)),
        np.full((3, 3), np.nan),
    ],
)
def test_non_rotation_matrix_raises(R: np.ndarray) -> None:
    with pytest.raises(SatsightError, match="not a proper rotation"):
        quaternion_from_matrix(R)


@pytest.mark.parametrize("shape", [(3,), (2, 2), (4, 4), (3, 4)])
def test_bad_matrix_shapes_raise(shape: tuple[int, ...]) -> None:
    with pytest.raises(SatsightError, match=r"\(\.\.\., 3, 3\)"):
        quaternion_from_matrix(np.ones(shape))


def test_bad_vectors_and_axes_raise() -> None:
    with pytest.raises(SatsightError, match="3 components"):
        rotate_vectors(IDENTITY, np.ones((4, 2)))
    with pytest.raises(SatsightError, match="batch shape"):
        rotate_vectors(np.tile(IDENTITY, (2, 1)), np.ones((3, 3)))
    with pytest.raises(SatsightError, match="non-zero"):
        quaternion_from_axis_angle([0.0, 0.0, 0.0], 1.0)
    with pytest.raises(SatsightError, match="3 components"):
        quaternion_from_axis_angle([1.0, 0.0], 1.0)
