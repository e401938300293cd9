"""The foreign car as an FMI 3.0 co-simulation FMU, packaged by pythonfmu3 (build: `pythonfmu3 build -f
foreign_car.py foreign_car_dynamics.py`). Its units are declared in the modelDescription's UnitDefinitions."""

from pythonfmu3 import Fmi3Causality, Fmi3Initial, Fmi3Slave, Fmi3Variability, Float64
from pythonfmu3.unit import Unit

import foreign_car_dynamics as dynamics


class ForeignCar(Fmi3Slave):
    author = "sdl-fmu test suite"
    description = ("A kinematic-bicycle car with its own equations, names, units and SAE axes "
                   "(x forward, y right, heading clockwise); no path length, no state get/set")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        dynamics.defaults(self)
        self.time = 0.0
        self.register_units([Unit(name, factor=factor, **base) for name, (factor, base) in dynamics.UNITS.items()])
        self.register_variable(Float64("time", causality=Fmi3Causality.independent,
                                       variability=Fmi3Variability.continuous))
        for name, (_, unit, text) in dynamics.INPUTS.items():
            self.register_variable(Float64(name, causality=Fmi3Causality.input, variability=Fmi3Variability.continuous,
                                           description=text, unit=None if unit == "1" else unit))
        for name, (_, unit, text) in dynamics.PARAMETERS.items():
            self.register_variable(Float64(name, causality=Fmi3Causality.parameter, variability=Fmi3Variability.fixed,
                                           initial=Fmi3Initial.exact, description=text,
                                           unit=None if unit == "1" else unit))
        for name, (_, unit, text) in dynamics.OUTPUTS.items():
            self.register_variable(Float64(name, causality=Fmi3Causality.output,
                                           variability=Fmi3Variability.continuous, description=text, unit=unit))

    def exit_initialization_mode(self):
        dynamics.initialise(self)

    def do_step(self, current_time, step_size):
        dynamics.advance(self, step_size)
        self.time = current_time + step_size
        return True
