"""Model exchange in fixed-step importers: fmpy's forward Euler drives the FMUs as fmusim and the FMI Compliance
Checker do (start values only, inputs from a table, fixed steps of 1 to 50 ms), and the event indicators are
what such an integrator needs (docs/fmu-runtime.md, "Event indicators a fixed-step integrator can see").

Closed form of every stop here (straight line, no drag, no rolling resistance, mu = 0.6 on every wheel): the
locked or braked wheels decelerate the car by a = min(brake brake_decel_max, mu g) = mu g (brake_decel_max =
9.81 > 0.6 g), so from v the car stops after v^2 / (2 a). Forward Euler with step h sums the speeds at the
start of each step, v_k = v - a k h, over the steps until the speed is no longer positive: a left Riemann sum of
the decreasing speed, which lies between the exact integral and the integral plus h (v(0) - v(end)) = h v.
The stop is therefore in [v^2 / (2 a), v^2 / (2 a) + v h]."""

import ctypes

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Model
from fmpy.fmi3 import FMU3Model

from sdl_fmu.units import STANDARD_GRAVITY as G

WHEELS = ("fl", "fr", "rl", "rr")
MU, V0 = 0.6, 30.0
DECELERATION = MU * G
STRAIGHT = {"drag_area": 0.0, "rolling_resistance": 0.0, **{f"mu_{w}": MU for w in WHEELS}}
VERSIONS = pytest.mark.parametrize("version", [2, 3], ids=["fmi2", "fmi3"])
STEPS = pytest.mark.parametrize("step", [0.001, 0.01, 0.02, 0.05], ids=["1ms", "10ms", "20ms", "50ms"])
# rounding of the Euler sums (at most 10^4 additions of ~30 m/s x h): far below a millimetre
ROUNDING = 1e-9


def euler(fmu, step, stop_time, start, inputs=None):
    return simulate_fmu(str(fmu), fmi_type="ModelExchange", solver="Euler", step_size=step, output_interval=step,
                        stop_time=stop_time, start_values=start, input=inputs,
                        output=["x", "s", "vx", "stopped"])


def event_times(result):
    """fmpy records a second sample at the time of every event it handles."""
    times = result["time"]
    return times[1:][np.diff(times) == 0]


def assert_stops_like_the_closed_form(result, step, brake_onset, speed_at_onset):
    """Stopped for good, never backwards, at most 2 events at the stop, distance within [closed form,
    closed form + v h] (module docstring)."""
    times = result["time"]
    assert result["stopped"][-1], "the car did not stop"
    first_stop = int(np.argmax(result["stopped"]))
    assert np.all(result["stopped"][first_stop:]), "the car started again"
    assert np.all(result["vx"][first_stop:] == 0.0), "a stopped car moves"
    assert np.all(np.diff(result["x"]) >= 0.0), "the car moved backwards"
    braking_events = event_times(result)[event_times(result) > brake_onset + step / 2]
    assert len(braking_events) <= 2, braking_events
    onset = int(np.searchsorted(times, brake_onset + step / 2)) - 1  # the last sample at the onset
    travelled = result["s"][-1] - result["s"][onset]
    exact = speed_at_onset**2 / (2 * DECELERATION)
    assert exact - ROUNDING <= travelled <= exact + speed_at_onset * step + ROUNDING, (travelled, exact)


@VERSIONS
@STEPS
def test_full_brake_stops_in_forward_euler(simple_fmus, version, step):
    result = euler(simple_fmus[version], step, 10.0, {**STRAIGHT, "v0": V0, "brake": 1.0})
    assert_stops_like_the_closed_form(result, step, 0.0, V0)


@VERSIONS
@pytest.mark.parametrize("step", [0.01, 0.02], ids=["10ms", "20ms"])
def test_throttle_then_brake_from_an_input_table(simple_fmus, version, step):
    """As fmusim and the Compliance Checker drive an FMU: start values only, the pedals from a table (6 s of full
    throttle from rest, then full brake)."""
    table = np.array([(0.0, 1.0, 0.0), (6.0, 1.0, 0.0), (6.0, 0.0, 1.0), (14.0, 0.0, 1.0)],
                     dtype=[("time", float), ("throttle", float), ("brake", float)])
    result = euler(simple_fmus[version], step, 14.0, {**STRAIGHT, "v0": 0.0}, table)
    at_onset = int(np.searchsorted(result["time"], 6.0 + step / 2)) - 1
    speed = result["vx"][at_onset]
    assert speed > 20.0  # it drove off
    assert not result["stopped"][at_onset]
    assert_stops_like_the_closed_form(result, step, 6.0, speed)


# ---- the event indicators themselves ---------------------------------------------------------------------------


def model_instance(fmu, version, tmp_path):
    description = read_model_description(str(fmu))
    unzipdir = extract(str(fmu), str(tmp_path / "fmu"))
    model_type = FMU2Model if version == 2 else FMU3Model
    model = model_type(guid=description.guid, unzipDirectory=unzipdir,
                       modelIdentifier=description.modelExchange.modelIdentifier, instanceName="me")
    references = {v.name: v.valueReference for v in description.modelVariables}
    return model, references, description.numberOfEventIndicators, description.numberOfContinuousStates


def initialized(model, references, version, values):
    model.instantiate()
    if version == 2:
        model.setupExperiment(startTime=0.0)
    model.enterInitializationMode()
    if version == 2:
        model.setReal([references[name] for name in values], list(values.values()))
    else:
        model.setFloat64([references[name] for name in values], list(values.values()))
    model.exitInitializationMode()
    if version == 2:
        while model.newDiscreteStates()[0]:
            pass
    else:
        while model.updateDiscreteStates()[0]:
            pass
    model.enterContinuousTimeMode()


@VERSIONS
@pytest.mark.parametrize("model_name", ["simple", "advanced"])
@pytest.mark.parametrize("case", ["held", "held_braking", "moving", "starting"])
def test_no_event_indicator_is_zero(simple_fmus, advanced_fmus, tmp_path, version, model_name, case):
    """Held at rest (with and without the brake), rolling, and 1 ms (one Euler step) after the start from rest:
    every indicator is nonzero (an indicator at 0 over an interval is invisible to an integrator). At the instant
    of the start the Simple model's wheel indicators are 0 (its wheels' motion; no hysteresis, docs/fmu-runtime.md)."""
    fmu = (simple_fmus if model_name == "simple" else advanced_fmus)[version]
    values = {"held": {"v0": 0.0}, "held_braking": {"v0": 0.0, "brake": 1.0}, "moving": {"v0": 20.0},
              "starting": {"v0": 0.0, "throttle": 1.0}}[case]
    model, references, nz, nx = model_instance(fmu, version, tmp_path)
    initialized(model, references, version, values)
    if case == "starting":  # one forward Euler step of 1 ms
        x, dx = np.zeros(nx), np.zeros(nx)
        pointer = ctypes.POINTER(ctypes.c_double)
        model.getContinuousStates(x.ctypes.data_as(pointer), nx)
        (model.getDerivatives if version == 2 else model.getContinuousStateDerivatives)(dx.ctypes.data_as(pointer), nx)
        model.setTime(1e-3)
        x += 1e-3 * dx
        model.setContinuousStates(x.ctypes.data_as(pointer), nx)
    indicators = np.full(nz, np.nan)
    model.getEventIndicators(indicators.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), nz)
    assert np.all(indicators != 0.0), indicators
    model.terminate()
    model.freeInstance()


# ---- an integrator that restarts only when the FMU says its states changed -----------------------------------


def cvode_restarting_when_told(fmu, version, workdir, start, table, stop_time, interval, tolerance,
                               honour_flag=True):
    """fmusim v0.0.39's model-exchange loop (FMI2MESimulation.c) with fmpy's CVode: integrate to the next output
    point or input event, enter Event Mode at an input event or a root, apply the inputs after the event there, and
    restart the integrator only if the event iteration reports valuesOfContinuousStatesChanged (or never, with
    honour_flag False). Returns the time and distance at each output point."""
    from fmpy.simulation import Input
    from fmpy.sundials import CVodeSolver
    description = read_model_description(str(fmu))
    model, references, nz, nx = model_instance(fmu, version, workdir / ("restart" if honour_flag else "keep"))
    model.instantiate()
    if version == 2:
        model.setupExperiment(startTime=0.0)
        model.enterInitializationMode()
        model.setReal([references[name] for name in start], list(start.values()))
    else:
        model.enterInitializationMode(startTime=0.0)
        model.setFloat64([references[name] for name in start], list(start.values()))
    inputs = Input(model, description, table)
    inputs.apply(0.0)
    model.exitInitializationMode()
    update = model.newDiscreteStates if version == 2 else model.updateDiscreteStates
    while update()[0]:
        pass
    model.enterContinuousTimeMode()
    solver = CVodeSolver(nx=nx, nz=nz, get_x=model.getContinuousStates, set_x=model.setContinuousStates,
                         get_dx=model.getDerivatives if version == 2 else model.getContinuousStateDerivatives,
                         get_z=model.getEventIndicators, get_nominals=model.getNominalsOfContinuousStates,
                         set_time=model.setTime, input=inputs, startTime=0.0, maxStep=stop_time / 50,
                         relativeTolerance=tolerance)
    s = references["s"]
    read = (lambda: model.getReal([s])[0]) if version == 2 else (lambda: model.getFloat64([s])[0])
    time, n, samples = 0.0, 0, [(0.0, read())]
    while time < stop_time - interval / 2:
        regular = (n + 1) * interval
        next_input = inputs.nextEvent(time)
        target = min(regular, next_input)
        input_event = np.isclose(target, next_input)
        state_event, _, time = solver.step(time, target)
        model.setTime(time)
        inputs.apply(time, discrete=False)
        if np.isclose(time, regular):
            n += 1
            samples.append((time, read()))
        if input_event or state_event:
            model.enterEventMode()
            if input_event:
                inputs.apply(time, after_event=True)
            states_changed = False
            while True:
                needed, _, _, values_changed, _, _ = update()
                states_changed |= values_changed
                if not needed:
                    break
            model.enterContinuousTimeMode()
            if states_changed and honour_flag:
                solver.reset(time)
    model.terminate()
    model.freeInstance()
    return np.array(samples)


@VERSIONS
def test_an_input_jump_restarts_an_integrator_that_waits_for_the_flag(simple_fmus, tmp_path, version):
    """fmusim's CVode restarts only when the FMU reports changed continuous states. At an input table's jump the
    states do not change, but the right-hand side does: an integrator that keeps its history integrates across the
    jump with a model that no longer holds (measured with fmusim before the FMU raised the flag: +7.9 m at its
    default tolerance, and CVode failed at 1e-8). So a value change of an input in Event Mode raises
    valuesOfContinuousStatesChanged once.

    Closed form: start at v0 on a straight road (no drag, no rolling resistance, no pedal: the speed stays v0),
    full brake from t_b; the car then decelerates at mu g (module docstring) and stops at
    s = v0 t_b + v0^2 / (2 mu g). CVode at relative tolerance 1e-8 keeps each step's local error below 1e-8 of
    the state (plus the nominal-scaled absolute part) and the stop instant is a root it locates to ~1e-10 s; the
    global error over its few hundred steps stays below 1e-8 x (number of steps) x 60 m < 1e-4 m. A loop that
    ignores the flag (the importer without the FMU's help) misses by far more."""
    fmu = simple_fmus[version]
    v0, brake_time, stop_time = 20.0, 2.0, 8.0
    table = np.array([(0.0, 0.0), (brake_time, 0.0), (brake_time, 1.0), (stop_time, 1.0)],
                     dtype=[("time", float), ("brake", float)])
    start = {**STRAIGHT, "v0": v0}
    exact = v0 * brake_time + v0**2 / (2 * DECELERATION)
    told = cvode_restarting_when_told(fmu, version, tmp_path, start, table, stop_time, 0.01, 1e-8)
    assert abs(told[-1, 1] - exact) < 1e-4, (told[-1, 1], exact)
    untold = cvode_restarting_when_told(fmu, version, tmp_path, start, table, stop_time, 0.01, 1e-8,
                                        honour_flag=False)
    assert abs(untold[-1, 1] - exact) > 1e-2, (untold[-1, 1], exact)
