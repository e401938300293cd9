"""FMU-state handles are checked by looking them up in the instance's registry, never by reading through them:
a wrong pointer (the handle's address where the handle is due, or the handle where its address is due), a freed
handle, a double free and another instance's handle each return an error with a log message, and the instance
goes on. Through ctypes (FMI 2.0 and 3.0) and through the plain C host calling the functions the way fmusim
v0.0.39's state-file options do."""

import ctypes
import subprocess

import pytest

import fmi_fuzz as fuzz
from sdl_fmu.fmu.package import fmi_headers

from helpers import ERROR, OK, SIMPLE_START, Raw, Raw3, extract_binary, host_arguments


def as_address(handle):
    """The handle itself, passed where the address of a handle is due (what fmusim v0.0.39 does)."""
    return ctypes.cast(handle, ctypes.POINTER(ctypes.c_void_p))


def started2(fmu, directory):
    raw = Raw(fmu, directory).instantiate()
    return raw.start(v0=20.0)


def test_fmi2_handles_are_looked_up_not_dereferenced(simple_fmu, tmp_path):
    a, b = started2(simple_fmu, tmp_path / "a"), started2(simple_fmu, tmp_path / "b")
    try:
        state, foreign = ctypes.c_void_p(), ctypes.c_void_p()
        assert a("GetFMUstate", ctypes.byref(state)) == OK and b("GetFMUstate", ctypes.byref(foreign)) == OK
        # the handle where its address is due (fmusim --final-fmu-state-file): refused, the handle still valid
        assert a("FreeFMUstate", as_address(state)) == ERROR
        assert a("SetFMUstate", state) == OK
        # the handle's address where the handle is due
        assert a("SetFMUstate", ctypes.addressof(state)) == ERROR
        wild = (ctypes.c_double * 16)()
        assert a("SetFMUstate", ctypes.addressof(wild)) == ERROR
        assert a("GetFMUstate", ctypes.byref(ctypes.c_void_p(ctypes.addressof(wild)))) == ERROR  # reuse: must be ours
        # another instance's handle
        assert a("SetFMUstate", foreign) == ERROR
        assert a("FreeFMUstate", ctypes.byref(ctypes.c_void_p(foreign.value))) == ERROR
        # freed, then freed again
        stale = ctypes.c_void_p(state.value)
        assert a("FreeFMUstate", ctypes.byref(state)) == OK and state.value is None
        assert a("SetFMUstate", stale) == ERROR
        assert a("FreeFMUstate", ctypes.byref(stale)) == ERROR
        # the size of a freed, a wild and a null handle: refused (with a message: Raw checks), size untouched
        size = ctypes.c_size_t(7)
        for handle in (stale, ctypes.addressof(wild), None):
            assert a("SerializedFMUstateSize", handle, ctypes.byref(size)) == ERROR and size.value == 7
        buffer = ctypes.create_string_buffer(1 << 12)
        assert a("SerializeFMUstate", stale, buffer, len(buffer)) == ERROR
        assert a("DoStep", 0.0, 0.01, 1) == OK  # every refusal left the instance usable
        assert b("FreeFMUstate", ctypes.byref(foreign)) == OK
    finally:
        a.free()
        b.free()


def test_fmi3_handles_are_looked_up_not_dereferenced(simple_fmus, tmp_path):
    a, b = Raw3(simple_fmus[3], tmp_path / "a"), Raw3(simple_fmus[3], tmp_path / "b")
    try:
        for raw in (a, b):
            assert raw("EnterInitializationMode", False, 0.0, 0.0, False, 0.0) == OK
            assert raw("ExitInitializationMode") == OK
        state, foreign = ctypes.c_void_p(), ctypes.c_void_p()
        assert a("GetFMUState", ctypes.byref(state)) == OK and b("GetFMUState", ctypes.byref(foreign)) == OK
        assert a("FreeFMUState", as_address(state)) == ERROR
        assert a("SetFMUState", state) == OK
        assert a("SetFMUState", ctypes.addressof(state)) == ERROR
        assert a("SetFMUState", foreign) == ERROR
        assert a("FreeFMUState", ctypes.byref(ctypes.c_void_p(foreign.value))) == ERROR
        stale = ctypes.c_void_p(state.value)
        assert a("FreeFMUState", ctypes.byref(state)) == OK and state.value is None
        assert a("SetFMUState", stale) == ERROR
        assert a("FreeFMUState", ctypes.byref(stale)) == ERROR
        data = bytes(8 * 64)
        assert a("DeserializeFMUState", data, len(data), ctypes.byref(stale)) == ERROR  # reuse: must be ours
        size = ctypes.c_size_t(7)  # a freed, a wild and a null handle's size: refused (with a message: Raw3 checks)
        for handle in (stale, ctypes.addressof(state), None):
            assert a("SerializedFMUStateSize", handle, ctypes.byref(size)) == ERROR and size.value == 7
        assert a.do_step(0.0, 0.01) == OK
        assert b("FreeFMUState", ctypes.byref(foreign)) == OK
    finally:
        a.free()
        b.free()


MISUSES = 6  # the misuses in misuse_states (tests/hosts/fmi_host.c)


@pytest.mark.parametrize("version", [2, 3], ids=["fmi2", "fmi3"])
def test_c_host_misusing_handles_as_fmusim_does(simple_fmus, c_host, tmp_path, version):
    fmu = simple_fmus[version]
    library = extract_binary(fmu, tmp_path, version, "so")
    arguments = host_arguments(fmu, library, SIMPLE_START, ("s",), 1.0)
    completed = subprocess.run([str(c_host), *map(str, arguments), "--misuse-states"], capture_output=True, text=True,
                               timeout=300)
    assert completed.returncode == 0, completed.stderr[-3000:]
    refused = [line for line in completed.stdout.splitlines() if line.startswith("MISUSE")]
    assert len(refused) == MISUSES, refused
    # each refusal was explained through the logger (status 3 = error)
    logged = [line for line in completed.stderr.splitlines() if "is not an FMU state of this instance" in line]
    assert len(logged) >= MISUSES, completed.stderr


@pytest.mark.slow  # rebuilds the FMU from its sources with the sanitizers
@pytest.mark.parametrize("version", [2, 3], ids=["fmi2", "fmi3"])
def test_c_host_misuse_is_clean_under_asan_and_ubsan(simple_fmus, c_host, tmp_path, version):
    """The same misuse against the FMU's own sources built with AddressSanitizer + UBSan (abort on the first
    finding, leaks included): no read through a freed or foreign handle, no double free, nothing leaked."""
    fmu = simple_fmus[version]
    extract_binary(fmu, tmp_path, version, "so")
    library = fuzz.sanitized_library(tmp_path, tmp_path / "sanitized.so")
    environment = {**fuzz.sanitizer_environment(), "ASAN_OPTIONS": "detect_leaks=1:abort_on_error=1"}
    arguments = host_arguments(fmu, library, SIMPLE_START, ("s",), 0.5)
    completed = subprocess.run([str(c_host), *map(str, arguments), "--misuse-states", "--repeat", "2"],
                               capture_output=True, text=True, timeout=600, env=environment)
    assert completed.returncode == 0, completed.stderr[-3000:]
    assert "Sanitizer" not in completed.stderr and "runtime error" not in completed.stderr
    assert sum(line.startswith("MISUSE") for line in completed.stdout.splitlines()) == 3 * MISUSES
