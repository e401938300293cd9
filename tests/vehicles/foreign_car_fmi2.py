"""The foreign car as an FMI 2.0 co-simulation FMU, packaged by PythonFMU (build: `pythonfmu build -f
foreign_car_fmi2.py foreign_car_dynamics.py`). PythonFMU 0.7 cannot declare units: the vehicle map gives them."""

from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Real

import foreign_car_dynamics as dynamics


class ForeignCarFmi2(Fmi2Slave):
    author = "sdl-fmu test suite"
    description = ("A kinematic-bicycle car with its own equations, names, units and SAE axes "
                   "(x forward, y right, heading clockwise); no path length, no state get/set")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        dynamics.defaults(self)
        for name, (_, unit, text) in dynamics.INPUTS.items():
            self.register_variable(Real(name, causality=Fmi2Causality.input, variability=Fmi2Variability.continuous,
                                        description=f"{text} [{unit}]"))
        for name, (_, unit, text) in dynamics.PARAMETERS.items():
            self.register_variable(Real(name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed,
                                        initial=Fmi2Initial.exact, description=f"{text} [{unit}]"))
        self.running = False
        for name, (_, unit, text) in dynamics.OUTPUTS.items():
            self.register_variable(Real(name, causality=Fmi2Causality.output, variability=Fmi2Variability.continuous,
                                        description=f"{text} [{unit}]", getter=lambda name=name: self._output(name)))

    def _output(self, name):
        """An output; before the first step, that of the start values and inputs set so far (an importer may read
        the outputs in initialization mode: SSP masters pass them on to the other FMUs there)."""
        if not self.running:
            dynamics.initialise(self)
        return getattr(self, name)

    def exit_initialization_mode(self):
        dynamics.initialise(self)
        self.running = True

    def do_step(self, current_time, step_size):
        dynamics.advance(self, step_size)
        return True
