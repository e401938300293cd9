"""The Simple dynamics (SPEC section 2, sdl_fmu/dynamics/simple.py) as a PythonFMU slave, for the per-step
cost benchmark only: the same equations, no stop event, integrated with classic RK4 at 1 ms substeps
(the native FMU takes RODAS4 steps of 1 ms)."""

import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

G = 9.80665
WHEELS = ("fl", "fr", "rl", "rr")


class SimplePythonFmu(Fmi2Slave):
    author = "sdl-fmu benchmarks"
    description = "Simple point-mass vehicle dynamics in Python (benchmark)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.throttle = 0.0
        self.brake = 0.0
        self.steer = 0.0
        self.mu_fl = self.mu_fr = self.mu_rl = self.mu_rr = 0.8
        self.mass, self.brake_decel_max, self.drive_accel_max, self.drive_power_max = 1500.0, 9.81, 4.0, 110000.0
        self.drag_area, self.air_density, self.rolling_resistance, self.wheelbase = 0.7, 1.225, 0.012, 2.7
        self.solver_step = 1e-3
        self.x, self.y, self.psi, self.s, self.v = 0.0, -1.8288, 0.0, 0.0, 26.8224
        for name in ("throttle", "brake", "steer", *[f"mu_{w}" for w in WHEELS]):
            self.register_variable(Real(name, causality=Fmi2Causality.input))
        for name in ("mass", "brake_decel_max", "drive_accel_max", "drive_power_max", "drag_area", "air_density",
                     "rolling_resistance", "wheelbase", "solver_step"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.tunable))
        for name in ("x", "y", "psi", "s", "v"):
            self.register_variable(Real(name, causality=Fmi2Causality.output))

    def derivatives(self, state):
        x, y, psi, s, v = state
        drive = self.throttle * min(self.drive_accel_max, self.drive_power_max / (self.mass * max(v, 1e-3)))
        demand = drive - self.brake * self.brake_decel_max
        lateral_demand = v * v * math.tan(self.steer) / self.wheelbase
        along_sum = scale_sum = 0.0
        for mu in (self.mu_fl, self.mu_fr, self.mu_rl, self.mu_rr):
            limit = mu * G
            along = min(max(demand, -limit), limit)
            available = math.sqrt(max(limit * limit - along * along, 1e-12))
            along_sum += along
            scale_sum += available / max(abs(lateral_demand), available, 1e-9)
        drag = self.air_density * self.drag_area / (2 * self.mass)
        net = along_sum / 4 - self.rolling_resistance * G - drag * v * v
        yaw = v * math.tan(self.steer) / self.wheelbase * scale_sum / 4
        return (v * math.cos(psi), v * math.sin(psi), yaw, v, net)

    def do_step(self, current_time, step_size):
        substeps = max(1, math.ceil(step_size / self.solver_step - 1e-9))
        h = step_size / substeps
        state = (self.x, self.y, self.psi, self.s, self.v)
        for _ in range(substeps):
            k1 = self.derivatives(state)
            k2 = self.derivatives([a + h / 2 * b for a, b in zip(state, k1)])
            k3 = self.derivatives([a + h / 2 * b for a, b in zip(state, k2)])
            k4 = self.derivatives([a + h * b for a, b in zip(state, k3)])
            state = tuple(a + h / 6 * (b + 2 * c + 2 * d + e) for a, b, c, d, e in zip(state, k1, k2, k3, k4))
        self.x, self.y, self.psi, self.s, self.v = state
        return True
