"""CommonRoad's single-track model (commonroad-vehicle-models, `vehicle_dynamics_st`) of its BMW 320i (vehicle ID 2)
as an FMI 2.0 co-simulation FMU, packaged by PythonFMU (build: `pythonfmu build -f commonroad_st.py`). Its equations
are CommonRoad's own, called as they are; this file only wraps them.

The model has no wheels: its inputs are the front wheels' steering velocity and the longitudinal acceleration, its
tires linear in slip angle with the axle loads shifted by the acceleration (load transfer), and no wheel ever locks
(nothing saturates but CommonRoad's own acceleration limit a_max = 11.5 m/s2). The wrapper's choices:
  - brake pedal 0..1 -> acceleration -BRAKE_DECELERATION x pedal (1 g at full pedal, below a_max: the deceleration
    grows with the pedal all the way); throttle 0..1 -> +a_max x pedal (CommonRoad's acceleration_constraints then
    cap it above v_switch by a_max v_switch / v, its engine-power limit); braking and throttle add.
  - the road-wheel angle `steer` (rad) is the input: at each communication point the steering-angle state x3 is set
    to it and the steering velocity u1 is 0 (an ideal steering actuator).
  - a car braked to a stop holds there (CommonRoad's model, with v_min = -13.9 m/s, would roll backwards): a sub-step
    that would carry the speed through 0 ends the motion at 0.
  - integration: classical Runge-Kutta 4, fixed sub-steps of at most RK4_STEP in each communication step. No state
    get/set.
Outputs (ISO axes, SI): x, y of the centre of gravity, yaw, speed (CommonRoad's x4, the velocity along the heading),
yaw rate. The map is commonroad_st.toml.
"""

from math import ceil

from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Real
from vehiclemodels.parameters_vehicle2 import parameters_vehicle2
from vehiclemodels.vehicle_dynamics_st import vehicle_dynamics_st

BRAKE_DECELERATION = 9.80665  # m/s2 at full brake pedal (the wrapper's choice: 1 g)
RK4_STEP = 0.001  # s

INPUTS = {"throttle": "accelerator pedal 0..1", "brake": "brake pedal 0..1", "steer": "road-wheel angle [rad]"}
START = {"v_init": "initial speed [m/s]", "x_init": "initial x [m]", "y_init": "initial y [m]",
         "yaw_init": "initial yaw [rad]"}
OUTPUTS = {"x": "x of the centre of gravity [m]", "y": "y of the centre of gravity [m]", "yaw": "yaw angle [rad]",
           "speed": "speed along the heading [m/s]", "yaw_rate": "yaw rate [rad/s]"}


class CommonRoadSt(Fmi2Slave):
    author = "sdl-fmu test suite"
    description = "CommonRoad's single-track model (vehicle_dynamics_st) of its BMW 320i: no wheels, none locks"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.p = parameters_vehicle2()
        for name in (*INPUTS, *START, *OUTPUTS):
            setattr(self, name, 0.0)
        for name, text in INPUTS.items():
            self.register_variable(Real(name, causality=Fmi2Causality.input, variability=Fmi2Variability.continuous,
                                        description=text))
        for name, text in START.items():
            self.register_variable(Real(name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed,
                                        initial=Fmi2Initial.exact, description=text))
        for name, text in OUTPUTS.items():
            self.register_variable(Real(name, causality=Fmi2Causality.output, variability=Fmi2Variability.continuous,
                                        description=text))
        self.state = None

    def _start(self):
        # CommonRoad's state: x, y, steering angle, velocity, yaw, yaw rate, slip angle at the centre of gravity
        self.state = [self.x_init, self.y_init, 0.0, max(self.v_init, 0.0), self.yaw_init, 0.0, 0.0]
        self._publish()

    def exit_initialization_mode(self):
        self._start()

    def _publish(self):
        x, y, _, v, psi, r, _ = self.state
        self.x, self.y, self.yaw, self.speed, self.yaw_rate = x, y, psi, v, r

    def _rates(self, state, acceleration):
        if state[3] <= 0.0 and acceleration <= 0.0:
            return [0.0] * 7  # at rest, braked or coasting: it holds
        return vehicle_dynamics_st(state, [0.0, acceleration], self.p)

    def do_step(self, current_time, step_size):
        if self.state is None:
            self._start()
        pedal = min(max(self.throttle, 0.0), 1.0)
        brake = min(max(self.brake, 0.0), 1.0)
        acceleration = pedal * self.p.longitudinal.a_max - brake * BRAKE_DECELERATION
        state = list(self.state)
        state[2] = self.steer  # the ideal steering actuator
        n = max(1, ceil(step_size / RK4_STEP - 1e-9))
        h = step_size / n
        for _ in range(n):
            k1 = self._rates(state, acceleration)
            k2 = self._rates([s + 0.5 * h * k for s, k in zip(state, k1)], acceleration)
            k3 = self._rates([s + 0.5 * h * k for s, k in zip(state, k2)], acceleration)
            k4 = self._rates([s + h * k for s, k in zip(state, k3)], acceleration)
            new = [s + h / 6 * (a + 2 * b + 2 * c + d) for s, a, b, c, d in zip(state, k1, k2, k3, k4)]
            if state[3] > 0.0 and new[3] <= 0.0:
                new = list(state)  # it stops inside this sub-step: there it holds
                new[3], new[5], new[6] = 0.0, 0.0, 0.0
            state = new
        self.state = state
        self._publish()
        return True
