"""The planar rigid body both ego models share: how position, heading, path length and the body-frame
velocities (vx, vy, yaw rate r) move under a body-frame force per unit mass (ax, ay) and a yaw moment."""

from __future__ import annotations

import casadi as ca


def body_derivatives(s, moving, ax, ay, yaw_moment, path_speed) -> dict:
    """d/dt of x, y, psi, s, vx, vy, yaw_rate (ISO 8855 axes); `moving` (0 or 1) freezes the body while it is
    held at rest, `path_speed` is what s integrates (|v|, or a smoothed form of it)."""
    vx, vy, r, psi = s["vx"], s["vy"], s["yaw_rate"], s["psi"]
    return {
        "x": moving * (vx * ca.cos(psi) - vy * ca.sin(psi)),
        "y": moving * (vx * ca.sin(psi) + vy * ca.cos(psi)),
        "psi": moving * r,
        "s": moving * path_speed,
        "vx": ax + moving * r * vy,
        "vy": ay - moving * r * vx,
        "yaw_rate": moving * yaw_moment / s["yaw_inertia"],
    }
