"""The standard's letter, through ctypes on the real binaries: a communication step of 0 is refused (FMI 2.0.4
sec. 4.2.2, FMI 3.0 fmi3DoStep: communicationStepSize > 0); SetDebugLogging honours its categories and refuses
unknown ones with a message; the FMI 3.0 state table's rows for fmi3GetNominalsOfContinuousStates,
fmi3GetNumberOf* and fmi3SetTime; a refused null output argument is explained by a log message."""

import ctypes

import fmi_fuzz as fuzz
from sdl_fmu.fmu.xml import LOG_CATEGORIES

from helpers import ERROR, OK, Raw, Raw3

DISCARD = fuzz.DISCARD


def declare(library, name, argtypes):
    """Signatures the fuzzer does not call (without them ctypes would pass pointers as C ints)."""
    function = getattr(library, name)
    function.restype, function.argtypes = ctypes.c_int, argtypes
    return library


LOGGING_ARGUMENTS = [ctypes.c_void_p, ctypes.c_int, ctypes.c_size_t, ctypes.POINTER(ctypes.c_char_p)]


class Categorised(Raw):
    """Raw, also recording each message's category."""

    def _log(self, environment, name, status, category, message, argument):
        super()._log(environment, name, status, category, message, argument)
        self.categories = getattr(self, "categories", []) + [category.decode()]

    def instantiate(self, kind=fuzz.CS):
        declare(self.library, "fmi2SetDebugLogging", LOGGING_ARGUMENTS)
        return super().instantiate(kind)


def categories(names):
    return len(names), (ctypes.c_char_p * len(names))(*[n.encode() for n in names])


def test_a_step_of_zero_is_refused(simple_fmus, tmp_path):
    cs2 = Raw(simple_fmus[2], tmp_path / "2").instantiate().start(v0=20.0)
    cs3 = Raw3(simple_fmus[3], tmp_path / "3")
    try:
        assert cs2("DoStep", 0.0, 0.0, 1) == ERROR
        assert cs2("DoStep", 0.0, 0.01, 1) == OK  # refused arguments leave it usable
        assert cs3("EnterInitializationMode", False, 0.0, 0.0, False, 0.0) == OK
        assert cs3("ExitInitializationMode") == OK
        assert cs3.do_step(0.0, 0.0) == ERROR
        assert cs3.do_step(0.0, 0.01) == OK
    finally:
        cs2.free()
        cs3.free()


def test_debug_logging_honours_categories(simple_fmu, tmp_path):
    raw = Categorised(simple_fmu, tmp_path).instantiate()
    try:
        assert raw("SetDebugLogging", 1, *categories(["logNoSuchCategory"])) == ERROR
        assert any("logNoSuchCategory" in m for _, m in raw.messages)
        assert raw("SetDebugLogging", 1, *categories(["logStatusError"])) == OK
        raw.start(v0=2.0, brake=1.0)  # stops after v0 / (mu g) = 0.34 s: a stop event inside the step
        raw.categories = []
        assert raw("DoStep", 0.0, 1.0, 1) == OK
        assert "logEvents" not in raw.categories
        assert raw("SetDebugLogging", 1, *categories(["logEvents"])) == OK
        assert raw("DoStep", 1.0, 0.5, 1) == OK  # held: no event, but the discrete update runs quietly
        raw2 = Categorised(simple_fmu, tmp_path / "second").instantiate()
        try:
            assert raw2("SetDebugLogging", 1, *categories(["logEvents"])) == OK
            raw2.start(v0=2.0, brake=1.0)
            raw2.categories = []
            assert raw2("DoStep", 0.0, 1.0, 1) == OK
            assert "logEvents" in raw2.categories  # the same stop, now logged
        finally:
            raw2.free()
    finally:
        raw.free()


def test_the_runtime_knows_the_declared_categories(simple_fmu, tmp_path):
    raw = Categorised(simple_fmu, tmp_path).instantiate()
    try:
        assert raw("SetDebugLogging", 1, *categories(list(LOG_CATEGORIES))) == OK
    finally:
        raw.free()


def test_fmi3_state_table_rows(simple_fmus, tmp_path):
    me = Raw3(simple_fmus[3], tmp_path, cosimulation=False)
    for name in ("fmi3GetNumberOfContinuousStates", "fmi3GetNumberOfEventIndicators"):
        declare(me.library, name, [ctypes.c_void_p, ctypes.POINTER(ctypes.c_size_t)])
    try:
        nx = me.description.numberOfContinuousStates
        count = ctypes.c_size_t()
        # Instantiated: the numbers yes, the nominals not yet
        assert me("GetNumberOfContinuousStates", ctypes.byref(count)) == OK and count.value == nx
        assert me("GetNumberOfEventIndicators", ctypes.byref(count)) == OK
        assert me("GetNominalsOfContinuousStates", (ctypes.c_double * nx)(), nx) == ERROR
        assert me("GetNumberOfContinuousStates", None) == ERROR  # a null output, with a message
        assert me("EnterInitializationMode", False, 0.0, 0.0, False, 0.0) == OK
        assert me("GetNumberOfContinuousStates", ctypes.byref(count)) == ERROR
        assert me("ExitInitializationMode") == OK  # Event Mode
        assert me("SetTime", 0.0) == ERROR
        assert me("GetNumberOfContinuousStates", ctypes.byref(count)) == OK
        assert me("EnterContinuousTimeMode") == OK
        assert me("GetNumberOfEventIndicators", ctypes.byref(count)) == ERROR
        assert me("GetNominalsOfContinuousStates", (ctypes.c_double * nx)(), nx) == OK
        assert me("SetTime", 0.001) == OK
        flag = ctypes.c_bool()
        assert me("CompletedIntegratorStep", True, None, ctypes.byref(flag)) == ERROR
        assert me("SerializedFMUStateSize", None, None) == ERROR
    finally:
        me.free()


def test_status_kinds_the_fmu_does_not_report_are_discarded_with_a_message(simple_fmu, tmp_path):
    """FMI 2.0 sec. 4.2.3: fmi2Get*Status returns fmi2Discard for a kind it cannot report; like every non-OK
    return here, it says why. fmi2StatusKind: 0 DoStepStatus, 1 PendingStatus, 2 LastSuccessfulTime, 3 Terminated."""
    raw = Raw(simple_fmu, tmp_path).instantiate().start(v0=20.0)
    getters = {"GetStatus": ctypes.c_int, "GetRealStatus": ctypes.c_double, "GetIntegerStatus": ctypes.c_int,
               "GetBooleanStatus": ctypes.c_int, "GetStringStatus": ctypes.c_char_p}
    for name, kind_type in getters.items():
        declare(raw.library, f"fmi2{name}", [ctypes.c_void_p, ctypes.c_int, ctypes.POINTER(kind_type)])
    reported = {("GetStatus", 0), ("GetRealStatus", 2), ("GetBooleanStatus", 3)}
    try:
        assert raw("DoStep", 0.0, 0.01, 1) == OK
        for name, kind_type in getters.items():
            for kind in (0, 1, 2, 3, 7):
                value = kind_type()
                status = raw(name, kind, ctypes.byref(value))
                if (name, kind) in reported:
                    assert status == OK, (name, kind)
                else:
                    assert status == DISCARD, (name, kind)
                    assert [m for s, m in raw.messages if s == DISCARD and f"fmi2{name}" in m], (name, kind)
        real, terminated = ctypes.c_double(), ctypes.c_int(1)
        assert raw("GetRealStatus", 2, ctypes.byref(real)) == OK and real.value == 0.01  # fmi2LastSuccessfulTime
        assert raw("GetBooleanStatus", 3, ctypes.byref(terminated)) == OK and terminated.value == 0
    finally:
        raw.free()
