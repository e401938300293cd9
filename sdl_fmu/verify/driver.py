"""The path-following driver of the closed-loop manoeuvres: pure pursuit of a look-ahead point on a path.

Pure pursuit (Coulter, "Implementation of the Pure Pursuit Path Tracking Algorithm", CMU-RI-TR-92-01, 1992):
the driver aims the centre of gravity at the path point a look-ahead distance ahead and steers the road
wheels to the kinematic curvature of the arc through it, delta = atan(L * 2 sin(alpha) / l_d). The look-ahead
grows with speed (a preview time), as a human driver's does.
"""

from __future__ import annotations

import math

import numpy as np

PREVIEW_TIME = 0.3  # s of look-ahead at the current speed (sdl-fmu's choice, tuned on the shipped models)
MIN_LOOKAHEAD = 4.0  # m


class PathFollower:
    """Steers along a polyline path (x increasing or any shape), sampled densely (<= 0.1 m between points)."""

    def __init__(self, x: np.ndarray, y: np.ndarray, wheelbase: float, max_steer: float = math.radians(35),
                 preview_time: float = PREVIEW_TIME, min_lookahead: float = MIN_LOOKAHEAD):
        self.x, self.y = np.asarray(x, float), np.asarray(y, float)
        self.s = np.concatenate(([0.0], np.cumsum(np.hypot(np.diff(self.x), np.diff(self.y)))))
        self.wheelbase, self.max_steer, self.preview_time = wheelbase, max_steer, preview_time
        self.min_lookahead = min_lookahead
        self.index = 0  # nearest path point, searched forward from the last one

    def nearest(self, x: float, y: float) -> int:
        window = slice(self.index, min(self.index + 400, len(self.x)))
        distance = (self.x[window] - x) ** 2 + (self.y[window] - y) ** 2
        self.index += int(np.argmin(distance))
        return self.index

    def steer(self, state) -> float:
        i = self.nearest(state.x, state.y)
        lookahead = max(self.min_lookahead, self.preview_time * state.v)
        target = self.s[i] + lookahead
        tx, ty = np.interp(target, self.s, self.x), np.interp(target, self.s, self.y)
        if target > self.s[-1]:  # beyond the end: continue along the last segment
            dx, dy = self.x[-1] - self.x[-2], self.y[-1] - self.y[-2]
            extra = (target - self.s[-1]) / math.hypot(dx, dy)
            tx, ty = self.x[-1] + dx * extra, self.y[-1] + dy * extra
        alpha = math.atan2(ty - state.y, tx - state.x) - state.psi
        distance = math.hypot(tx - state.x, ty - state.y)
        steer = math.atan(2 * self.wheelbase * math.sin(alpha) / max(distance, 1e-6))
        return min(max(steer, -self.max_steer), self.max_steer)
