"""Exact partial derivatives of both FMUs, FMI 2.0 and 3.0, through the real binaries (fmpy's low-level API):
fmi2GetDirectionalDerivative, fmi3GetDirectionalDerivative and fmi3GetAdjointDerivative against central finite
differences of the same binary at random states and inputs, forward against adjoint products, zero entries
against the declared dependencies, co-simulation against model exchange, and initialization (initial unknowns
with respect to parameters and inputs)."""

import ctypes

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Model, FMU2Slave
from fmpy.fmi3 import FMU3Model

from sdl_fmu.dynamics.advanced import SPIN_HYSTERESIS, WHEEL_SPIN

EPS = np.finfo(float).eps
RELATIVE_STEP = 1e-5  # ~ cube root of eps: balances O(h^2) truncation against O(eps/h) round-off
# A model evaluation is a chain of a few hundred floating-point operations: its values carry a relative
# rounding error of at most ~100 eps of the magnitudes involved.
EVALUATION_ROUNDING = 100 * EPS
# A test whose tolerances are loose could not fail: 99 % of the nonzero entries must have a derived tolerance
# within 1e-3 of the derivative (+1e-6), i.e. the finite differences confirm at least three digits.
SHARP = 1e-3


class Probe:
    """One FMU instance whose states (model exchange) and Real inputs are set at will, reading every Real
    unknown the ModelStructure names (derivatives, outputs, event indicators) and its exact partial derivatives."""

    def __init__(self, path, version, directory, start=None, cosimulation=False):
        self.md = read_model_description(str(path))
        self.version = version
        unzip = extract(str(path), unzipdir=str(directory))
        interface = self.md.coSimulation if cosimulation else self.md.modelExchange
        kwargs = dict(guid=self.md.guid, unzipDirectory=unzip, modelIdentifier=interface.modelIdentifier,
                      instanceName="probe")
        if version == 2:
            self.fmu = (FMU2Slave if cosimulation else FMU2Model)(**kwargs)
        else:
            from fmpy.fmi3 import FMU3Slave
            self.fmu = (FMU3Slave if cosimulation else FMU3Model)(**kwargs)
        self.fmu.instantiate()
        if version == 2:
            self.fmu.setupExperiment(startTime=0.0)
        self.variables = {v.name: v for v in self.md.modelVariables}
        self.set_start(start or {})
        self.states = [d.variable.derivative for d in self.md.derivatives]
        self.unknowns = self._real_unknowns()
        self.real_inputs = [v for v in self.md.modelVariables if v.causality == "input" and v.type in ("Real", "Float64")]
        self.cosimulation = cosimulation

    def _real_unknowns(self):
        names = [d.variable for d in self.md.derivatives]
        names += [o.variable for o in self.md.outputs if o.variable.type in ("Real", "Float64")]
        names += [v for v in self.md.modelVariables if v.name.startswith("event_indicator_")]
        return names

    def set_start(self, values):
        for name, value in values.items():
            variable = self.variables[name]
            if variable.type in ("Real", "Float64"):
                self.set_real([variable.valueReference], [value])
            elif self.version == 2:
                self.fmu.setInteger([variable.valueReference], [int(value)])
            else:
                self.fmu.setInt32([variable.valueReference], [int(value)])

    def set_real(self, references, values):
        (self.fmu.setReal if self.version == 2 else self.fmu.setFloat64)(list(references), list(map(float, values)))

    def get_real(self, references):
        return np.array((self.fmu.getReal if self.version == 2 else self.fmu.getFloat64)(list(references)))

    def enter_initialization(self):
        if self.version == 2:
            self.fmu.enterInitializationMode()
        else:
            self.fmu.enterInitializationMode(startTime=0.0)

    def start_continuous_time(self):
        """Initialization done, discrete states settled, model exchange in continuous-time mode."""
        self.enter_initialization()
        self.fmu.exitInitializationMode()
        if not self.cosimulation:
            self.update_discrete_states()
            self.fmu.enterContinuousTimeMode()

    def update_discrete_states(self):
        if self.version == 2:
            while self.fmu.newDiscreteStates()[0]:
                pass
        else:
            while self.fmu.updateDiscreteStates()[0]:
                pass

    def event(self):
        """Event mode, discrete update, back to continuous time (model exchange)."""
        self.fmu.enterEventMode()
        self.update_discrete_states()
        self.fmu.enterContinuousTimeMode()

    def set_states(self, x):
        x = np.ascontiguousarray(x, dtype=float)
        self.fmu.setContinuousStates(x.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), len(x))

    def knowns(self):
        return [*self.states, *self.real_inputs]

    def known_values(self):
        return self.get_real([v.valueReference for v in self.knowns()])

    def set_known(self, values):
        nx = len(self.states)
        self.set_states(values[:nx])
        self.set_real([v.valueReference for v in self.real_inputs], values[nx:])

    def values(self, unknowns=None):
        return self.get_real([v.valueReference for v in (unknowns or self.unknowns)])

    def directional(self, unknowns, knowns, seed):
        return np.array(self.fmu.getDirectionalDerivative([u.valueReference for u in unknowns],
                                                          [k.valueReference for k in knowns], list(seed)))

    def adjoint(self, unknowns, knowns, seed):
        # fmpy's default sensitivity length is the number of unknowns; the adjoint has one per known
        return np.array(self.fmu.getAdjointDerivative([u.valueReference for u in unknowns],
                                                      [k.valueReference for k in knowns], list(seed),
                                                      nSensitivity=len(knowns)))

    def jacobian_forward(self, unknowns, knowns):
        """Column by column: J e_j."""
        return np.column_stack([self.directional(unknowns, [k], [1.0]) for k in knowns])

    def jacobian_adjoint(self, unknowns, knowns):
        """Row by row: J^T e_i."""
        return np.vstack([self.adjoint([u], knowns, [1.0]) for u in unknowns])

    def free(self):
        self.fmu.terminate()
        self.fmu.freeInstance()


def finite_differences(evaluate, set_known, point, steps, exact, columns=None):
    """Central differences with steps h and 2h per known (of `columns`, default all), and the tolerance they
    justify themselves.

    D(h) = J + c h^2 + O(h^4) + noise/h, so D(2h) - D(h) = 3 c h^2 (+ noise): 4 |D(2h) - D(h)| bounds the
    truncation error of D(h) with room to spare. Round-off: an unknown f_i is computed from terms whose size
    is about S_i = max(|f_i|, max_j |J_ij| max(|k_j|, 1)) (a term T in f_i shows as T / k_j in the Jacobian),
    so each evaluation is off by at most EVALUATION_ROUNDING S_i and D(h) by EVALUATION_ROUNDING S_i / h.
    The tolerance is the sum of both, entry by entry."""
    columns = range(len(steps)) if columns is None else columns
    estimates, spreads = [], []
    center = evaluate()
    for j in columns:
        h = steps[j]
        samples = {}
        for k in (-2, -1, 1, 2):
            shifted = point.copy()
            shifted[j] += k * h
            set_known(shifted)
            samples[k] = evaluate()
        d1 = (samples[1] - samples[-1]) / (2 * h)
        d2 = (samples[2] - samples[-2]) / (4 * h)
        estimates.append(d1)
        spreads.append(np.abs(d2 - d1))
    set_known(point)
    term_scale = np.maximum(np.abs(center), (np.abs(exact) * np.maximum(np.abs(point), 1.0)).max(axis=1))
    roundoff = EVALUATION_ROUNDING * term_scale[:, None] / np.asarray(steps)[None, list(columns)]
    return np.column_stack(estimates), 4 * np.column_stack(spreads) + roundoff


# Larger steps for the knowns whose entries the first step cannot confirm sharply (see confirm_jacobian).
STEP_LADDER = (10, 100)


def confirm_jacobian(evaluate, set_known, point, steps, exact, fits, failures, label):
    """Finite differences at `steps` and, for the knowns with an entry that is not confirmed sharply there,
    again at 10 and 100 times the step: every step must agree within its own derived tolerance (each is a
    bound on its own, so a wrong derivative has to hide from all of them), and an entry counts as sharp if any
    step confirms it. Returns the tightest tolerance per entry.

    Why larger steps: the round-off bound EVALUATION_ROUNDING S_i / h of a row is set by that unknown's largest
    term S_i, whatever the known. In initialization the wheels spin at v0 / R, so a steered front tire has a
    small slip (kappa ~ steer^2 / 2, sliding share ~ steer^4): its Fx, and so der(wheel_speed_f*), depends on
    the tire parameters (PCY1, PEY1, PDY1, PEX3, ...) by only 1e-6 .. 4e-3 rad/s2, beside brake and drive
    torques over I_w of S_i ~ 1e3 rad/s2 (round-off bound 2.2e-14 * 3e3 / 1e-5 = 7e-6 at the first step,
    above 1e-3 |J| + 1e-6). Truncation there is tiny (the spreads 4 |D(2h) - D(h)| are <= 1e-8, mostly
    noise), so the balance of truncation c h^2 and round-off rounding / h, h ~ (rounding / |c|)^(1/3), lies
    at a larger step, which the ladder brackets; at 10 h the bound is 7e-7. The actual round-off is far below
    the bound (the perturbed term is small), but the bound is what the test may rely on.
    fits(j, h): True if the known j may move by +-2h (inside its declared range)."""
    approximate, tolerance = finite_differences(evaluate, set_known, point, steps, exact["directional"])
    best = tolerance.copy()
    for factor in (1, *STEP_LADDER):
        if factor > 1:
            loose = (exact["directional"] != 0) & (best > SHARP * np.abs(exact["directional"]) + 1e-6)
            columns = [j for j in np.flatnonzero(loose.any(axis=0)) if fits(j, factor * steps[j])]
            if not columns:
                break
            approximate, tolerance = finite_differences(evaluate, set_known, point, factor * steps,
                                                        exact["directional"], columns)
            best[:, columns] = np.minimum(best[:, columns], tolerance)
        else:
            columns = list(range(len(steps)))
        for name, jacobian in exact.items():
            bad = ~(np.abs(jacobian[:, columns] - approximate) <= tolerance)  # NaN fails too
            for i, c in np.argwhere(bad)[:3]:
                failures.append(f"{label(i, columns[c])} ({name}, step x{factor}): {jacobian[i, columns[c]]!r} vs "
                                f"{approximate[i, c]!r} +- {tolerance[i, c]:.3g}")
    return best


def declared_mask(probe, unknowns, knowns):
    """True where the modelDescription declares unknown i to depend on known j."""
    lists = list(probe.md.outputs) + list(probe.md.derivatives) + list(getattr(probe.md, "eventIndicators", []))
    dependencies = {u.variable.name: u.dependencies for u in lists}
    mask = np.zeros((len(unknowns), len(knowns)), dtype=bool)
    for i, unknown in enumerate(unknowns):
        if unknown.name not in dependencies:
            assert probe.version == 2 and unknown.name.startswith("event_indicator_")
            mask[i, :] = True  # FMI 2.0 has no event indicators in its ModelStructure
            continue
        names = {v.name for v in dependencies[unknown.name]}
        mask[i] = [k.name in names for k in knowns]
    return mask


# ---- random states and inputs ----------------------------------------------------------------------------

def random_point(probe, rng, regime, radius=None, **fixed_inputs):
    """Random states and Real inputs by variable name (so the test follows the models' interfaces).

    driving: speeds 1..40 m/s, wheels rolling within 10 % of the ground speed; standstill: speeds and yaw rate
    within the slip floor (0.1 m/s) and spin smoothing (0.1 rad/s) of the models; lock: 5..30 m/s with wheel
    spins at 0..3 % of rolling speed (slip ratio near -1). Inputs stay inside their declared ranges."""
    speed = {"driving": rng.uniform(1, 40), "standstill": rng.uniform(-0.2, 0.2), "lock": rng.uniform(5, 30)}[regime]
    states = {"x": rng.uniform(-100, 100), "y": rng.uniform(-100, 100), "psi": rng.uniform(-3, 3),
              "s": rng.uniform(0, 1000), "v": abs(speed), "vx": speed,
              "vy": rng.uniform(-0.2, 0.2) if regime == "standstill" else rng.uniform(-2, 2),
              "yaw_rate": rng.uniform(-0.05, 0.05) if regime == "standstill" else rng.uniform(-0.5, 0.5)}
    values = []
    for state in probe.states:
        if state.name.startswith("wheel_speed_"):
            rolling = speed / radius
            values.append({"driving": rolling * rng.uniform(0.9, 1.1), "standstill": rng.uniform(-0.5, 0.5),
                           "lock": rolling * rng.uniform(0.0, 0.03)}[regime])
        elif state.name.startswith("load_"):
            values.append(rng.uniform(-8, 8))
        else:
            values.append(states.get(state.name, rng.uniform(-1, 1)))
    for variable in probe.real_inputs:
        if variable.name in fixed_inputs:
            values.append(fixed_inputs[variable.name])
        elif variable.name == "steer":
            values.append(rng.uniform(-0.5, 0.5))
        elif variable.name.startswith("mu_"):
            values.append(rng.uniform(0.1, 1.2))
        else:  # pedals and anything else within its range
            low = float(variable.min) if variable.min is not None else 0.0
            high = float(variable.max) if variable.max is not None else low + 1.0
            values.append(rng.uniform(low + 0.01 * (high - low), high - 0.01 * (high - low)))
    return np.array(values)


def check_point(probe, point, failures, stats):
    """Compares the exact Jacobian at one point with finite differences (and, in FMI 3.0, the adjoint
    one); collects what disagrees and counts the point."""
    adjoint = probe.version == 3
    stats["points"] += 1
    knowns, unknowns = probe.knowns(), probe.unknowns
    probe.set_known(point)
    exact = probe.jacobian_forward(unknowns, knowns)
    steps = RELATIVE_STEP * np.maximum(np.abs(point), 1.0)
    approximate, tolerance = finite_differences(probe.values, probe.set_known, point, steps, exact)
    jacobians = {"directional": exact}
    if adjoint:
        jacobians["adjoint"] = probe.jacobian_adjoint(unknowns, knowns)
    for name, jacobian in jacobians.items():
        bad = ~(np.abs(jacobian - approximate) <= tolerance)  # NaN fails too
        if bad.any():
            i, j = np.argwhere(bad)[0]
            failures.append(f"{name}: d {unknowns[i].name} / d {knowns[j].name} at {point.tolist()}: "
                            f"exact {jacobian[i, j]!r}, finite differences {approximate[i, j]!r} +- {tolerance[i, j]:.3g}")
    nonzero = exact != 0
    stats["entries"] += int(nonzero.sum())
    stats["tight"] += int((tolerance[nonzero] <= SHARP * np.abs(exact[nonzero]) + 1e-6).sum())
    undeclared = nonzero & ~declared_mask(probe, unknowns, knowns)
    if undeclared.any():
        i, j = np.argwhere(undeclared)[0]
        failures.append(f"d {unknowns[i].name} / d {knowns[j].name} = {exact[i, j]!r} but not declared")
    if adjoint:
        # v^T (J w) = (J^T v)^T w for random directions. Both sides sum the same n_U n_K products in different
        # orders; each carries a relative rounding error below (n + few) eps of sum |v_i J_ij w_j|, so 1e-12
        # of that sum bounds the difference for n << 1e3.
        rng = np.random.default_rng(len(failures) + stats["entries"])
        v, w = rng.standard_normal(len(unknowns)), rng.standard_normal(len(knowns))
        forward = v @ probe.directional(unknowns, knowns, w)
        reverse = probe.adjoint(unknowns, knowns, v) @ w
        condition = np.abs(v) @ np.abs(exact) @ np.abs(w)
        stats["product_error"] = max(stats["product_error"], abs(forward - reverse) / condition)
        if abs(forward - reverse) > 1e-12 * condition:
            failures.append(f"v^T(J w) = {forward!r} but (J^T v)^T w = {reverse!r} at {point.tolist()}")


def assert_checked(failures, stats, minimum_points):
    assert stats["points"] >= minimum_points
    assert not failures, f"{len(failures)} disagreements, first: " + "\n".join(failures[:5])
    assert stats["tight"] >= 0.99 * stats["entries"], stats  # see SHARP


@pytest.mark.parametrize("version", [2, 3])
def test_simple_derivatives_against_finite_differences(simple_fmus, tmp_path, version):
    probe = Probe(simple_fmus[version], version, tmp_path, start={"v0": 20.0})
    probe.start_continuous_time()
    rng = np.random.default_rng(8)
    failures, stats = [], {"entries": 0, "tight": 0, "points": 0, "product_error": 0.0}
    for n in range(100):  # 70 % driving, 30 % near standstill
        point = random_point(probe, rng, "standstill" if n % 10 < 3 else "driving")
        check_point(probe, point, failures, stats)
    probe.free()
    print(f"Simple FMI {version}: {stats}")
    assert_checked(failures, stats, 100)


@pytest.mark.parametrize("version", [2, 3])
def test_advanced_derivatives_against_finite_differences(advanced_fmus, tmp_path, version):
    """Driving, near standstill and near wheel lock (rolling), and with locked wheels (wheel mode 0)."""
    rng = np.random.default_rng(9)
    failures, stats = [], {"entries": 0, "tight": 0, "points": 0, "product_error": 0.0}
    surfaces = {"surface_fl": 0, "surface_fr": 1, "surface_rl": 2, "surface_rr": 4}
    # model exchange: the quasi-static wheels (automatic) and the dynamic ones (selected)
    for wheel_spin in (WHEEL_SPIN["automatic"], WHEEL_SPIN["dynamic"]):
        probe = Probe(advanced_fmus[version], version, tmp_path / f"rolling{wheel_spin}",
                      start={"v0": 20.0, "wheel_spin": wheel_spin, **surfaces})
        probe.start_continuous_time()
        radius = probe.get_real([probe.variables["wheel_radius"].valueReference])[0]
        for regime, count in (("driving", 40), ("standstill", 30), ("lock", 30)):
            for _ in range(count):
                point = random_point(probe, rng, regime, radius)
                check_point(probe, point, failures, stats)
        probe.free()

    # locked wheels: on ice under full brake, spins that cross zero lock every wheel at the next event
    ice = {f"surface_{w}": 3 for w in ("fl", "fr", "rl", "rr")}
    locked = Probe(advanced_fmus[version], version, tmp_path / "locked",
                   start={"v0": 20.0, "brake": 1.0, "wheel_spin": WHEEL_SPIN["dynamic"], **ice})
    locked.start_continuous_time()
    x = locked.known_values()[:len(locked.states)]
    spin_names = [f"wheel_speed_{w}" for w in ("fl", "fr", "rl", "rr")]
    for name in spin_names:  # past zero by more than the rolling mode's hysteresis, so the event locks the wheel
        x[[s.name for s in locked.states].index(name)] = -10 * SPIN_HYSTERESIS
    locked.set_states(x)
    locked.event()
    modes = [locked.variables[f"wheel_mode_{w}"].valueReference for w in ("fl", "fr", "rl", "rr")]
    assert list(locked.fmu.getInteger(modes) if version == 2 else locked.fmu.getInt32(modes)) == [0, 0, 0, 0]
    for _ in range(20):
        point = random_point(locked, rng, "lock", radius, throttle=0.02, brake=rng.uniform(0.9, 0.99))
        check_point(locked, point, failures, stats)
    locked.free()
    print(f"Advanced FMI {version}: {stats}")
    assert_checked(failures, stats, 100)


@pytest.mark.parametrize("version", [2, 3])
def test_cosimulation_derivatives_equal_model_exchange(simple_fmus, advanced_fmus, tmp_path, version):
    """fmi2/fmi3GetDirectionalDerivative of a co-simulation instance between steps: the same exact numbers as
    model exchange at the same states and inputs (both evaluate the same generated function)."""
    for name, fmus, start in (("simple", simple_fmus, {"v0": 25.0, "steer": 0.05, "brake": 0.3}),
                              ("advanced", advanced_fmus,
                               {"v0": 25.0, "steer": 0.05, "brake": 0.3, "wheel_spin": WHEEL_SPIN["dynamic"]})):
        slave = Probe(fmus[version], version, tmp_path / f"{name}-cs", start=start, cosimulation=True)
        slave.start_continuous_time()
        for step in range(50):
            slave.fmu.doStep(currentCommunicationPoint=step * 0.01, communicationStepSize=0.01)
        point = slave.known_values()
        knowns, unknowns = slave.knowns(), slave.unknowns
        cosimulation = slave.jacobian_forward(unknowns, knowns)
        model = Probe(fmus[version], version, tmp_path / f"{name}-me", start=start)
        model.start_continuous_time()
        model.set_known(point)
        assert np.array_equal(model.jacobian_forward(unknowns, knowns), cosimulation)
        if version == 3:
            assert np.array_equal(model.jacobian_adjoint(unknowns, knowns), slave.jacobian_adjoint(unknowns, knowns))
        slave.free()
        model.free()


def initial_problem(probe):
    """Initial unknowns (Real) and the knowns of initialization (Real inputs and parameters)."""
    unknowns = [u.variable for u in probe.md.initialUnknowns if u.variable.type in ("Real", "Float64")]
    knowns = [v for v in probe.md.modelVariables
              if v.causality in ("input", "parameter") and v.type in ("Real", "Float64")]
    return unknowns, knowns


def within_range(variable, value, step):
    """True if value +- 2 step stays inside the variable's declared range (the FMU may refuse values outside)."""
    return ((variable.min is None or value - 2 * step >= float(variable.min))
            and (variable.max is None or value + 2 * step <= float(variable.max)))


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("model", ["simple", "advanced"])
def test_initial_unknowns_against_finite_differences(simple_fmus, advanced_fmus, tmp_path, model, version):
    """In initialization mode the states are x0(u, p): derivatives of every Real initial unknown with respect
    to every Real input and parameter, at random starts, against central differences (as above)."""
    fmus = simple_fmus if model == "simple" else advanced_fmus
    rng = np.random.default_rng(10)
    failures, stats = [], {"entries": 0, "tight": 0, "points": 0}
    for sample in range(3):
        start = {"v0": rng.uniform(5, 30), "psi0": rng.uniform(-3, 3), "x0": rng.uniform(-50, 50),
                 "throttle": rng.uniform(0.01, 0.99), "brake": rng.uniform(0.01, 0.99), "steer": rng.uniform(-0.3, 0.3)}
        probe = Probe(fmus[version], version, tmp_path / str(sample), start=start)
        probe.enter_initialization()
        unknowns, knowns = initial_problem(probe)
        point = probe.get_real([k.valueReference for k in knowns])
        steps = RELATIVE_STEP * np.maximum(np.abs(point), 1.0)
        # keep every perturbation inside the variable's declared range (the FMU may refuse values outside)
        inside = [within_range(k, p, h) for k, p, h in zip(knowns, point, steps)]
        knowns = [k for k, keep in zip(knowns, inside) if keep]
        point, steps = point[inside], steps[inside]
        references = [k.valueReference for k in knowns]

        exact = {"directional": probe.jacobian_forward(unknowns, knowns)}
        if version == 3:
            exact["adjoint"] = probe.jacobian_adjoint(unknowns, knowns)
        tolerance = confirm_jacobian(lambda: probe.values(unknowns), lambda values: probe.set_real(references, values),
                                     point, steps, exact, lambda j, h: within_range(knowns[j], point[j], h), failures,
                                     lambda i, j: f"d {unknowns[i].name} / d {knowns[j].name}")
        nonzero = exact["directional"] != 0
        tight = tolerance <= SHARP * np.abs(exact["directional"]) + 1e-6
        stats["entries"] += int(nonzero.sum())
        stats["tight"] += int((tight & nonzero).sum())
        stats["points"] += 1
        stats.setdefault("loose", []).extend(
            (unknowns[i].name, knowns[j].name, exact["directional"][i, j], tolerance[i, j])
            for i, j in np.argwhere(nonzero & ~tight)[:5])
        probe.fmu.exitInitializationMode()
        probe.free()
    print(f"{model} FMI {version} initialization: {stats}")
    assert not failures, "\n".join(failures[:5])
    # sharp for 99 %, as the running derivatives (see SHARP): the step ladder of confirm_jacobian brings the
    # round-off of the smallest sensitivities (to tire parameters, 1e-6 .. 1e-3 beside terms of ~1e3) below 1e-6
    assert stats["entries"] > 0 and stats["tight"] >= 0.99 * stats["entries"], stats


@pytest.mark.parametrize("version", [2, 3])
def test_derivatives_are_finite_at_rest(simple_fmus, advanced_fmus, tmp_path, version):
    """A car held at rest without pedals: speeds and tire forces are exactly 0, where the norms in the
    equations (sqrt(a^2 + b^2)) have no derivative; the FMU gives their subgradient 0, not 0/0."""
    for name, fmus in (("simple", simple_fmus), ("advanced", advanced_fmus)):
        probe = Probe(fmus[version], version, tmp_path / name, start={"v0": 0.0})
        probe.start_continuous_time()
        stopped = probe.variables["stopped"].valueReference
        assert probe.fmu.getBoolean([stopped]) == [True]
        knowns, unknowns = probe.knowns(), probe.unknowns
        assert np.isfinite(probe.jacobian_forward(unknowns, knowns)).all(), name
        if version == 3:
            assert np.isfinite(probe.jacobian_adjoint(unknowns, knowns)).all(), name
        probe.free()


def test_misuse_of_partial_derivatives_is_an_error_not_a_crash(simple_fmus, advanced_fmus, tmp_path):
    from fmpy.fmi1 import FMICallException

    probe = Probe(advanced_fmus[3], 3, tmp_path / "a", start={"v0": 10.0})
    probe.start_continuous_time()
    v = probe.variables
    der = probe.unknowns[0]
    for unknowns, knowns in (([der], [v["surface_fl"]]),   # an Integer input is not a known
                             ([v["stopped"]], [v["vx"]]),  # a Boolean is not an unknown
                             ([der], [v["ax"]]),           # an output is not a known
                             ([v["throttle"]], [v["vx"]])):  # an input is not an unknown
        with pytest.raises(FMICallException):
            probe.directional(unknowns, knowns, [1.0])
    with pytest.raises(FMICallException):  # one sensitivity per known in the adjoint
        probe.fmu.getAdjointDerivative([der.valueReference], [v["vx"].valueReference, v["vy"].valueReference], [1.0])
    with pytest.raises(FMICallException):  # unknown value reference
        probe.fmu.getDirectionalDerivative([10**6], [v["vx"].valueReference], [1.0])
    # the instance is still usable after argument errors
    assert np.isfinite(probe.directional([der], [v["vx"]], [1.0])).all()
    probe.free()

    initializing = Probe(simple_fmus[2], 2, tmp_path / "s", start={"v0": 10.0})
    initializing.enter_initialization()
    with pytest.raises(FMICallException):  # states are calculated in initialization, not knowns
        initializing.directional([initializing.variables["der(x)"]], [initializing.states[0]], [1.0])
    assert initializing.directional([initializing.variables["der(x)"]], [initializing.variables["v0"]], [1.0])[0] == 1.0
    initializing.fmu.exitInitializationMode()
    initializing.free()
