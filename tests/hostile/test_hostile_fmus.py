"""A foreign FMU cannot take sdl-fmu down silently (sdl_fmu/vehicle/isolated.py, unpack.py, fmu_log.py).

The hostile car (tests/vehicles/hostile_car.c, compiled here) hangs, crashes, exits, outputs NaN, lies about its
FMU state or logs garbage on demand; its description is varied for a wrong GUID, a modelIdentifier that is a path,
member names that escape, a huge declared size. Every case runs the real command line under a 1.5 GB address-space
cap (tests/hostile_fmus.py), with a private $TMPDIR that must be empty afterwards (the unpacked FMU is removed on
every path) and no host process left. Timeouts only catch hangs; a signal is sent when the FMU says it hangs (it
creates a file), never after a guessed time."""

import os
import shutil
import signal
import subprocess
import time
import zipfile
from pathlib import Path

import pytest

from hostile_fmus import (GUID, HANG_LIMIT, IDENTIFIER, assert_clean, capped, environment, hostile_fmu, hostile_map,
                          hosts_of, library, one_line, popen_capped, wait_for)

SCENARIO = "English\n300,BRK,100,1,50\n600,ES\n"
SLOW = pytest.mark.slow  # the fast loop keeps a crash and a hang under Ctrl-C; the rest runs in CI  # a BRK whose threshold is bisected: FMU states saved and restored


@pytest.fixture(scope="module")
def car(tmp_path_factory):
    """(folder, FMU, scenario): the hostile car built once, an honest description."""
    folder = tmp_path_factory.mktemp("hostile")
    library(folder)
    scenario = folder / "brake.sdl"
    scenario.write_text(SCENARIO)
    return folder, hostile_fmu(folder), scenario


@pytest.fixture
def work(tmp_path):
    """A working folder and a private, empty $TMPDIR (checked empty at the end)."""
    (tmp_path / "tmp").mkdir()
    (tmp_path / "work").mkdir()
    return tmp_path


def run(car, work, mode, *more, **map_options):
    folder, fmu, scenario = car
    vehicle = hostile_map(work, mode, **map_options)
    return capped("run", scenario, "--fmu", fmu, "--vehicle", vehicle, "--out", work / "work" / "out", *more,
                  cwd=work / "work", env=environment(work))


@pytest.mark.parametrize("mode, needle", [
    ("crash", "it crashed (SIGSEGV) in fmi2DoStep from t = 1.000000 s to "),
    pytest.param("exit", "its process ended (exit status 0) in fmi2DoStep from t = 1.000000 s to ", marks=SLOW),
    pytest.param("nan", "its output 'x' (x) is nan at t = 1.000000 s: not a finite number", marks=SLOW),
    pytest.param("inf", "its output 'x' (x) is inf at t = 1.000000 s: not a finite number", marks=SLOW),
    pytest.param("huge", "its output 'x' (x) is 1e+308 at t = 1.000000 s: beyond 1e+09 in SI units", marks=SLOW),
])
def test_a_crash_an_exit_or_a_non_finite_output_ends_the_run_in_one_line(car, work, mode, needle):
    completed = run(car, work, mode)
    one_line(completed, 2, "sdl-fmu: the FMU HostileCar.fmu failed: ", needle)
    assert completed.stdout == "" and os.listdir(work / "work") == []  # nothing written
    assert_clean(work)


@SLOW
def test_an_honest_foreign_fmu_runs_out_of_process_and_leaves_nothing_behind(car, work):
    completed = run(car, work, "honest")
    assert completed.returncode == 0, completed.stderr
    assert sorted(os.listdir(work / "work" / "out")) == [".sdl-fmu-results.json", "plot.png", "summary.json",
                                                         "timeseries.csv"]
    assert_clean(work)


@SLOW
def test_a_capability_lie_is_caught_by_the_state_round_trip(car, work):
    """canGetAndSetFMUstate declared, fmi2SetFMUstate answers OK and restores nothing: the first restore finds outputs
    other than those saved (the BRK threshold is bisected on saved states)."""
    completed = run(car, work, "lie", trigger_time=0.0)
    one_line(completed, 2, "sdl-fmu: the FMU HostileCar.fmu failed: it declares canGetAndSetFMUstate, but "
                           "fmi2SetFMUstate did not restore its state of t = ")
    assert_clean(work)


@pytest.mark.parametrize("how, verb", [("ctrl-c", "run"), pytest.param("timeout", "run", marks=SLOW),
                                       pytest.param("ctrl-c", "verify", marks=SLOW),
                                       pytest.param("timeout", "verify", marks=SLOW)])
def test_a_hang_in_do_step_is_ended_by_ctrl_c_and_by_timeout(car, work, how, verb):
    folder, fmu, scenario = car
    vehicle = hostile_map(work, "hang")
    hanging = work / "hanging"
    command = ([verb, scenario] if verb == "run" else [verb, "--only", "braking"]) + [
        "--fmu", fmu, "--vehicle", vehicle, "--out", work / "work" / "out"]
    env = environment(work, HOSTILE_HANG_FILE=str(hanging))
    if how == "ctrl-c":
        process = popen_capped(*command, cwd=work / "work", env=env)
    else:  # coreutils timeout relays the SIGTERM it gets to the command and its process group, as on expiry
        from hostile_fmus import capped_command, _capped

        process = subprocess.Popen(["timeout", str(HANG_LIMIT), *map(str, capped_command(*command))],
                                   cwd=work / "work", env={**os.environ, **env}, preexec_fn=_capped,
                                   stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        wait_for(hanging, process)
        process.send_signal(signal.SIGINT if how == "ctrl-c" else signal.SIGTERM)
        stdout, stderr = process.communicate(timeout=HANG_LIMIT)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    expected = {"ctrl-c": (130, "sdl-fmu: interrupted (Ctrl-C); nothing was written"),
                "timeout": (143, "sdl-fmu: terminated (SIGTERM); nothing was written")}[how]
    assert (process.returncode, stderr.splitlines()) == (expected[0], [expected[1]]), stderr
    assert stdout == "" and os.listdir(work / "work") == []
    assert_clean(work)


@SLOW
def test_the_api_timeout_ends_a_hang_inside_a_step(car, work):
    """api.run(timeout=) (the sweep's per-run limit) stops waiting for a hung FMU mid-step, not only between steps."""
    folder, fmu, scenario = car
    code = ("import sys; from sdl_fmu import api\n"
            "try:\n"
            f"    api.run({str(scenario)!r}, fmu={str(fmu)!r}, vehicle={str(hostile_map(work, 'hang'))!r}, timeout=2)\n"
            "except api.RunTimeout as error:\n"
            "    print(error)\n")
    completed = subprocess.run([os.sys.executable, "-c", code], capture_output=True, text=True, timeout=HANG_LIMIT,
                               env={**os.environ, **environment(work)}, cwd=work / "work")
    assert completed.returncode == 0, completed.stderr
    assert completed.stdout.startswith("the run exceeded its time limit of 2 s (wall clock): the FMU HostileCar.fmu "
                                       "did not answer in fmi2DoStep from t = 1.000000 s to ")
    assert_clean(work)


@SLOW
def test_a_killed_sdl_fmu_takes_its_hung_host_along_and_the_next_run_removes_its_unpacked_fmu(car, work):
    folder, fmu, scenario = car
    hanging = work / "hanging"
    process = popen_capped("run", scenario, "--fmu", fmu, "--vehicle", hostile_map(work, "hang"), "--out",
                           work / "work" / "out", cwd=work / "work",
                           env=environment(work, HOSTILE_HANG_FILE=str(hanging)))
    try:
        wait_for(hanging, process)
        assert len(os.listdir(work / "tmp")) == 1
        process.kill()  # SIGKILL: no clean-up of its own
        process.wait(timeout=HANG_LIMIT)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    deadline = time.monotonic() + HANG_LIMIT
    while hosts_of(work):  # the host dies with its parent (PR_SET_PDEATHSIG)
        assert time.monotonic() < deadline, "the hung host outlived sdl-fmu"
        time.sleep(0.05)
    assert len(os.listdir(work / "tmp")) == 1  # what SIGKILL left
    completed = run(car, work, "honest")
    assert completed.returncode == 0, completed.stderr
    assert_clean(work)


@SLOW
def test_an_fmu_that_fails_to_initialise_is_one_line_for_run_verify_and_sweep(car, work):
    folder, fmu, scenario = car
    vehicle = hostile_map(work, "no_init")
    for command in (["run", scenario, "--out", work / "work" / "out"], ["verify", "--out", work / "work" / "out"],
                    ["sweep", scenario, "--vary", "speed=40,50", "--workers", "1", "--out", work / "work" / "out"]):
        completed = capped(*command, "--fmu", fmu, "--vehicle", vehicle, cwd=work / "work", env=environment(work))
        lines = completed.stderr.splitlines()  # the FMU's own log line, then sdl-fmu's
        assert completed.returncode == 2 and len(lines) == 2, completed.stderr
        assert lines[0] == "HostileCar.fmu: [Error] logAll: cannot initialise: the engine is missing"
        assert "HostileCar.fmu" in lines[1] and "could not be initialised: fmi2ExitInitializationMode failed" in lines[1]
        assert os.listdir(work / "work") == []
    assert_clean(work)


@SLOW
def test_instantiation_failures_are_one_line_for_run_verify_and_sweep(car, work):
    """A GUID the binary does not know: fmi2Instantiate returns NULL. run, verify and sweep refuse the FMU before
    anything runs (the sweep does not start its runs)."""
    folder, fmu, scenario = car
    wrong = hostile_fmu(work / "wrong", guid="{00000000-0000-0000-0000-000000000000}")
    vehicle = hostile_map(work, "honest")
    needle = "fmi2Instantiate returned NULL (its GUID or instantiation token"
    for command in (["run", scenario, "--out", work / "work" / "out"], ["verify", "--out", work / "work" / "out"],
                    ["sweep", scenario, "--vary", "speed=40,50", "--workers", "1", "--out", work / "work" / "out"]):
        completed = capped(*command, "--fmu", wrong, "--vehicle", vehicle, cwd=work / "work", env=environment(work))
        one_line(completed, 2, "HostileCar.fmu", needle)
        assert os.listdir(work / "work") == []
    assert_clean(work)


@SLOW
@pytest.mark.parametrize("variant, needle", [
    ("identifier", "modelIdentifier '../../../tmp/Evil' is not a C identifier"),
    ("absolute", "the member name '/tmp/evil.so' has an absolute path"),
    ("backslash", "the member name 'binaries\\\\linux64\\\\..\\\\..\\\\evil.so' has a backslash"),
    ("dotdot", "the member name 'resources/../../evil.so' has a '..' part"),
    ("size", "unpacks to 4096 MB, more than the 1024 MB an FMU may take here"),
])
def test_an_archive_that_could_escape_or_exhaust_is_refused_before_anything_is_unpacked(car, work, variant, needle):
    folder, fmu, scenario = car
    binary = (folder / f"{IDENTIFIER}.so").read_bytes()
    members = {f"binaries/linux64/{IDENTIFIER}.so": binary}
    options = {}
    if variant == "identifier":
        options["identifier"] = "../../../tmp/Evil"
    elif variant == "absolute":
        members["/tmp/evil.so"] = b"x"
    elif variant == "backslash":
        members["binaries\\linux64\\..\\..\\evil.so"] = b"x"
    elif variant == "dotdot":
        members["resources/../../evil.so"] = b"x"
    path = hostile_fmu(work / variant, members=members, **options)
    if variant == "size":  # a member that declares 4 GiB (the archive lies; nothing that big is ever written)
        path = declared_size(path, f"binaries/linux64/{IDENTIFIER}.so", 4 << 30)
    commands = [["run", scenario, "--out", work / "work" / "out"]]
    if variant == "absolute":  # verify reads the FMU the same way: once is enough to show it
        commands.append(["verify", "--out", work / "work" / "out"])
    for command in commands:
        completed = capped(*command, "--fmu", path, "--vehicle", hostile_map(work, "honest"), cwd=work / "work",
                           env=environment(work))
        one_line(completed, 2, f"sdl-fmu: --fmu {path}: ", needle)
    assert os.listdir(work / "work") == []
    assert_clean(work)


def declared_size(fmu: Path, member: str, size: int) -> Path:
    """The FMU with `member`'s uncompressed size declared as `size`: its central directory entry says 0xFFFFFFFF and
    a zip64 extra field gives the size (a 2 MB archive can declare gigabytes)."""
    import struct

    data = bytearray(fmu.read_bytes())
    name, offset = member.encode(), 0
    while True:  # the member's central directory entry
        offset = data.find(b"PK\x01\x02", offset)
        assert offset >= 0, member
        name_length, extra_length, comment_length = struct.unpack_from("<HHH", data, offset + 28)
        if bytes(data[offset + 46:offset + 46 + name_length]) == name:
            break
        offset += 46 + name_length + extra_length + comment_length
    extra = struct.pack("<HHQ", 1, 8, size)
    struct.pack_into("<I", data, offset + 24, 0xFFFFFFFF)
    struct.pack_into("<H", data, offset + 30, extra_length + len(extra))
    end = offset + 46 + name_length + extra_length
    data[end:end] = extra
    eocd = data.rfind(b"PK\x05\x06")  # the end record: the central directory grew
    struct.pack_into("<I", data, eocd + 12, struct.unpack_from("<I", data, eocd + 12)[0] + len(extra))
    fmu.write_bytes(bytes(data))
    with zipfile.ZipFile(fmu) as archive:
        assert archive.getinfo(member).file_size == size
    return fmu


@SLOW
def test_the_fmu_is_unpacked_once_per_process(car, work):
    """The vehicle test pack instantiates the FMU for every manoeuvre (and the probe before): one unpack folder for
    all of them, gone at the end."""
    folder, fmu, scenario = car
    instances = work / "instances"
    completed = capped("verify", "--fmu", fmu, "--vehicle", hostile_map(work, "honest"), "--out",
                       work / "work" / "out", cwd=work / "work",
                       env=environment(work, HOSTILE_INSTANCES_FILE=str(instances)))
    assert completed.returncode == 0, completed.stderr
    locations = instances.read_text().splitlines()
    assert len(locations) > 6 and len(set(locations)) == 1, locations
    assert locations[0].startswith((work / "tmp").as_uri())
    assert_clean(work)


@SLOW
def test_a_full_disk_during_the_unpack_leaves_nothing(car, work):
    """$TMPDIR on a 1 MB tmpfs (a private mount namespace: nothing of the machine is touched) and an FMU whose binary
    needs more: one line naming the FMU and the full disk, and the partial unpack is gone."""
    if shutil.which("unshare") is None or subprocess.run(["unshare", "--user", "--map-root-user", "--mount", "true"],
                                                          capture_output=True).returncode != 0:
        pytest.skip("unshare cannot make a private mount namespace here")
    folder, fmu, scenario = car
    big = hostile_fmu(work / "big", members={f"binaries/linux64/{IDENTIFIER}.so": (folder / f"{IDENTIFIER}.so")
                                             .read_bytes(), "resources/padding.bin": os.urandom(3 << 20)})
    small = work / "small"
    small.mkdir()
    from hostile_fmus import capped_command

    inner = " ".join(f"'{arg}'" for arg in capped_command("run", scenario, "--fmu", big, "--vehicle",
                                                          hostile_map(work, "honest"), "--out", work / "work" / "out"))
    script = (f"mount -t tmpfs -o size=1m tmpfs '{small}' && TMPDIR='{small}' {inner}; code=$?; "
              f"ls -A '{small}' >&2; exit $code")
    from hostile_fmus import _capped

    completed = subprocess.run(["unshare", "--user", "--map-root-user", "--mount", "sh", "-c", script],
                               capture_output=True, text=True, cwd=work / "work", timeout=HANG_LIMIT,
                               preexec_fn=_capped, env={**os.environ, **environment(work)})
    one_line(completed, 2, "sdl-fmu: the FMU HostileCar.fmu failed: ",
             f"{big}: cannot be unpacked into {small}: No space left on device")  # and `ls -A` of the tmpfs: empty
    assert os.listdir(work / "work") == []


@SLOW
def test_fmu_log_lines_go_to_stderr_decoded_leniently_escaped_and_bounded(car, work):
    completed = run(car, work, "garbage_log")
    assert completed.returncode == 0, completed.stderr[-2000:]
    assert "Traceback" not in completed.stderr and "Exception ignored" not in completed.stderr
    assert "[OK]" not in completed.stdout and "step" not in completed.stdout  # nothing of the FMU's on stdout
    logged = [line for line in completed.stderr.splitlines() if line.startswith("HostileCar.fmu: ")]
    assert len(logged) == 101 and logged[-1].endswith("further log messages of the FMU are not shown (at most 100)")
    assert logged[0] == ("HostileCar.fmu: [OK] logAll: step \ufffd\ufffd\ufffd( not UTF-8 \\x1b[2J\\x1b[31m red "
                         "\\x07 bell")
    assert "\x1b" not in completed.stderr and "\x07" not in completed.stderr
    assert_clean(work)


@SLOW
def test_isolation_changes_no_result(simple_fmu, work):
    """The shipped FMU in its host process (SDL_FMU_ISOLATION=always) gives byte-identical results to the same FMU in
    sdl-fmu's process: the requests carry every call, in the same order."""
    outputs = []
    for isolation in ("auto", "always"):
        out = work / "work" / isolation
        completed = capped("run", "demo", "--fmu", simple_fmu, "--out", out, cwd=work / "work",
                           env=environment(work, SDL_FMU_ISOLATION=isolation))
        assert completed.returncode == 0, completed.stderr
        outputs.append((out / "timeseries.csv").read_bytes())
    assert outputs[0] == outputs[1]
    assert_clean(work)
