"""The foreign AEB controller as an FMI 2.0 co-simulation FMU, packaged by PythonFMU (build: `pythonfmu build -f
foreign_aeb_fmi2.py foreign_aeb_logic.py`, with --handle-state for the variant that can get and set its state).
PythonFMU 0.7 cannot declare units: the controller map gives them."""

from pythonfmu import Boolean, Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Integer, Real

import foreign_aeb_logic as logic


class ForeignAebFmi2(Fmi2Slave):
    author = "sdl-fmu test suite"
    description = "An emergency brake latched on time to collision, with its own names and units"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        logic.defaults(self)
        for name, (_, unit, text) in logic.INPUTS.items():
            self.register_variable(Real(name, causality=Fmi2Causality.input, variability=Fmi2Variability.continuous,
                                        description=f"{text} [{unit}]"))
        for name, (_, text) in logic.BOOLEAN_INPUTS.items():
            self.register_variable(Boolean(name, causality=Fmi2Causality.input, variability=Fmi2Variability.discrete,
                                           description=text))
        for name, (_, text) in logic.INTEGER_INPUTS.items():
            self.register_variable(Integer(name, causality=Fmi2Causality.input, variability=Fmi2Variability.discrete,
                                           description=text))
        for name, (_, unit, text) in logic.PARAMETERS.items():
            self.register_variable(Real(name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed,
                                        initial=Fmi2Initial.exact, description=f"{text} [{unit}]"))
        for name, (_, unit, text) in logic.OUTPUTS.items():
            self.register_variable(Real(name, causality=Fmi2Causality.output, variability=Fmi2Variability.discrete,
                                        description=f"{text} [{unit}]"))
        for name, (_, text) in logic.BOOLEAN_OUTPUTS.items():
            self.register_variable(Boolean(name, causality=Fmi2Causality.output,
                                           variability=Fmi2Variability.discrete, description=text))
        for name, (_, text) in logic.INTEGER_OUTPUTS.items():
            self.register_variable(Integer(name, causality=Fmi2Causality.output,
                                           variability=Fmi2Variability.discrete, description=text))

    def do_step(self, current_time, step_size):
        return logic.step(self, current_time, step_size)
