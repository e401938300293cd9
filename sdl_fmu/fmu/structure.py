"""Exact derivatives and the true dependency structure of a model, both from CasADi.

The FMI layer sees two vectors per model:
  unknowns U = [x, d, xdot, y, z]   (states, discrete states, derivatives, outputs, event indicators)
  knowns   K = [x, u, p]            (states, inputs, parameters)
In the modes after initialization U is a function of K as the equations say. In initialization the states
and discrete states are themselves unknowns, x = x0(u, p) and d = d0(u, p), substituted into the rest.

From these, CasADi generates the C functions the runtime calls for fmi2/fmi3GetDirectionalDerivative
(forward mode: seed over K -> sensitivity over U) and fmi3GetAdjointDerivative (reverse mode: seed over
U -> sensitivity over K), and the structural sparsity of dU/dK that the ModelStructure declares.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from ..dynamics.equations import Equations
from ..interface import DISCRETE, INPUT, OUTPUT, PARAMETER, STATE

# Order of the C functions in ModelInfo after the six model functions (see model.h).
DERIVATIVE_FUNCTIONS = ("unknowns_forward", "unknowns_adjoint", "initial_forward", "initial_adjoint")


@dataclass
class Unknowns:
    """U over K, after initialization (`continuous`) and in initialization (`initial`)."""

    known: ca.SX  # K = [x; u; p]
    continuous: ca.SX  # U = [x; d; xdot; y; z]
    initial: ca.SX  # U with x = x0, d = d0
    sizes: dict  # nx, nd, ny, nz, nu, np


def unknowns(equations: Equations) -> Unknowns:
    s = equations.symbols
    interface = equations.interface
    outputs = ca.vertcat(*[ca.SX(equations.outputs[name]) for name in interface.names(OUTPUT)])
    body = ca.vertcat(equations.derivatives, outputs, equations.event_indicators)
    continuous = ca.vertcat(s.x, s.d, body)
    x0, d0 = equations.initial_states, equations.initial_discrete
    initial_body = ca.substitute(body, ca.vertcat(s.x, s.d), ca.vertcat(x0, d0))
    initial = ca.vertcat(x0, d0, initial_body)
    sizes = {"nx": s.x.numel(), "nd": s.d.numel(), "ny": outputs.numel(),
             "nz": equations.event_indicators.numel(), "nu": s.u.numel(), "np": s.p.numel()}
    return Unknowns(ca.vertcat(s.x, s.u, s.p), continuous, initial, sizes)


def zero_subgradient_at_roots(expression: ca.SX, inputs: list[ca.SX]) -> ca.SX:
    """The same expression with every sqrt(a) read as (a > 0 ? sqrt(a) : 0).

    Its values are unchanged where they are defined, but its derivatives at a = 0 become 0 instead of 0/0:
    a norm sqrt(a^2 + b^2) at the origin (a car at rest, a tire without force) gets the subgradient 0, not
    NaN. Done by replaying CasADi's instruction list, so it works for any model."""
    function = ca.Function("rewritten", inputs, [expression])
    work: dict[int, ca.SX] = {}
    result = [ca.SX(0)] * expression.numel()
    for k in range(function.n_instructions()):
        op = function.instruction_id(k)
        arguments = function.instruction_input(k)
        destination = function.instruction_output(k)
        if op == ca.OP_INPUT:
            work[destination[0]] = inputs[arguments[0]].nz[arguments[1]]
        elif op == ca.OP_OUTPUT:
            result[destination[1]] = work[arguments[0]]
        elif op == ca.OP_CONST:
            work[destination[0]] = ca.SX(function.instruction_constant(k))
        elif op == ca.OP_SQRT:
            radicand = work[arguments[0]]
            work[destination[0]] = ca.if_else(radicand > 0, ca.sqrt(radicand), 0)
        elif len(arguments) == 1:
            work[destination[0]] = ca.SX.unary(op, work[arguments[0]])
        else:
            work[destination[0]] = ca.SX.binary(op, work[arguments[0]], work[arguments[1]])
    return ca.reshape(ca.vertcat(*result), expression.shape) if result else expression


def derivative_functions(equations: Equations, model: str) -> dict[str, ca.Function]:
    """The four CasADi functions (x, d, u, p, seed) -> sensitivity of the runtime's derivative calls.

    unknowns_forward: (dU/dK) w, unknowns_adjoint: (dU/dK)^T v, at the current x and d.
    initial_forward: (dx0/dK) w, initial_adjoint: (dx0/dK)^T v_x. In initialization the runtime chains them
    (dU/dK at x = x0 plus dU/dx dx0/dK): the discrete start d0(u, p) is piecewise constant, so it adds nothing,
    and the chain keeps the generated code half the size of differentiating the substituted U once more."""
    s = equations.symbols
    system = unknowns(equations)
    args = [s.x, s.d, s.u, s.p]
    known = system.known
    unknown = zero_subgradient_at_roots(system.continuous, args)
    initial_states = zero_subgradient_at_roots(equations.initial_states, args)
    names = ["x", "d", "u", "p"]
    seed_known = ca.SX.sym("seed_known", known.numel())
    seed_unknown = ca.SX.sym("seed_unknown", unknown.numel())
    seed_state = ca.SX.sym("seed_state", s.x.numel())
    # forward mode: J w; reverse mode: J^T v (jtimes with transpose=True runs CasADi's reverse sweep);
    # cse merges the subexpressions the sweeps repeat (about 40 % fewer operations for the Advanced model)
    sweeps = {
        "unknowns_forward": (seed_known, ca.cse(ca.jtimes(unknown, known, seed_known))),
        "unknowns_adjoint": (seed_unknown, ca.cse(ca.jtimes(unknown, known, seed_unknown, True))),
        "initial_forward": (seed_known, ca.jtimes(initial_states, known, seed_known)),
        "initial_adjoint": (seed_state, ca.jtimes(initial_states, known, seed_state, True)),
    }
    return {key: ca.Function(f"{model}_{key}", [*args, seed], [sensitivity], [*names, "seed"], ["sensitivity"])
            for key, (seed, sensitivity) in sweeps.items()}


# ---- dependencies --------------------------------------------------------------------------------------

# How the known enters (FMI 2.0 and 3.0 dependenciesKind), from the most special to the most general.
KIND_ORDER = ("constant", "fixed", "tunable", "discrete", "dependent")


@dataclass(frozen=True)
class Dependency:
    known: int  # position in K
    kind: str


def _rows_depending_on(entries: ca.SX, symbols: ca.SX) -> set[int]:
    """Indices of the entries whose expression depends structurally on any of the symbols."""
    if entries.numel() == 0 or symbols.numel() == 0:
        return set()
    sparsity = ca.jacobian_sparsity(entries, symbols)
    return set(sparsity.get_triplet()[0])


def dependencies(equations: Equations, initial: bool) -> list[list[Dependency]]:
    """Per unknown (position in U), the knowns it depends on structurally and how (dependenciesKind).

    The kind of a Real dependency follows from what the partial derivative itself depends on: nothing
    (constant), fixed or tunable parameters only, also discrete states or Integer inputs (discrete), or
    states and Real inputs (dependent). Initial unknowns only use constant/dependent (FMI 2.0 schema)."""
    s = equations.symbols
    interface = equations.interface
    system = unknowns(equations)
    expression = system.initial if initial else system.continuous
    jacobian = ca.jacobian(expression, system.known)
    rows, columns = jacobian.sparsity().get_triplet()
    if not rows:
        return [[] for _ in range(expression.numel())]
    entries = ca.vertcat(*[jacobian[r, c] for r, c in zip(rows, columns)])

    real_unknown = _real_unknowns(interface, system.sizes)
    real_known = ([True] * s.x.numel() + [v.type == "Real" for v in interface.of_role(INPUT)]
                  + [v.type == "Real" for v in interface.of_role(PARAMETER)])
    declared = len(real_known)  # the runtime's own parameters (equations.MODEL_EXCHANGE) come after: no variable
    inputs = interface.of_role(INPUT)
    parameters = interface.of_role(PARAMETER)

    def pick(vector, variables, keep):
        return ca.vertcat(*[vector[v.index] for v in variables if keep(v)])

    continuous_symbols = ca.vertcat(s.x, pick(s.u, inputs, lambda v: v.type == "Real"))
    discrete_symbols = ca.vertcat(s.d, pick(s.u, inputs, lambda v: v.type != "Real"))
    tunable_symbols = pick(s.p, parameters, lambda v: v.variability == "tunable")
    fixed_symbols = pick(s.p, parameters, lambda v: v.variability != "tunable")
    levels = [(_rows_depending_on(entries, continuous_symbols), "dependent"),
              (_rows_depending_on(entries, discrete_symbols), "discrete"),
              (_rows_depending_on(entries, tunable_symbols), "tunable"),
              (_rows_depending_on(entries, fixed_symbols), "fixed")]

    result: list[list[Dependency]] = [[] for _ in range(expression.numel())]
    for entry, (row, column) in enumerate(zip(rows, columns)):
        if column >= declared:
            continue
        if not (real_unknown[row] and real_known[column]):
            kind = "dependent"  # the other kinds are only defined for Real variables
        else:
            kind = next((name for found, name in levels if entry in found), "constant")
            if initial and kind != "constant":
                kind = "dependent"
        result[row].append(Dependency(column, kind))
    for row in result:
        row.sort(key=lambda dependency: dependency.known)
    return result


def _real_unknowns(interface, sizes: dict) -> list[bool]:
    discrete = [v.type == "Real" for v in interface.of_role(DISCRETE)]
    outputs = [v.type == "Real" for v in interface.of_role(OUTPUT)]
    return [True] * sizes["nx"] + discrete + [True] * sizes["nx"] + outputs + [True] * sizes["nz"]


def known_roles(sizes: dict) -> list[tuple[str, int]]:
    """(role, index) of every position in K."""
    return ([(STATE, i) for i in range(sizes["nx"])] + [(INPUT, i) for i in range(sizes["nu"])]
            + [(PARAMETER, i) for i in range(sizes["np"])])


def unknown_position(role: str, index: int, sizes: dict) -> int:
    """Position in U of a state, discrete state, derivative ('derivative'), output or event indicator."""
    offsets = {STATE: 0, DISCRETE: sizes["nx"], "derivative": sizes["nx"] + sizes["nd"],
               OUTPUT: 2 * sizes["nx"] + sizes["nd"], "event_indicator": 2 * sizes["nx"] + sizes["nd"] + sizes["ny"]}
    return offsets[role] + index


@dataclass
class DeclaredDependencies:
    """What the ModelStructure declares, by value reference: unknown -> [(known, dependenciesKind)].

    `continuous`: outputs, derivatives and event indicators on states and inputs (modes after initialization,
    communication points); `initial`: initial unknowns on inputs and parameters (initial="exact")."""

    continuous: dict[int, list[tuple[int, str]]]
    initial: dict[int, list[tuple[int, str]]]


def declared_dependencies(equations: Equations, table) -> DeclaredDependencies:
    """The dependencies of every unknown in the variable table (codegen.TableEntry list, vr = position + 1)."""
    system = unknowns(equations)
    sizes = system.sizes
    reference = {}
    for vr, entry in enumerate(table, start=1):
        if entry.variable is not None:
            reference[(entry.variable.role, entry.variable.index)] = vr
    known_references = [reference.get(role_index) for role_index in known_roles(sizes)]  # None: the runtime's own
    known_role = [role for role, _ in known_roles(sizes)]

    def position(entry) -> int | None:
        if entry.derivative_of is not None:
            return unknown_position("derivative", entry.index, sizes)
        if entry.event_indicator is not None:
            return unknown_position("event_indicator", entry.event_indicator, sizes)
        if entry.variable.role in (STATE, DISCRETE, OUTPUT):
            return unknown_position(entry.variable.role, entry.variable.index, sizes)
        return None

    declared = DeclaredDependencies({}, {})
    for initial, target, roles in ((False, declared.continuous, (STATE, INPUT)),
                                   (True, declared.initial, (INPUT, PARAMETER))):
        per_unknown = dependencies(equations, initial)
        for vr, entry in enumerate(table, start=1):
            row = position(entry)
            if row is None:
                continue
            # FMI 2.0: "ordered according to size, starting with the smallest index"
            target[vr] = sorted((known_references[d.known], d.kind) for d in per_unknown[row]
                                if known_role[d.known] in roles)
    return declared


def reinitialized_states(equations: Equations) -> set[int]:
    """Indices of the states that the discrete update may change at an event (FMI 3.0 reinit)."""
    x = equations.symbols.x
    return {i for i in range(x.numel()) if not ca.is_equal(equations.state_update[i], x[i], 2)}
