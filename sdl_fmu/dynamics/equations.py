"""What a dynamics model hands to the FMU build: CasADi expressions over the interface's vectors.

Every expression is a function of the same four vectors (x, d, u, p) — continuous states, discrete
states, inputs, parameters — laid out in the order of the interface data, so the generated C knows
the model only through them.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from ..interface import DISCRETE, INPUT, OUTPUT, PARAMETER, STATE, Interface


@dataclass
class Symbols:
    """The CasADi vectors of one interface and a name -> element lookup."""

    x: ca.SX
    d: ca.SX
    u: ca.SX
    p: ca.SX
    by_name: dict

    def __getitem__(self, name: str) -> ca.SX:
        return self.by_name[name]


# A parameter the runtime sets, not the importer: 1 in a model-exchange instance, 0 in a co-simulation one. A model
# that asks for it (make_symbols(..., runtime=True)) finds it after the interface's parameters in p; it is in no
# modelDescription and no dependency list (ModelInfo.model_exchange_parameter, instance.c).
MODEL_EXCHANGE = "model_exchange"


def make_symbols(interface: Interface, runtime: bool = False) -> Symbols:
    vectors = {}
    by_name = {}
    for role, letter in ((STATE, "x"), (DISCRETE, "d"), (INPUT, "u"), (PARAMETER, "p")):
        names = interface.names(role) + ([MODEL_EXCHANGE] if runtime and role == PARAMETER else [])
        vector = ca.SX.sym(letter, len(names))
        vectors[letter] = vector
        for i, name in enumerate(names):
            by_name[name] = vector[i]
    return Symbols(by_name=by_name, **vectors)


@dataclass
class Equations:
    interface: Interface
    symbols: Symbols
    derivatives: ca.SX  # dx/dt, one per state
    outputs: dict  # output name -> expression, one per interface output
    event_indicators: ca.SX  # a sign change of any entry is an event
    state_update: ca.SX  # x after the discrete update at an event
    discrete_update: ca.SX  # d after the discrete update at an event
    initial_states: ca.SX  # x at initialization, from the parameters
    initial_discrete: ca.SX  # d at initialization
    # Optional cases of the same equations with a branch fixed: case (a function of p) selects cases[case] at run
    # time, and the generated functions evaluate only that case; the expressions above are their union (both
    # branches), from which the dependencies are read.
    cases: tuple = ()
    case: ca.SX | None = None

    def check(self) -> None:
        """Sizes and names agree with the interface (caught at build time, not in C)."""
        s = self.symbols
        expected = {
            "derivatives": (self.derivatives, s.x.numel()),
            "state_update": (self.state_update, s.x.numel()),
            "initial_states": (self.initial_states, s.x.numel()),
            "discrete_update": (self.discrete_update, s.d.numel()),
            "initial_discrete": (self.initial_discrete, s.d.numel()),
        }
        for name, (expression, size) in expected.items():
            if expression.numel() != size:
                raise ValueError(f"{self.interface.model_name}: {name} has {expression.numel()} entries, expected {size}")
        missing = set(self.interface.names(OUTPUT)) ^ set(self.outputs)
        if missing:
            raise ValueError(f"{self.interface.model_name}: outputs and interface disagree on {sorted(missing)}")

    def functions(self) -> dict[str, ca.Function]:
        """The six CasADi functions the C runtime calls, all with arguments (x, d, u, p). With cases, each function
        runs only the selected case's expressions (a CasADi Switch: the other case is neither evaluated nor
        differentiated); its outputs keep the sparsity of the union expressions."""
        full = self._functions("")
        if not self.cases:
            return full
        s = self.symbols
        model = self.interface.model_name
        args = [s.x, s.d, s.u, s.p]
        names = ["x", "d", "u", "p"]
        selector = ca.Function(f"{model}_case", args, [self.case], names, ["case"])
        per_case = [case._functions(f"_case{index}") for index, case in enumerate(self.cases)]
        switched = {}
        for key, function in full.items():
            *earlier, last = [functions[key] for functions in per_case]
            switch = ca.Function.conditional(f"{model}_{key}_switch", earlier, last)
            symbols = [ca.MX.sym(name, function.sparsity_in(i)) for i, name in enumerate(names)]
            results = switch(selector(*symbols), *symbols)
            results = results if isinstance(results, (list, tuple)) else [results]
            switched[key] = ca.Function(
                function.name(), symbols,
                [ca.project(result, function.sparsity_out(i)) for i, result in enumerate(results)],
                names, function.name_out())
        return switched

    def _functions(self, suffix: str) -> dict[str, ca.Function]:
        self.check()
        s = self.symbols
        args = [s.x, s.d, s.u, s.p]
        names = ["x", "d", "u", "p"]
        model = self.interface.model_name + suffix
        outputs = ca.vertcat(*[self.outputs[name] for name in self.interface.names(OUTPUT)])
        return {
            "derivatives": ca.Function(f"{model}_derivatives", args, [self.derivatives], names, ["xdot"]),
            "jacobian": ca.Function(
                f"{model}_jacobian", args, [ca.densify(ca.jacobian(self.derivatives, s.x))], names, ["jac"]
            ),
            "outputs": ca.Function(f"{model}_outputs", args, [outputs], names, ["y"]),
            "event_indicators": ca.Function(f"{model}_event_indicators", args, [self.event_indicators], names, ["z"]),
            "discrete_update": ca.Function(
                f"{model}_discrete_update", args, [self.state_update, self.discrete_update], names, ["x_next", "d_next"]
            ),
            "initial_state": ca.Function(
                f"{model}_initial_state", args, [self.initial_states, self.initial_discrete], names, ["x0", "d0"]
            ),
        }
