"""``pyrobot.utils.util``'s rotation helpers (quaternions ``[x, y, z, w]``; Euler angles
``[yaw, pitch, roll]``, ``R = Rz(yaw) Ry(pitch) Rx(roll)``), in numpy."""

from __future__ import annotations

import numpy as np

__all__ = ["euler_to_quat", "quat_to_rot_mat", "rot_mat_to_quat", "euler_to_rot_mat", "quat_multiply", "quat_inverse"]


def euler_to_quat(euler):
    """``[yaw, pitch, roll]`` (rad) to a unit quaternion ``[x, y, z, w]``."""
    yaw, pitch, roll = (float(v) for v in np.asarray(euler).reshape(3))
    cy, sy = np.cos(yaw / 2), np.sin(yaw / 2)
    cp, sp = np.cos(pitch / 2), np.sin(pitch / 2)
    cr, sr = np.cos(roll / 2), np.sin(roll / 2)
    return np.array(
        [
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy,
        ]
    )


def quat_to_rot_mat(quat):
    """A quaternion ``[x, y, z, w]`` (normalised here) to a 3x3 rotation matrix."""
    x, y, z, w = np.asarray(quat, dtype=float).reshape(4) / np.linalg.norm(quat)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def euler_to_rot_mat(euler):
    """``[yaw, pitch, roll]`` (rad) to a 3x3 rotation matrix."""
    return quat_to_rot_mat(euler_to_quat(euler))


def rot_mat_to_quat(rot):
    """A 3x3 rotation matrix to a unit quaternion ``[x, y, z, w]`` with ``w >= 0``."""
    m = np.asarray(rot, dtype=float).reshape(3, 3)
    # The largest of the four squared components first (Shepperd's method).
    t = np.trace(m)
    d = [t, m[0, 0], m[1, 1], m[2, 2]]
    i = int(np.argmax(d))
    if i == 0:
        w = np.sqrt(1 + t) / 2
        q = [(m[2, 1] - m[1, 2]) / (4 * w), (m[0, 2] - m[2, 0]) / (4 * w), (m[1, 0] - m[0, 1]) / (4 * w), w]
    elif i == 1:
        x = np.sqrt(1 + m[0, 0] - m[1, 1] - m[2, 2]) / 2
        q = [x, (m[0, 1] + m[1, 0]) / (4 * x), (m[0, 2] + m[2, 0]) / (4 * x), (m[2, 1] - m[1, 2]) / (4 * x)]
    elif i == 2:
        y = np.sqrt(1 - m[0, 0] + m[1, 1] - m[2, 2]) / 2
        q = [(m[0, 1] + m[1, 0]) / (4 * y), y, (m[1, 2] + m[2, 1]) / (4 * y), (m[0, 2] - m[2, 0]) / (4 * y)]
    else:
        z = np.sqrt(1 - m[0, 0] - m[1, 1] + m[2, 2]) / 2
        q = [(m[0, 2] + m[2, 0]) / (4 * z), (m[1, 2] + m[2, 1]) / (4 * z), z, (m[1, 0] - m[0, 1]) / (4 * z)]
    q = np.array(q)
    q /= np.linalg.norm(q)
    return -q if q[3] < 0 else q


def quat_multiply(q1, q2):
    """The Hamilton product ``q1 q2`` of quaternions ``[x, y, z, w]``."""
    x1, y1, z1, w1 = np.asarray(q1, dtype=float).reshape(4)
    x2, y2, z2, w2 = np.asarray(q2, dtype=float).reshape(4)
    return np.array(
        [
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        ]
    )


def quat_inverse(q):
    """The inverse of a quaternion ``[x, y, z, w]``."""
    x, y, z, w = np.asarray(q, dtype=float).reshape(4)
    return np.array([-x, -y, -z, w]) / (x * x + y * y + z * z + w * w)
