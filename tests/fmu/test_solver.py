"""The FMUs' error-controlled co-simulation solver (cosimulation.c): accuracy against a closed form as the
tolerance varies, and an FMU state that repeats its steps exactly."""

import math
import shutil

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave

from helpers import parameter_defaults

V0 = 40.0  # m/s
COAST_TIME = 20.0  # s


def coasting_distance(drag_factor, v0, t):
    """Coasting against air drag alone: v' = -K v^2, so v = v0 / (1 + K v0 t) and s = ln(1 + K v0 t) / K."""
    return math.log(1 + drag_factor * v0 * t) / drag_factor


@pytest.fixture(scope="module")
def coasting_errors(simple_fmu):
    """The error in s of a 20 s coast from 40 m/s, in one communication step, at each tolerance; solver_step
    10 s lets the error control alone choose the internal steps."""
    p = parameter_defaults(simple_fmu)
    drag_factor = p["air_density"] * p["drag_area"] / (2 * p["mass"])
    exact = coasting_distance(drag_factor, V0, COAST_TIME)
    errors = {}
    for tolerance in (1e-6, 1e-7, 1e-8, 1e-9):
        result = simulate_fmu(str(simple_fmu), fmi_type="CoSimulation", output=["s"], stop_time=COAST_TIME,
                              output_interval=COAST_TIME,
                              start_values={"v0": V0, "rolling_resistance": 0.0, "solver_step": 10.0,
                                            "solver_tolerance": tolerance})
        errors[tolerance] = result["s"][-1] - exact
    return drag_factor, exact, errors


def test_global_error_stays_within_the_tolerance(coasting_errors, simple_fmu):
    # The controller holds the local error of RODAS4's embedded third-order solution at about
    # tol * (nominal + |s|) per step (nominal of s: 100 m). The propagated fourth-order solution's local error
    # is smaller by the ratio of the next Taylor terms, ~h |s^(5) / s^(4)|: with v = v0 / (1 + K v0 t),
    # v^(n) = (-1)^n n! K^n v^(n+1), so s^(5) / s^(4) = v'''' / v''' = 4 K v. The coasting car is dissipative
    # (errors do not grow), so over the run the errors add up to at most
    # sum h 4 K v tol (nominal + |s|) <= T 4 K v0 tol (nominal + |s|) = 20 x 4 x 2.86e-4 x 40 = 0.92 of
    # tol (nominal + |s|). Bound: tol (nominal + |s|). Measured: 0.05 of it at every tolerance.
    drag_factor, exact, errors = coasting_errors
    assert COAST_TIME * 4 * drag_factor * V0 < 1.0
    nominal = float({v.name: v.nominal for v in read_model_description(str(simple_fmu)).modelVariables}["s"])
    for tolerance, error in errors.items():
        print(f"tolerance {tolerance:g}: error {error:.3e} m = {abs(error) / (tolerance * (nominal + exact)):.3f} "
              "of tol (nominal + |s|)")
        assert abs(error) <= tolerance * (nominal + exact)


def test_the_error_falls_in_proportion_to_the_tolerance(coasting_errors):
    # Error-per-step control of an order-4 method: steps h ~ tol^(1/4), each with a local error ~h^5 ~ tol^(5/4),
    # T / h ~ tol^(-1/4) of them: a global error ~ tol. Three decades of tolerance, 1e-6 -> 1e-9, should then
    # give 1000x; required 100x. A controller that ignored the tolerance would give 1x.
    _, _, errors = coasting_errors
    assert abs(errors[1e-6]) >= 100 * abs(errors[1e-9]) > 0


def test_default_longest_step_keeps_the_closed_form_to_round_off(simple_fmu):
    # With the default solver_step (0.1 s) and tolerance (1e-8), the longest step binds before the error
    # control does here: the local error is C h^5 |s^(5)| with s^(5) = v'''' = 24 K^4 v^5 <= 1.7e-5 m/s^5 and
    # h = 0.1 s, and C, RODAS4's error constant, is of the order of the Taylor remainder's 1/5! ~ 1e-2:
    # 1.7e-12 m per step, 200 steps: 3.4e-10 m on 720 m = 5e-13 relative. Allowed 1e-11 (C up to 0.2).
    # Measured 4e-14.
    p = parameter_defaults(simple_fmu)
    drag_factor = p["air_density"] * p["drag_area"] / (2 * p["mass"])
    assert 24 * drag_factor**4 * V0**5 < 1.7e-5
    exact = coasting_distance(drag_factor, V0, COAST_TIME)
    result = simulate_fmu(str(simple_fmu), fmi_type="CoSimulation", output=["s"], stop_time=COAST_TIME,
                          output_interval=1.0, start_values={"v0": V0, "rolling_resistance": 0.0})
    assert abs(result["s"][-1] - exact) / exact < 1e-11


def test_a_restored_state_repeats_the_same_steps(advanced_fmu, tmp_path):
    # The error-controlled step carries its next length from one doStep to the next, and the FMU state holds
    # it: from a restored (or deserialized) state the same doSteps give bit-identical outputs. Without it,
    # the first internal step after the restore would differ and so, at round-off level, would the outputs.
    description = read_model_description(str(advanced_fmu))
    refs = [v.valueReference for v in description.modelVariables
            if v.name in ("x", "y", "psi", "s", "vx", "vy", "yaw_rate")]
    inputs = {v.name: v.valueReference for v in description.modelVariables}
    unzipped = extract(str(advanced_fmu), unzipdir=str(tmp_path / "fmu"))
    slave = FMU2Slave(guid=description.guid, unzipDirectory=unzipped,
                      modelIdentifier=description.coSimulation.modelIdentifier, instanceName="restore")
    try:
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.setReal([inputs["v0"]], [25.0])
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        slave.setReal([inputs["steer"], inputs["brake"]], [0.04, 0.3])
        # communication steps (0.3 s) longer than the internal steps the error control takes (up to 0.1 s)
        times = np.round(np.arange(0.0, 6.0, 0.3), 12)
        for t, h in zip(times[:8], np.diff(times)[:8]):
            slave.doStep(float(t), float(h))
        saved = slave.getFMUstate()
        serialized = slave.serializeFMUstate(saved)

        def run_on():
            outputs = []
            for t, h in zip(times[8:-1], np.diff(times)[8:]):
                slave.doStep(float(t), float(h))
                outputs.append(slave.getReal(refs))
            return np.array(outputs)

        first = run_on()
        slave.setFMUstate(saved)
        again = run_on()
        slave.setFMUstate(slave.deSerializeFMUstate(serialized))
        deserialized = run_on()
        assert np.array_equal(first, again) and np.array_equal(first, deserialized)
        assert abs(first[-1][3] - first[0][3]) > 10.0  # it moved: s grew by more than 10 m
        slave.freeFMUstate(saved)
        slave.terminate()
    finally:
        slave.freeInstance()
        shutil.rmtree(unzipped, ignore_errors=True)
