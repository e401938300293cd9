"""The foreign AEB controller as an FMI 3.0 co-simulation FMU, packaged by pythonfmu3 (build: `pythonfmu3 build -f
foreign_aeb.py foreign_aeb_logic.py`). Its units are declared in the modelDescription's UnitDefinitions."""

from pythonfmu3 import Boolean, Fmi3Causality, Fmi3Initial, Fmi3Slave, Fmi3Variability, Float64, Int32
from pythonfmu3.unit import Unit

import foreign_aeb_logic as logic


class ForeignAeb(Fmi3Slave):
    author = "sdl-fmu test suite"
    description = "An emergency brake latched on time to collision, with its own names and units"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        logic.defaults(self)
        self.time = 0.0
        self.register_units([Unit(name, factor=factor, **base) for name, (factor, base) in logic.UNITS.items()])
        self.register_variable(Float64("time", causality=Fmi3Causality.independent,
                                       variability=Fmi3Variability.continuous))
        for name, (_, unit, text) in logic.INPUTS.items():
            self.register_variable(Float64(name, causality=Fmi3Causality.input, variability=Fmi3Variability.continuous,
                                           description=text, unit=unit))
        for name, (_, text) in logic.BOOLEAN_INPUTS.items():
            self.register_variable(Boolean(name, causality=Fmi3Causality.input, variability=Fmi3Variability.discrete,
                                           description=text))
        for name, (_, text) in logic.INTEGER_INPUTS.items():
            self.register_variable(Int32(name, causality=Fmi3Causality.input, variability=Fmi3Variability.discrete,
                                         description=text))
        for name, (_, unit, text) in logic.PARAMETERS.items():
            self.register_variable(Float64(name, causality=Fmi3Causality.parameter, variability=Fmi3Variability.fixed,
                                           initial=Fmi3Initial.exact, description=text, unit=unit))
        for name, (_, unit, text) in logic.OUTPUTS.items():
            self.register_variable(Float64(name, causality=Fmi3Causality.output, variability=Fmi3Variability.discrete,
                                           description=text, unit=unit))
        for name, (_, text) in logic.BOOLEAN_OUTPUTS.items():
            self.register_variable(Boolean(name, causality=Fmi3Causality.output, variability=Fmi3Variability.discrete,
                                           description=text))
        for name, (_, text) in logic.INTEGER_OUTPUTS.items():
            self.register_variable(Int32(name, causality=Fmi3Causality.output, variability=Fmi3Variability.discrete,
                                         description=text))

    def do_step(self, current_time, step_size):
        ok = logic.step(self, current_time, step_size)
        self.time = current_time + step_size
        return ok
