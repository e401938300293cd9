"""The ModelStructure of all four FMUs declares exactly CasADi's structural sparsity: every output, derivative,
event indicator (FMI 3.0) and initial unknown depends on just the knowns its expression contains."""

import casadi as ca
import pytest
from fmpy import read_model_description

from sdl_fmu.dynamics import advanced, simple
from sdl_fmu.interface import DISCRETE, INPUT, OUTPUT, PARAMETER, STATE

EQUATIONS = {"simple": simple.equations, "advanced": advanced.equations}


def structural_dependencies(equations, initial):
    """name of unknown -> set of names of knowns, from CasADi's Jacobian sparsity of the model functions.

    After initialization the knowns are the states and inputs; in initialization they are the inputs and
    parameters, and x = x0(u, p), d = d0(u, p) are substituted into everything."""
    s, interface = equations.symbols, equations.interface
    names = {letter: interface.names(role) for letter, role in
             (("x", STATE), ("d", DISCRETE), ("u", INPUT), ("p", PARAMETER))}
    outputs = interface.names(OUTPUT)
    unknowns = {f"der({n})": equations.derivatives[i] for i, n in enumerate(names["x"])}
    unknowns.update({n: ca.SX(equations.outputs[n]) for n in outputs})
    unknowns.update({f"event_indicator_{k + 1}": equations.event_indicators[k]
                     for k in range(equations.event_indicators.numel())})
    unknowns.update({n: s.x[i] for i, n in enumerate(names["x"])})
    unknowns.update({n: s.d[i] for i, n in enumerate(names["d"])})
    if initial:
        x0, d0 = equations.initial_states, equations.initial_discrete
        substituted = ca.substitute([*unknowns.values()], [s.x, s.d], [x0, d0])
        unknowns = dict(zip(unknowns, substituted))
    arguments = [s.x, s.d, s.u, s.p]
    known_arguments = {2: "u", 3: "p"} if initial else {0: "x", 2: "u"}
    result = {}
    for name, expression in unknowns.items():
        function = ca.Function("f", arguments, [expression])
        depends = set()
        for argument, letter in known_arguments.items():
            sparsity = function.sparsity_jac(argument, 0)
            # columns past the interface's parameters are the runtime's own (equations.MODEL_EXCHANGE): no
            # variable, in no dependency list
            depends |= {names[letter][column] for column in sparsity.get_col() if column < len(names[letter])}
        result[name] = depends
    return result


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("model", ["simple", "advanced"])
def test_declared_dependencies_are_casadis_sparsity(simple_fmus, advanced_fmus, model, version):
    fmu = (simple_fmus if model == "simple" else advanced_fmus)[version]
    md = read_model_description(str(fmu))
    equations = EQUATIONS[model]()
    continuous = structural_dependencies(equations, initial=False)
    initial = structural_dependencies(equations, initial=True)
    lists = {"outputs": (md.outputs, continuous), "derivatives": (md.derivatives, continuous),
             "initial unknowns": (md.initialUnknowns, initial)}
    if version == 3:
        lists["event indicators"] = (md.eventIndicators, continuous)
        assert len(md.eventIndicators) == equations.event_indicators.numel()
    for kind, (declared, expected) in lists.items():
        assert declared, kind
        for unknown in declared:
            assert unknown.dependencies is not None, f"{kind} {unknown.variable.name} declares no dependencies"
            names = [v.name for v in unknown.dependencies]
            references = [v.valueReference for v in unknown.dependencies]
            assert references == sorted(set(references)), f"{kind} {unknown.variable.name}: not ascending"
            assert set(names) == expected[unknown.variable.name], f"{kind} {unknown.variable.name}"
            assert len(unknown.dependenciesKind) == len(names)
            allowed = {"dependent", "constant"} if kind == "initial unknowns" else \
                {"dependent", "constant", "fixed", "tunable", "discrete"}
            assert set(unknown.dependenciesKind) <= allowed
    feedthrough = [o.variable.name for o in md.outputs
                   if any(v.causality == "input" for v in o.dependencies)]
    print(f"{model} FMI {version}: {len(md.outputs) - len(feedthrough)} of {len(md.outputs)} outputs "
          f"without direct feedthrough; with: {feedthrough}")


def test_dependency_kinds_follow_the_partial_derivatives():
    """dependenciesKind says what the partial derivative itself depends on: nothing (constant), parameters only
    (fixed/tunable), also discrete states or Integer inputs (discrete), states or Real inputs (dependent)."""
    from sdl_fmu.fmu.codegen import variable_table
    from sdl_fmu.fmu.structure import declared_dependencies

    seen = set()
    for model, make in EQUATIONS.items():
        equations = make()
        interface, s = equations.interface, equations.symbols
        table = variable_table(interface, equations.event_indicators.numel())
        declared = declared_dependencies(equations, table)
        symbol = {}
        for letter, role in (("x", STATE), ("u", INPUT), ("p", PARAMETER)):
            for i, name in enumerate(interface.names(role)):
                symbol[name] = getattr(s, letter)[i]
        real = {v.name for v in interface.variables if v.type == "Real"}
        inputs = interface.of_role(INPUT)
        continuous = ca.vertcat(s.x, *[s.u[v.index] for v in inputs if v.type == "Real"])
        discrete = ca.vertcat(s.d, *[s.u[v.index] for v in inputs if v.type != "Real"])
        name_of = {vr: entry.name for vr, entry in enumerate(table, start=1)}
        for vr, dependencies in declared.continuous.items():
            entry = table[vr - 1]
            if entry.derivative_of is not None:
                expression = equations.derivatives[entry.index]
            elif entry.event_indicator is not None:
                expression = equations.event_indicators[entry.event_indicator]
            elif entry.variable.role == OUTPUT:
                expression = ca.SX(equations.outputs[entry.name])
            else:
                continue
            for known, kind in dependencies:
                seen.add(kind)
                partial = ca.jacobian(expression, symbol[name_of[known]])
                where = (model, entry.name, name_of[known], kind)
                if name_of[known] not in real:
                    assert kind == "dependent", where  # the only kind for Integer knowns
                elif kind == "dependent":
                    assert ca.depends_on(partial, continuous), where
                elif kind == "discrete":
                    assert ca.depends_on(partial, discrete) and not ca.depends_on(partial, continuous), where
                elif kind in ("fixed", "tunable"):
                    assert ca.depends_on(partial, s.p) and not ca.depends_on(partial, ca.vertcat(continuous, discrete)), where
                else:
                    assert kind == "constant" and partial.is_constant(), where
    assert {"dependent", "discrete", "constant"} <= seen
