"""Rotation helpers: matrix <-> axis-angle <-> (yaw, pitch, roll), with validation.

Convention: rotations are 3x3 proper orthonormal matrices acting on column
vectors in the right-handed, z-up frame of CONVENTIONS.md. For arrays of row
vectors ``P`` of shape (N, 3), apply ``R`` as ``P @ R.T``.

``(yaw, pitch, roll)`` describe the orientation of a viewing direction, the
way a camera is pointed:

- yaw: about +z, counter-clockwise seen from above, from +x towards +y (the
  same sense as an object's yaw). Note that the panorama's lon grows the
  other way: a view at yaw ``a`` looks at ``lon = -a``.
- pitch: elevation, positive looks up.
- roll: about the viewing direction, right-handed (``Rx(roll)``): positive
  turns the view's up vector towards its right (-y of the local frame), so the
  scene in the view image appears turned counter-clockwise.

``ypr_to_matrix(yaw, pitch, roll) = Rz(yaw) @ Ry(-pitch) @ Rx(roll)`` maps a
local frame (x forward, y left, z up) into the world frame: its first column
is the viewing direction.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._checks import float_array

__all__ = [
    "check_rotation",
    "rot_x",
    "rot_y",
    "rot_z",
    "axis_angle_to_matrix",
    "matrix_to_axis_angle",
    "ypr_to_matrix",
    "matrix_to_ypr",
    "nearest_rotation",
    "angle_difference",
]

Array = NDArray[np.float64]


def check_rotation(R: ArrayLike, name: str = "rotation", atol: float = 1e-6) -> Array:
    """Return ``R`` as a float (3, 3) array after checking it is a proper rotation.

    Raises
    ------
    ValueError
        If ``R`` is not 3x3, not finite, not orthonormal within ``atol`` or has
        determinant -1 (a reflection).
    """
    R = float_array(R, name)
    if R.shape != (3, 3):
        raise ValueError(f"{name}: expected a (3, 3) rotation matrix, got shape {R.shape}")
    err = np.abs(R @ R.T - np.eye(3)).max()
    if err > atol:
        raise ValueError(f"{name}: expected an orthonormal matrix (R @ R.T == I), deviation {err:.2e}")
    if np.linalg.det(R) < 0:
        raise ValueError(f"{name}: expected a proper rotation (det +1), got a reflection (det -1)")
    return R


def angle_difference(a: ArrayLike, b: ArrayLike, fold: int = 1) -> Array:
    """Smallest angle between angles ``a`` and ``b`` (radians, broadcast), with ``fold``-fold symmetry: in
    ``[0, pi / fold]``.

    >>> round(float(np.rad2deg(angle_difference(np.deg2rad(350.0), np.deg2rad(10.0)))), 9)
    20.0
    >>> float(np.rad2deg(angle_difference(0.0, np.pi, fold=2)))
    0.0
    """
    if int(fold) != fold or fold < 1:
        raise ValueError(f"fold: expected an integer >= 1, got {fold!r}")
    period = 2.0 * np.pi / int(fold)
    d = np.mod(np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64), period)
    return np.minimum(d, period - d)


def rot_x(a: float) -> Array:
    """Rotation by ``a`` radians about +x."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> Array:
    """Rotation by ``a`` radians about +y."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> Array:
    """Rotation by ``a`` radians about +z (counter-clockwise seen from above)."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def axis_angle_to_matrix(rotvec: ArrayLike) -> Array:
    """Rotation vector (axis * angle, radians) to a matrix (Rodrigues).

    Parameters
    ----------
    rotvec : (3,) float

    Returns
    -------
    R : (3, 3) float

    Examples
    --------
    >>> np.allclose(axis_angle_to_matrix([0, 0, np.pi / 2]) @ [1, 0, 0], [0, 1, 0])
    True
    """
    r = float_array(rotvec, "rotvec")
    if r.shape != (3,):
        raise ValueError(f"rotvec: expected shape (3,), got {r.shape}")
    theta = float(np.linalg.norm(r))
    if theta < 1e-300:
        return np.eye(3)
    k = r / theta
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(theta) * K + (1.0 - np.cos(theta)) * (K @ K)


def matrix_to_axis_angle(R: ArrayLike) -> Array:
    """Rotation matrix to a rotation vector with angle in [0, pi].

    Numerically stable near 0 and near pi (uses scipy's quaternion route).
    """
    from scipy.spatial.transform import Rotation

    R = check_rotation(R)
    return Rotation.from_matrix(R).as_rotvec()


def ypr_to_matrix(yaw: float, pitch: float = 0.0, roll: float = 0.0) -> Array:
    """Orientation of a viewing direction as a rotation matrix.

    Returns ``Rz(yaw) @ Ry(-pitch) @ Rx(roll)``, which maps the local frame
    (x forward, y left, z up) into the world frame.

    Examples
    --------
    >>> ypr_to_matrix(0.0, np.pi / 2)[:, 0].round(12) + 0.0   # looking straight up
    array([0., 0., 1.])
    """
    for n, a in (("yaw", yaw), ("pitch", pitch), ("roll", roll)):
        if not np.isfinite(a):
            raise ValueError(f"{n}: expected a finite angle in radians, got {a!r}")
    return rot_z(yaw) @ rot_y(-pitch) @ rot_x(roll)


def matrix_to_ypr(R: ArrayLike) -> tuple[float, float, float]:
    """Inverse of :func:`ypr_to_matrix`.

    Returns
    -------
    yaw, pitch, roll : float
        yaw and roll in (-pi, pi], pitch in [-pi/2, pi/2]. At pitch = +-pi/2
        (gimbal lock) the roll is set to 0 and the yaw absorbs it.
    """
    R = check_rotation(R)
    f = R[:, 0]
    pitch = float(np.arctan2(f[2], np.hypot(f[0], f[1])))
    if np.hypot(f[0], f[1]) < 1e-12:
        # The local y axis stays horizontal: R[:, 1] = (-sin(yaw), cos(yaw), 0).
        return float(np.arctan2(-R[0, 1], R[1, 1])), pitch, 0.0
    yaw = float(np.arctan2(f[1], f[0]))
    # Undo yaw and pitch, what remains is Rx(roll).
    rem = (rot_z(yaw) @ rot_y(-pitch)).T @ R
    roll = float(np.arctan2(rem[2, 1], rem[1, 1]))
    return yaw, pitch, roll


def nearest_rotation(M: ArrayLike) -> Array:
    """The proper rotation closest to ``M`` in the Frobenius norm (SVD projection).

    Parameters
    ----------
    M : (3, 3) float
    """
    M = float_array(M, "M")
    if M.shape != (3, 3):
        raise ValueError(f"M: expected shape (3, 3), got {M.shape}")
    U, _, Vt = np.linalg.svd(M)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt)) or 1.0])
    return U @ D @ Vt
