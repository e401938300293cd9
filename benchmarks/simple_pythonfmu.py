"""The current Simple dynamics (sdl_fmu/dynamics/simple.py) as a PythonFMU slave, for the per-step cost
benchmark only. The equations come from the same CasADi model: its derivatives function (x, d, u, p) ->
dx/dt, built once in __init__ from sdl_fmu.dynamics.simple.equations() and evaluated in Python inside
classic RK4 at 1 ms substeps (the native FMU takes error-controlled RODAS4 steps; table 1 also shows it
at fixed 1 ms steps). That is what a PythonFMU user with this model would write. No events: the discrete
states are held at their initial values (moving, every wheel rolling forward); the benchmark drives
forward and never stops. The FMU needs sdl_fmu and casadi importable by the Python that loads it."""

import math

import numpy as np
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

from sdl_fmu.dynamics.simple import equations
from sdl_fmu.interface import DISCRETE, INPUT, OUTPUT, PARAMETER, STATE

RK4_STEP = 1e-3  # s: the slave's own fixed-step integrator (the native FMU's parameter solver_step is registered
# but, as the longest step of an error-controlled method, has no meaning for RK4)


class SimplePythonFmu(Fmi2Slave):
    author = "sdl-fmu benchmarks"
    description = "Simple planar vehicle dynamics, the model's CasADi equations evaluated in Python (benchmark)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        model = equations()
        interface = model.interface
        functions = model.functions()
        self._derivatives = functions["derivatives"]
        self._outputs = functions["outputs"]
        self._initial_state = functions["initial_state"]
        self._inputs = interface.names(INPUT)
        self._parameters = interface.names(PARAMETER)
        self._states = interface.names(STATE)
        self._speed_index = interface.names(OUTPUT).index("v")
        for v in interface.of_role(INPUT):
            setattr(self, v.name, v.start)
            self.register_variable(Real(v.name, causality=Fmi2Causality.input))
        for v in interface.of_role(PARAMETER):
            setattr(self, v.name, v.start)
            self.register_variable(Real(v.name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.tunable))
        self._state = np.zeros(len(self._states))
        self._discrete = np.zeros(len(interface.names(DISCRETE)))
        self.exit_initialization_mode()
        for name in (*self._states, "v"):
            self.register_variable(Real(name, causality=Fmi2Causality.output, getter=self._getter(name)))

    def _getter(self, name):
        if name == "v":
            return lambda: float(self._outputs(self._state, self._discrete, self._input_vector(),
                                               self._parameter_vector())[self._speed_index])
        index = self._states.index(name)
        return lambda: float(self._state[index])

    def _input_vector(self):
        return np.array([getattr(self, n) for n in self._inputs])

    def _parameter_vector(self):
        return np.array([getattr(self, n) for n in self._parameters])

    def exit_initialization_mode(self):
        # the initial states from the parameters as set by the importer (v0, x0, ...)
        x0, d0 = self._initial_state(self._state, self._discrete, self._input_vector(), self._parameter_vector())
        self._state = np.asarray(x0, dtype=float).ravel()
        self._discrete = np.asarray(d0, dtype=float).ravel()
        return True

    def do_step(self, current_time, step_size):
        substeps = max(1, math.ceil(step_size / RK4_STEP - 1e-9))
        h = step_size / substeps
        d, u, p = self._discrete, self._input_vector(), self._parameter_vector()

        def f(x):
            return np.asarray(self._derivatives(x, d, u, p)).ravel()

        x = self._state
        for _ in range(substeps):
            k1 = f(x)
            k2 = f(x + h / 2 * k1)
            k3 = f(x + h / 2 * k2)
            k4 = f(x + h * k3)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        self._state = x
        return True
