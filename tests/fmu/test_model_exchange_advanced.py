"""The Advanced model in fixed-step model exchange: fmpy's forward Euler drives the FMUs with start values only (and,
as fmusim and the FMI Compliance Checker do, with the pedals from a table), at steps of 1 to 50 ms.

In a model-exchange instance the Advanced model's wheels are quasi-static (wheel_spin = 0, automatic;
docs/fmu-runtime.md, "The Advanced model in fixed-step model exchange"): a rolling wheel's slip solves its torque
balance, a locked wheel slides. Nothing stiff is left at these speeds, so forward Euler converges to the model's own solution with
the error of a left Riemann sum: with the speed decreasing, each step adds at most h (v(t_k) - v(t_k+1)) to the
exact distance, h v0 over the whole stop (the same bound as the Simple model's, tests/fmu/test_model_exchange.py).

Every run is straight ahead without drag or rolling resistance on the shipped standard tire."""

import numpy as np
import pytest
from fmpy import simulate_fmu

from sdl_fmu.dynamics.advanced import STOP_SPEED, WHEEL_SPIN

WHEELS = ("fl", "fr", "rl", "rr")
V0 = 20.0
MASS, RADIUS, WHEEL_INERTIA, BRAKE_DECEL_MAX = 1500.0, 0.3, 1.0, 9.81
STRAIGHT = {"drag_area": 0.0, "rolling_resistance": 0.0, "mass": MASS, "wheel_radius": RADIUS,
            "wheel_inertia": WHEEL_INERTIA, "brake_decel_max": BRAKE_DECEL_MAX}
VERSIONS = pytest.mark.parametrize("version", [2, 3], ids=["fmi2", "fmi3"])
STEPS = pytest.mark.parametrize("step", [0.001, 0.01, 0.02, 0.05], ids=["1ms", "10ms", "20ms", "50ms"])
OUTPUTS = ["x", "s", "vx", "stopped", *[f"wheel_mode_{w}" for w in WHEELS]]
# rounding of the Euler sums (at most 10^4 additions of ~20 m/s x h) and of the quasi-static slip (Newton-converged
# to ~1e-15 relative): far below a millimetre
ROUNDING = 1e-9
# The CVode reference's own error: fmpy's CVode at relative tolerance 1e-10 (its absolute tolerance and event
# location included) gives 27.35760 m with the FMI 2.0 FMU and 27.35785 m with the FMI 3.0 one, the same equations:
# 2.5e-4 m apart. 1e-3 m covers that and stays far below the Euler excess, v0 h / 2 >= 0.01 m, that the bounds test.
CVODE_ERROR = 1e-3


def euler(fmu, step, stop_time, start, inputs=None):
    return simulate_fmu(str(fmu), fmi_type="ModelExchange", solver="Euler", step_size=step, output_interval=step,
                        stop_time=stop_time, start_values=start, input=inputs, output=OUTPUTS)


def cvode(fmu, stop_time, start, inputs=None, fmi_type="ModelExchange"):
    return simulate_fmu(str(fmu), fmi_type=fmi_type, solver="CVode", relative_tolerance=1e-10, output_interval=1e-3,
                        stop_time=stop_time, start_values=start, input=inputs, output=OUTPUTS)


def event_times(result):
    """fmpy records a second sample at the time of every event it handles."""
    times = result["time"]
    return times[1:][np.diff(times) == 0]


def assert_stops(result, step, brake_onset):
    """Stopped for good, never backwards, at most 2 events at the stop; the distance braked (from the onset)."""
    times, stopped = result["time"], result["stopped"]
    assert stopped[-1], "the car did not stop"
    first_stop = int(np.argmax(stopped))
    assert np.all(stopped[first_stop:]), "the car started again"
    assert np.all(result["vx"][first_stop:] == 0.0), "a stopped car moves"
    assert np.all(np.diff(result["x"]) >= 0.0), "the car moved backwards"
    # the events at the stop: from the last step that began above STOP_SPEED on
    last_moving = times[np.flatnonzero(result["vx"][:first_stop] > STOP_SPEED)[-1]]
    at_stop = event_times(result)[event_times(result) >= last_moving]
    assert 1 <= len(at_stop) <= 2, at_stop
    onset = int(np.searchsorted(times, brake_onset + step / 2)) - 1  # the last sample at the onset
    return result["s"][-1] - result["s"][onset]


@pytest.fixture(scope="module")
def full_brake_reference(advanced_fmus):
    """Full brake from V0: the front wheels lock at once (their brake asks 0.77 x 9.81 x 1500 / 2 = 5.7 kN, the
    tire's peak is 0.85 x 4.4 kN), the rear ones when the load transfer has unloaded them; the locked tire's
    force depends on its load, which lags the deceleration: no closed form. The reference is the same model's
    own accurate answer, CVode (rtol 1e-10) in model exchange, which locates the lock and stop events."""
    return {version: cvode(advanced_fmus[version], 10.0, {**STRAIGHT, "v0": V0, "brake": 1.0})
            for version in (2, 3)}


@VERSIONS
@STEPS
def test_full_brake_stops_in_forward_euler(advanced_fmus, full_brake_reference, version, step):
    """Within [reference, reference + v0 h]: the Riemann sum's excess (module docstring). A lock found up to one
    step late shortens the stop: for at most h the wheel gives its peak force instead of the sliding one, (0.85 -
    0.75) x 2 kN / 1500 kg x h = 0.13 h m/s of speed, 0.3 h m over the 2.3 s left; the Riemann excess for this
    near-constant deceleration is v0 h / 2 = 10 h m, so the distance stays above the reference."""
    reference = full_brake_reference[version]
    assert reference["stopped"][-1]
    expected = reference["s"][-1]
    result = euler(advanced_fmus[version], step, 10.0, {**STRAIGHT, "v0": V0, "brake": 1.0})
    travelled = assert_stops(result, step, 0.0)
    assert expected - CVODE_ERROR <= travelled <= expected + V0 * step + CVODE_ERROR, (travelled, expected)
    assert np.all(result[f"wheel_mode_{WHEELS[0]}"] == 0), "the front wheels lock from the start"


# Brake 0.3: every wheel keeps rolling (the front ones need 0.77 x 0.3 x 9.81 x 1500 / 2 = 1.7 kN of a 3.7 kN
# peak). A rolling quasi-static wheel gives Fx_i = -T_brake_i / R - I_w a / R^2 (its spin decelerates with the
# body), so m a = -sum T_brake_i / R - 4 I_w a / R^2 and, with sum T_brake_i = brake brake_decel_max m R,
#     a = -brake brake_decel_max m / (m + 4 I_w / R^2),
# constant: the car stops (is held at STOP_SPEED) after (v0^2 - STOP_SPEED^2) / (2 |a|).
BRAKE = 0.3
DECELERATION = BRAKE * BRAKE_DECEL_MAX * MASS / (MASS + 4 * WHEEL_INERTIA / RADIUS**2)
BRAKE_STOP = (V0**2 - STOP_SPEED**2) / (2 * DECELERATION)


@VERSIONS
@STEPS
def test_partial_brake_decelerates_monotonically_and_stops(advanced_fmus, version, step):
    """Within [closed form, closed form + v0 h] (module docstring; the last step may end below STOP_SPEED, which
    only shortens the Riemann sum's excess). Monotonic: the speed never rises while moving; the step that crosses
    STOP_SPEED may end at most a h below 0 before the event holds the car (x never decreases, checked)."""
    result = euler(advanced_fmus[version], step, 10.0, {**STRAIGHT, "v0": V0, "brake": BRAKE})
    travelled = assert_stops(result, step, 0.0)
    assert BRAKE_STOP - ROUNDING <= travelled <= BRAKE_STOP + V0 * step + ROUNDING, (travelled, BRAKE_STOP)
    first_stop = int(np.argmax(result["stopped"]))
    moving = result["vx"][:first_stop]
    assert np.all(np.diff(moving) <= 0.0), "the car did not decelerate monotonically"
    assert moving[-1] >= -DECELERATION * step - ROUNDING
    for w in WHEELS:
        assert np.all(result[f"wheel_mode_{w}"][:first_stop] == 1), f"wheel {w} did not keep rolling"


@VERSIONS
@pytest.mark.parametrize("step", [0.01, 0.02], ids=["10ms", "20ms"])
def test_throttle_then_brake_from_an_input_table(advanced_fmus, version, step):
    """As fmusim and the Compliance Checker drive an FMU: start values only, the pedals from a table (6 s of full
    throttle from rest, then full brake). Reference: CVode on the same table. Euler reaches the onset at a
    slightly different speed v (its error while accelerating); the braking distance from v is the reference's,
    s_c, scaled for the speed: s_c + (v^2 - v_c^2) / (2 a_c) with the reference's mean deceleration a_c =
    v_c^2 / (2 s_c) (exact for a constant deceleration; the lagged load transfer's share, which does not grow with
    v^2, changes the correction by a few per cent of (v - v_c) v / a_c, below a millimetre here)."""
    table = np.array([(0.0, 1.0, 0.0), (6.0, 1.0, 0.0), (6.0, 0.0, 1.0), (14.0, 0.0, 1.0)],
                     dtype=[("time", float), ("throttle", float), ("brake", float)])
    start = {**STRAIGHT, "v0": 0.0}
    reference = cvode(advanced_fmus[version], 14.0, start, table)
    result = euler(advanced_fmus[version], step, 14.0, start, table)

    def onset_speed(run, h):
        return run["vx"][int(np.searchsorted(run["time"], 6.0 + h / 2)) - 1]

    speed, reference_speed = onset_speed(result, step), onset_speed(reference, 1e-3)
    assert speed > 20.0 and not result["stopped"][int(np.searchsorted(result["time"], 6.0))]  # it drove off
    reference_distance = reference["s"][-1] - reference["s"][int(np.searchsorted(reference["time"], 6.0 + 5e-4)) - 1]
    mean_deceleration = reference_speed**2 / (2 * reference_distance)
    expected = reference_distance + (speed**2 - reference_speed**2) / (2 * mean_deceleration)
    travelled = assert_stops(result, step, 6.0)
    correction_error = 0.05 * abs(speed - reference_speed) * speed / mean_deceleration
    assert expected - correction_error - CVODE_ERROR <= travelled, (travelled, expected)
    assert travelled <= expected + speed * step + correction_error + CVODE_ERROR, (travelled, expected)


# ---- the quasi-static wheels against the dynamic ones (co-simulation) ------------------------------------------


@VERSIONS
def test_quasi_static_wheels_follow_the_dynamic_ones(advanced_fmus, version):
    """Brake 0.3 from V0, CVode model exchange (quasi-static) against co-simulation (dynamic wheels). What the
    quasi-static wheel neglects: (1) its spin's inertia rides on the body's deceleration a, not on a (1 + kappa)
    + v dkappa/dt: with the slip kappa = Fx / C_kappa, C_kappa = PKX1 LKX Fz = 21.51 x 1.0 x ~4 kN, at most
    1.7 kN / 86 kN = 0.02, the inertia share 4 I_w / (m R^2) = 0.03 of the deceleration is off by 2 %, i.e.
    6e-4 of the distance (0.04 m of 70 m); (2) the slip's build-up at the onset: the spin equation's time constant
    I_w v / (C_kappa R^2) = 1 x 20 / (86e3 x 0.09) = 2.6 ms, during which the dynamic car brakes less, about
    v0 x 2.6 ms / 2 = 0.03 m. Bound: 0.07 m."""
    start = {**STRAIGHT, "v0": V0, "brake": BRAKE}
    quasi_static = cvode(advanced_fmus[version], 10.0, start)
    dynamic = cvode(advanced_fmus[version], 10.0, start, fmi_type="CoSimulation")
    assert quasi_static["stopped"][-1] and dynamic["stopped"][-1]
    assert abs(quasi_static["s"][-1] - dynamic["s"][-1]) <= 0.07
    # and model exchange with the dynamic wheels selected is co-simulation's model
    selected = cvode(advanced_fmus[version], 10.0, {**start, "wheel_spin": WHEEL_SPIN["dynamic"]})
    assert abs(selected["s"][-1] - dynamic["s"][-1]) <= 1e-4


@VERSIONS
@pytest.mark.parametrize("rolling_resistance", [0.012, 2.0])
def test_rolling_resistance_beyond_the_peak_locks_the_wheels_for_good(advanced_fmus, version, rolling_resistance):
    """A rolling wheel locks when its brake and rolling-resistance torque ask more of the tire than its peak force
    R mu_peak Fz (mu_peak ~ 0.85 on the standard tire); a locked wheel is held while the same torque exceeds what
    would release it. With f_r = 2.0, f_r Fz R > R mu_peak Fz on every wheel at any load: no wheel can roll, so
    every wheel locks at the initial event and stays locked (before both tests counted rolling resistance, the
    event iteration locked and released the wheels until it gave up: found by the fuzzer). With the default
    f_r = 0.012 and no pedal every wheel rolls. Either way the car comes to rest and never moves backwards."""
    result = euler(advanced_fmus[version], 0.01, 1.0, {**STRAIGHT, "v0": 0.2, "rolling_resistance": rolling_resistance})
    locked = rolling_resistance > 0.85
    for w in WHEELS:
        modes = result[f"wheel_mode_{w}"][result["stopped"] == 0]
        assert np.all(modes == (0 if locked else 1)), (w, modes)
    assert np.all(np.diff(result["x"]) >= 0.0)
    if locked:  # sliding at mu ~ 0.75 from 0.2 m/s stops within a few hundredths of a second
        assert result["stopped"][-1]



@VERSIONS
@pytest.mark.parametrize("case", ["light_car_full_throttle", "heavy_wheels_brake_and_throttle"])
def test_the_event_iteration_settles_when_the_wheels_outweigh_the_car(advanced_fmus, version, case):
    """Quasi-static wheels where a wheel's rotational inertia, I / R^2 = 11.1 kg and more, is comparable to the car's
    mass (cases found by the fuzzer and by a random search over the declared ranges): a rolling wheel needs
    I a_x / R^2 of its tire's force to follow the body, and before the fix that demand locked a wheel that the hold
    test, blind to it, released again, until the event iteration gave up (the runtime then returns Error, which
    fmpy raises). Now each rolling wheel's share of a_x is clipped to its tire's capacity and a locked wheel is
    released only if it would pass the lock test at the acceleration it would then see, with the margin
    1 - RELEASE_SHARE: every event iteration settles, each wheel mode stays one of -1, 0, 1, and on the straight
    the car never moves backwards."""
    start = {"light_car_full_throttle": {**STRAIGHT, "mass": 1.1, "throttle": 1.0, "v0": 0.0},
             "heavy_wheels_brake_and_throttle": {**STRAIGHT, "mass": 6.6186, "wheel_inertia": 1.0568,
                                                 "rolling_resistance": 0.012, "v0": 0.0, "throttle": 0.2335,
                                                 "brake": 1.0, "steer": -0.4473}}[case]
    result = euler(advanced_fmus[version], 0.001, 0.3, start)
    for w in WHEELS:
        assert set(np.unique(result[f"wheel_mode_{w}"])) <= {-1, 0, 1}
    assert result["vx"][-1] > 0.0  # the drive beats the brake on both cars: they move off
    if "steer" not in start:
        assert np.all(np.diff(result["x"]) >= 0.0)
