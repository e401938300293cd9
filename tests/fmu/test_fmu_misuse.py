"""The hardened runtime, called through ctypes: every misuse docs/fmu-runtime.md lists returns fmi2Error with a log
message, argument errors leave the instance usable, no call runs without bound, and serialized states are
checked (GUID hash, checksum, then field by field) before they touch the instance."""

import ctypes
import math
import struct

import pytest

import fmi_fuzz as fuzz

from helpers import ERROR, OK, WHEELS, G, Raw, Raw3


@pytest.fixture
def simple(simple_fmu, tmp_path):
    raw = Raw(simple_fmu, tmp_path).instantiate()
    yield raw
    raw.free()


@pytest.fixture
def advanced_me(advanced_fmu, tmp_path):
    raw = Raw(advanced_fmu, tmp_path).instantiate(fuzz.ME)
    yield raw
    raw.free()


def usable(raw, t):
    """The instance still steps normally from time t."""
    return raw("DoStep", t, 0.01, 1) == OK


def test_nan_communication_point_or_start_time_is_an_error(simple):
    assert simple("SetupExperiment", 0, 0.0, math.nan, 0, 0.0) == ERROR
    assert simple("SetupExperiment", 1, 0.0, 0.0, 1, math.nan) == ERROR
    simple.start(v0=10.0)
    assert simple("DoStep", math.nan, 0.01, 1) == ERROR
    assert simple("DoStep", 0.0, math.nan, 1) == ERROR
    assert usable(simple, 0.0)
    assert simple.get_real("s")[0] == pytest.approx(0.1, rel=1e-3)


def test_time_that_cannot_advance_is_an_error_not_a_hang(simple):
    simple.start(start_time=1e16, v0=10.0)  # 1e16 + 1 ms == 1e16 in double precision
    assert simple("DoStep", 1e16, 1e-3, 1) == ERROR
    assert "time cannot advance" in simple.messages[-1][1]
    assert simple("DoStep", 1e16, 2.0, 1) == ERROR  # t + 2 s exists, but not t + one 1 ms internal step
    assert simple("DoStep", 1e16, 0.0, 1) == ERROR  # FMI 2.0.4: a communication step must be > 0
    assert simple("Terminate") == OK  # argument errors: the instance is not in the error state (Step Mode)


def test_internal_step_budget_bounds_every_do_step(simple):
    simple.start(v0=10.0)
    assert simple.set_real(solver_step=1e-300) == ERROR  # below its declared min 1e-6: refused
    assert simple("DoStep", 0.0, 1e300, 1) == ERROR
    assert simple("DoStep", 0.0, 0.1 * 50001, 1) == ERROR  # the budget: 50000 internal steps of at most
    # solver_step (default 0.1 s) per doStep
    assert "budget" in simple.messages[-1][1]  # bounded work, whatever the machine's speed
    assert usable(simple, 0.0)


def test_error_controlled_steps_cannot_run_without_bound(simple, simple_fmu, tmp_path):
    # A tolerance no step can meet (1e-300, allowed by the declared minimum 0): every step is rejected and
    # shrinks 5x until time cannot advance; an error, at once.
    simple.start(v0=30.0, steer=0.05, solver_tolerance=1e-300)
    assert simple("DoStep", 0.0, 1.0, 1) == ERROR
    assert "time cannot advance" in simple.messages[-1][1]
    # 1e-15 is met only by steps of ~2 ms in a steady turn (round-off in the estimate): 100 s would take more
    # than the 50 000 internal steps one doStep may take (measured: the budget is reached at t = 92 s).
    other = Raw(simple_fmu, tmp_path / "other").instantiate()
    try:
        other.start(v0=30.0, steer=0.05, solver_tolerance=1e-15)
        assert other("DoStep", 0.0, 100.0, 1) == ERROR
        assert "budget of 50000 internal steps" in other.messages[-1][1]
        assert other("Reset") == OK
    finally:
        other.free()
    assert simple("Reset") == OK


def test_step_far_below_solver_step_and_event_at_the_end_of_a_step(simple):
    # solver_step 0.01: a step of 5e-12 s used to divide by zero in the step splitter (ceil(5e-10 - 1e-9) = 0);
    # so did the rest of a step after an event located within 1e-11 s of the step's end.
    mu, v0 = 0.6, 30.0
    simple.start(v0=v0, brake=1.0, drag_area=0.0, rolling_resistance=0.0, solver_step=0.01,
                 **{f"mu_{w}": mu for w in WHEELS})
    assert simple("DoStep", 0.0, 5e-12, 1) == OK
    t_stop = v0 / (mu * G)  # constant deceleration mu g (< brake_decel_max)
    assert simple("DoStep", 5e-12, t_stop, 1) == OK  # ends 5e-12 s after the stop
    s, v = simple.get_real("s", "v")
    assert v == 0.0 and s == pytest.approx(v0**2 / (2 * mu * G), rel=1e-9)
    assert usable(simple, t_stop + 5e-12)


def test_values_outside_the_declared_range_are_refused_and_change_nothing(simple):
    assert simple.set_real(brake=-1.0) == ERROR
    assert "outside its declared range" in simple.messages[-1][1]
    assert simple.set_real(mass=-1500.0) == ERROR
    assert simple.set_real(mu_fl=-0.5) == ERROR
    assert simple.set_real(steer=1.5) == ERROR
    assert simple.set_real(throttle=math.inf) == ERROR
    assert simple.set_real(brake=0.5, throttle=2.0) == ERROR  # refused as a whole: brake unchanged
    simple.start(v0=0.0)
    assert simple.get_real("brake", "throttle", "mass") == [0.0, 0.0, 1500.0]
    for k in range(100):
        assert usable(simple, k * 0.01)
    assert simple.get_real("s", "v") == [0.0, 0.0]  # brake -1 would have driven the car from rest


def test_state_table_of_fmi2(simple, advanced_me):
    assert simple("Terminate") == ERROR  # Instantiated
    simple("SetupExperiment", 0, 0.0, 0.0, 0, 0.0)
    simple("EnterInitializationMode")
    assert simple("Terminate") == ERROR  # Initialization Mode
    for name, args in [("EnterEventMode", ()), ("SetTime", (0.0,)), ("EnterContinuousTimeMode", ()),
                       ("GetDerivatives", ((ctypes.c_double * 5)(), 5)),
                       ("GetContinuousStates", ((ctypes.c_double * 5)(), 5)),
                       ("GetNominalsOfContinuousStates", ((ctypes.c_double * 5)(), 5))]:
        assert simple(name, *args) == ERROR, name  # model-exchange functions on a co-simulation instance
    assert simple("ExitInitializationMode") == OK
    assert usable(simple, 0.0)

    me = advanced_me
    me.start(v0=10.0)  # now in Event Mode
    assert me("DoStep", 0.0, 0.01, 1) == ERROR  # a co-simulation function on a model-exchange instance
    assert me("GetRealStatus", 2, ctypes.byref(ctypes.c_double())) == ERROR
    assert me("EnterContinuousTimeMode") == OK
    surface = (ctypes.c_uint * 1)(me.vr["surface_fl"])
    assert me("SetInteger", surface, 1, (ctypes.c_int * 1)(1)) == ERROR  # a discrete input in Continuous-Time Mode
    assert me.set_real(steer=0.01) == OK  # a continuous one is fine
    assert me("EnterEventMode") == OK
    assert me("SetInteger", surface, 1, (ctypes.c_int * 1)(1)) == OK


# Serialized layout (instance.c): 8-byte words magic | GUID hash | nx nd nu np | mode | time | x d u p | checksum
def fnv1a(data):
    value = 14695981039346656037
    for byte in data:
        value = ((value ^ byte) * 1099511628211) % 2**64
    return value


def with_checksum(data):
    return data[:-8] + struct.pack("<Q", fnv1a(data[:-8]))


def test_serialized_states_are_validated_field_by_field(simple, advanced_fmu, tmp_path):
    simple.start(v0=20.0, brake=0.5)
    assert usable(simple, 0.0)
    good = bytearray(simple.serialize())
    nx, nd, nu, np_ = struct.unpack_from("<4Q", good, 16)
    mode_at, time_at, solver_step_at, x_at = 48, 56, 64, 72
    u_at = x_at + 8 * (nx + nd)
    p_at = u_at + 8 * nu
    assert len(good) == 8 * (9 + nx + nd + nu + np_ + 1)
    mass_at = p_at + 8 * [v.name for v in simple.description.modelVariables
                          if v.causality == "parameter"].index("mass")

    def corrupt(offset, fmt, value, fix_checksum=True):
        data = bytearray(good)
        struct.pack_into(fmt, data, offset, value)
        return with_checksum(data) if fix_checksum else data

    cases = {
        "mode word": corrupt(mode_at, "<Q", 0x7),
        "error mode": corrupt(mode_at, "<Q", 1 << 6),
        "model-exchange mode": corrupt(mode_at, "<Q", 1 << 3),
        "time NaN": corrupt(time_at, "<d", math.nan),
        "time inf": corrupt(time_at, "<d", math.inf),
        "solver step NaN": corrupt(solver_step_at, "<d", math.nan),
        "solver step negative": corrupt(solver_step_at, "<d", -1e-3),
        "state NaN": corrupt(x_at, "<d", math.nan),
        "input out of range": corrupt(u_at + 8, "<d", -1.0),  # brake
        "negative mass": corrupt(mass_at, "<d", -1500.0),
        "GUID hash": corrupt(8, "<Q", 12345),
        "bit flip": corrupt(x_at + 3, "<B", good[x_at + 3] ^ 4, fix_checksum=False),
        "truncated": good[:-1],
    }
    t = 0.01
    for name, data in cases.items():
        assert simple.deserialize_and_set(data) == ERROR, name
        assert usable(simple, t), name  # nothing reached the instance
        t += 0.01
    assert simple.deserialize_and_set(with_checksum(bytearray(good))) == OK
    assert usable(simple, 0.01)  # back at the saved time
    assert simple("Reset") == OK

    other = Raw(advanced_fmu, tmp_path / "advanced").instantiate()
    try:
        assert other.deserialize_and_set(good) == ERROR  # another model's state
    finally:
        other.free()


# ---- FMI 3.0: the same shared checks behind fmi3Functions.c, and its own state table ---------------------------


def test_fmi3_gets_the_same_hardening(simple_fmus, advanced_fmus, tmp_path):
    cs = Raw3(simple_fmus[3], tmp_path / "cs")
    try:
        assert cs.set_float64(brake=-1.0) == ERROR and cs.set_float64(mass=-1.0) == ERROR
        assert cs("EnterInitializationMode", False, 0.0, math.nan, False, 0.0) == ERROR
        assert cs("EnterInitializationMode", False, 0.0, 0.0, True, -1.0) == ERROR  # stop before start
        assert cs("EnterInitializationMode", False, 0.0, 0.0, False, 0.0) == OK
        assert cs("Terminate") == ERROR  # Initialization Mode
        assert cs("ExitInitializationMode") == OK
        assert cs("EnterContinuousTimeMode") == ERROR and cs("SetTime", 0.0) == ERROR  # model exchange only
        assert cs.do_step(math.nan, 0.01) == ERROR and cs.do_step(0.0, 1e300) == ERROR
        assert cs.do_step(0.0, 0.1 * 50001) == ERROR  # the internal-step budget (solver_step 0.1 s)
        assert cs.do_step(0.0, 0.01) == OK  # argument errors left it usable
        state = ctypes.c_void_p()
        assert cs("GetFMUState", ctypes.byref(state)) == OK
        size = ctypes.c_size_t()
        assert cs("SerializedFMUStateSize", state, ctypes.byref(size)) == OK
        buffer = ctypes.create_string_buffer(size.value)
        assert cs("SerializeFMUState", state, buffer, size.value) == OK
        corrupted = bytearray(buffer.raw)
        corrupted[60] ^= 1  # a bit of the time
        copy = ctypes.c_void_p()
        assert cs("DeserializeFMUState", bytes(corrupted), len(corrupted), ctypes.byref(copy)) == ERROR
        assert cs("FreeFMUState", ctypes.byref(state)) == OK
    finally:
        cs.free()

    me = Raw3(advanced_fmus[3], tmp_path / "me", cosimulation=False)
    try:
        assert me("EnterInitializationMode", False, 0.0, 0.0, False, 0.0) == OK
        assert me("ExitInitializationMode") == OK  # Event Mode
        assert me.do_step(0.0, 0.01) == ERROR  # co-simulation only
        assert me("EnterContinuousTimeMode") == OK
        surface = (ctypes.c_uint * 1)(me.vr["surface_fl"])
        assert me("SetInt32", surface, 1, (ctypes.c_int32 * 1)(1), 1) == ERROR  # discrete input, Continuous-Time Mode
        assert me("SetTime", math.inf) == ERROR
        nx = me.description.numberOfContinuousStates
        assert me("SetContinuousStates", (ctypes.c_double * nx)(*[math.nan] * nx), nx) == ERROR
    finally:
        me.free()
