"""Hostile inputs built at test time: the hostile car (tests/vehicles/hostile_car.c, compiled with gcc, an FMI 2.0
co-simulation FMU that hangs, crashes, exits, outputs NaN, lies about its FMU state, logs garbage on demand) with
its model description and vehicle map, variants of both; the hostile controller (tests/controllers/hostile_aeb.c, an
AEB that does the same on demand) with its controller map; and the command line run under a memory cap.

    fmu = hostile_fmu(folder)                     # the honest description; keywords change it (a unit, the GUID, ...)
    car = hostile_map(folder, mode=2)             # its map; mode picks the misbehaviour (see hostile_car.c)
    completed = capped("run", "demo", "--fmu", fmu, "--vehicle", car)   # the real command line, capped
    aeb = hostile_controller(folder)              # the hostile controller, and its map (see hostile_aeb.c)
    completed = capped("run", "demo", "--controller", aeb, "--controller-map", hostile_controller_map(folder, "nan"))
"""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

from sdl_fmu.hold import HOLD_VARIABLE

SOURCE = Path(__file__).parent / "vehicles" / "hostile_car.c"
GUID = "{8c4e810f-3df3-4a00-8276-176fa3c9f000}"
IDENTIFIER = "HostileCar"
MEMORY_CAP = 1536 * 2**20  # bytes of address space for every command under test (1.5 GB)
HANG_LIMIT = 600  # s: only a hang takes this long; no test asserts on speed
MODES = {"honest": 0, "hang": 1, "crash": 2, "exit": 3, "nan": 4, "inf": 5, "huge": 6, "garbage_log": 7, "lie": 8,
         "no_init": 9}

VARIABLES = [  # name, causality, variability, start (None: an output)
    ("throttle", "input", "continuous", 0.0), ("brake", "input", "continuous", 0.0),
    ("steer", "input", "continuous", 0.0), ("x", "output", "continuous", None), ("y", "output", "continuous", None),
    ("yaw", "output", "continuous", None), ("speed", "output", "continuous", None),
    ("v_init", "parameter", "fixed", 20.0), ("mode", "parameter", "fixed", 0.0),
    ("trigger_time", "parameter", "fixed", 1.0)]


def library(folder: Path, source: Path = SOURCE, identifier: str = IDENTIFIER) -> Path:
    """The hostile car's shared library (or another source's), compiled once into `folder`."""
    from sdl_fmu.fmu.package import fmi_headers

    built = folder / f"{identifier}.so"
    if not built.exists():
        subprocess.run(["gcc", "-std=c99", "-O1", "-shared", "-fPIC", "-Wall", "-Wextra", "-Werror",
                        f"-I{fmi_headers()}", str(source), "-o", str(built), "-lm"], check=True)
    return built


def description(*, model_name: str = "Hostile car", guid: str = GUID, identifier: str = IDENTIFIER,
                can_get_set: bool = True, speed_unit: str | None = None, extra_variables: str = "",
                ranges: dict[str, tuple[float, float]] | None = None, names: dict[str, str] | None = None) -> str:
    """The model description; `ranges` declares min/max of variables by name, `names` renames variables."""
    from xml.sax.saxutils import quoteattr

    units = f" unit={quoteattr(speed_unit)}" if speed_unit is not None else ""
    variables = []
    for name, causality, variability, start in VARIABLES:
        attributes = f' start="{start!r}"' if start is not None else ""
        if ranges and name in ranges:
            attributes += f' min="{ranges[name][0]!r}" max="{ranges[name][1]!r}"'
        unit = units if name == "speed" else ""
        shown = quoteattr((names or {}).get(name, name))
        variables.append(f'    <ScalarVariable name={shown} valueReference="{len(variables)}" causality="{causality}" '
                         f'variability="{variability}"><Real{unit}{attributes}/></ScalarVariable>')
    outputs = "".join(f'<Unknown index="{i + 1}"/>' for i, v in enumerate(VARIABLES) if v[1] == "output")
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName={quoteattr(model_name)} guid="{guid}" generationTool="tests/hostile_fmus.py"
  numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="{identifier}" canGetAndSetFMUstate="{str(can_get_set).lower()}"
    canHandleVariableCommunicationStepSize="true"/>
  <ModelVariables>
{chr(10).join(variables)}
{extra_variables}  </ModelVariables>
  <ModelStructure><Outputs>{outputs}</Outputs></ModelStructure>
</fmiModelDescription>
"""


def hostile_fmu(folder: Path, name: str = "HostileCar", *, members: dict[str, bytes] | None = None,
                **description_options) -> Path:
    """The hostile car as an FMU `folder/name.fmu`: its binary under binaries/linux64/<identifier>.so (or the members
    given instead) and the model description (keywords of `description`)."""
    folder.mkdir(parents=True, exist_ok=True)
    binary = library(folder).read_bytes()
    identifier = description_options.get("identifier", IDENTIFIER)
    if members is None:
        members = {f"binaries/linux64/{identifier}.so": binary}
    path = folder / f"{name}.fmu"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as fmu:
        fmu.writestr("modelDescription.xml", description(**description_options))
        for member, data in members.items():
            fmu.writestr(member, data)
    return path


def hostile_map(folder: Path, mode: str | int = "honest", trigger_time: float = 1.0, *, name: str = "hostile",
                vehicle: str | None = None, extra: str = "", speed: str = 'variable = "speed"',
                parameters: str | None = None) -> Path:
    """A vehicle map driving the hostile car; `mode` (a name of MODES or a number) starts at `trigger_time` (s).
    `vehicle` replaces the [vehicle] table's body, `parameters` the [parameters] table's, `extra` is the top level."""
    mode = MODES.get(mode, mode)
    vehicle = vehicle if vehicle is not None else "length = 4.5\nwidth = 1.8\nwheelbase = 2.7\ntrack = 1.5\n"
    text = f"""{extra}
[inputs]
throttle = {{ variable = "throttle" }}
brake = {{ variable = "brake" }}
steer = {{ variable = "steer" }}

[outputs]
x = {{ variable = "x" }}
y = {{ variable = "y" }}
yaw = {{ variable = "yaw" }}
speed = {{ {speed} }}

[start]
speed = {{ variable = "v_init" }}

[vehicle]
{vehicle}
[parameters]
{parameters if parameters is not None else f"mode = {float(mode)!r}{chr(10)}trigger_time = {float(trigger_time)!r}"}
"""
    path = folder / f"{name}.toml"
    folder.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


CONTROLLER_SOURCE = Path(__file__).parent / "controllers" / "hostile_aeb.c"
CONTROLLER_GUID = "{5d1e7f3a-4b2c-4e8d-9a61-0c3f2b7e4a10}"
CONTROLLER_IDENTIFIER = "HostileAeb"
CONTROLLER_MODES = {"honest": 0, "hang": 1, "crash": 2, "exit": 3, "nan": 4, "inf": 5, "lie": 6, "huge": 7}
CONTROLLER_VARIABLES = [  # name, causality, variability, start (None: an output); SI, no units declared
    ("ttc", "input", "continuous", 1000.0), ("brake", "output", "discrete", None),
    ("mode", "parameter", "fixed", 0.0), ("trigger_time", "parameter", "fixed", 1.0),
    ("ttc_trigger", "parameter", "fixed", 1.0)]


def hostile_controller(folder: Path, name: str = "HostileAeb") -> Path:
    """The hostile controller as an FMU `folder/name.fmu` (FMI 2.0 co-simulation; its XML declares
    canGetAndSetFMUstate, which mode 6 of hostile_aeb.c lies about)."""
    folder.mkdir(parents=True, exist_ok=True)
    binary = library(folder, CONTROLLER_SOURCE, CONTROLLER_IDENTIFIER).read_bytes()
    variables = []
    for index, (variable, causality, variability, start) in enumerate(CONTROLLER_VARIABLES):
        attributes = f' start="{start!r}"' if start is not None else ""
        initial = ' initial="exact"' if causality == "output" else ""
        start_value = ' start="0.0"' if causality == "output" else attributes
        variables.append(f'    <ScalarVariable name="{variable}" valueReference="{index}" causality="{causality}" '
                         f'variability="{variability}"{initial}><Real{start_value}/></ScalarVariable>')
    outputs = "".join(f'<Unknown index="{i + 1}"/>' for i, v in enumerate(CONTROLLER_VARIABLES) if v[1] == "output")
    xml = f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="Hostile AEB" guid="{CONTROLLER_GUID}"
  generationTool="tests/hostile_fmus.py" numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="{CONTROLLER_IDENTIFIER}" canGetAndSetFMUstate="true"
    canHandleVariableCommunicationStepSize="true"/>
  <ModelVariables>
{chr(10).join(variables)}
  </ModelVariables>
  <ModelStructure><Outputs>{outputs}</Outputs></ModelStructure>
</fmiModelDescription>
"""
    path = folder / f"{name}.fmu"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as fmu:
        fmu.writestr("modelDescription.xml", xml)
        fmu.writestr(f"binaries/linux64/{CONTROLLER_IDENTIFIER}.so", binary)
    return path


def hostile_controller_map(folder: Path, mode: str | int = "honest", trigger_time: float = 1.0,
                           ttc_trigger: float = 1.0, *, name: str = "hostile-aeb", period: float = 0.01) -> Path:
    """A controller map of the hostile controller: the lead TTC in, a brake request out (rule max); `mode` (a name
    of CONTROLLER_MODES or a number) starts at `trigger_time` (s)."""
    mode = CONTROLLER_MODES.get(mode, mode)
    text = f"""period = {period!r}

[inputs]
lead_ttc = {{ variable = "ttc" }}

[outputs]
brake = {{ variable = "brake" }}

[arbitration]
brake = "max"

[parameters]
mode = {float(mode)!r}
trigger_time = {float(trigger_time)!r}
ttc_trigger = {float(ttc_trigger)!r}
"""
    path = folder / f"{name}.toml"
    folder.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


def _capped() -> None:
    """In the child before exec: the memory cap, and Ctrl-C's default action (a background test run may start the
    child with SIGINT ignored)."""
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_CAP, MEMORY_CAP))
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def capped_command(*args) -> list[str]:
    return [sys.executable, "-m", "sdl_fmu.cli", *map(str, args)]


def capped(*args, cwd=None, env=None, timeout: float = HANG_LIMIT, **options) -> subprocess.CompletedProcess:
    """`sdl-fmu ARGS` as a user runs it, in a subprocess with at most MEMORY_CAP of address space; `timeout` only
    catches a hang."""
    environment = {**os.environ, "OPENBLAS_NUM_THREADS": "1", **(env or {})}
    return subprocess.run(capped_command(*args), capture_output=True, text=True, cwd=cwd, env=environment,
                          timeout=timeout, preexec_fn=_capped, **options)


def popen_capped(*args, cwd=None, env=None, **options) -> subprocess.Popen:
    """capped() started in the background (for signals)."""
    environment = {**os.environ, "OPENBLAS_NUM_THREADS": "1", **(env or {})}
    return subprocess.Popen(capped_command(*args), cwd=cwd, env=environment, preexec_fn=_capped,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **options)


def one_line(completed: subprocess.CompletedProcess, code: int, *needles: str) -> str:
    """The command ended with `code` and one line on stderr holding every needle, no traceback; that line."""
    lines = completed.stderr.splitlines()
    assert completed.returncode == code and len(lines) == 1, (completed.returncode, completed.stderr[-3000:])
    assert "Traceback" not in completed.stderr
    assert all(needle in lines[0] for needle in needles), lines[0]
    return lines[0]


# ---- the tests' surroundings: a private $TMPDIR, the processes a test started, a hang to wait for -------------


def environment(work, **extra) -> dict:
    return {"TMPDIR": str(work / "tmp"), "SDL_FMU_TEST_MARK": str(work), **extra}


def hosts_of(work) -> list[int]:
    """Processes started for this test (its mark in their environment) that are still there."""
    found = []
    mark = f"SDL_FMU_TEST_MARK={work}".encode()
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                if mark in (entry / "environ").read_bytes().split(b"\0"):
                    found.append(int(entry.name))
            except OSError:
                continue
    return found


def assert_clean(work) -> None:
    """$TMPDIR empty (the unpacked FMUs gone) and no process of this test left (a host reaped)."""
    left = sorted(os.listdir(work / "tmp"))
    assert left == [], f"the unpacked FMU (or a host's file) was left in $TMPDIR: {left}"
    deadline = time.monotonic() + HANG_LIMIT  # a killed host is reaped by its parent before it exits
    while hosts_of(work):
        assert time.monotonic() < deadline, f"processes left: {hosts_of(work)}"
        time.sleep(0.05)


# ---- a command caught at a hold point of the test hook (sdl_fmu/hold.py) and interrupted there ----------------


def held_work(tmp_path: Path) -> Path:
    """`interrupted`'s folder: tmp/ (a private, empty $TMPDIR), work/ (the command's working folder), the hold file."""
    for name in ("tmp", "work"):
        (tmp_path / name).mkdir()
    (tmp_path / "hold").touch()
    return tmp_path


def interrupted(work, command: list, how: str, ready=None, **extra_env) -> tuple[int, str, str]:
    """Starts the command, waits until it is held (and `ready()`, when given, says so too), signals it as `how` says,
    releases the hold once the command has acted on the signal and returns (exit code, stdout, stderr)."""
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", **environment(work, **extra_env),
           HOLD_VARIABLE: str(work / "hold")}
    line = [str(arg) for arg in capped_command(*command)]
    if how == "sigterm":
        line = ["timeout", str(HANG_LIMIT)] + line
    process = subprocess.Popen(line, cwd=work / "work", env=env, preexec_fn=_capped, start_new_session=True,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        running = work / "hold.running"
        deadline = time.monotonic() + HANG_LIMIT  # only against a hang: the loops end when the command is held
        while not (running.exists() and running.read_text().endswith("\n") and (ready is None or ready())):
            assert process.poll() is None, process.communicate()
            assert time.monotonic() < deadline, "the command was never held"
            time.sleep(0.02)
        if how == "ctrl-c":
            os.killpg(process.pid, signal.SIGINT)  # the terminal's Ctrl-C: the whole foreground process group
            main = process.pid
        else:
            process.send_signal(signal.SIGTERM)  # to `timeout`, which relays it
            main = int(Path(f"/proc/{process.pid}/task/{process.pid}/children").read_text().split()[0])
        # released only once sdl-fmu's own process has acted on the signal (`timeout` relays it when it is next
        # scheduled: a hold released before could let a short command finish first); what reaches a hold point
        # later (a compiler started while the build winds down, another run on a worker) goes on as without the hook
        while not acted_on_signal(main):
            assert time.monotonic() < deadline, "the command never acted on the signal"
            time.sleep(0.02)
        (work / "hold").unlink()
        stdout, stderr = process.communicate(timeout=HANG_LIMIT)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    return process.returncode, stdout, stderr


def acted_on_signal(pid: int) -> bool:
    """Whether sdl-fmu's process has acted on a Ctrl-C or SIGTERM: it then ignores both (a repeat while it cleans up,
    cli._stop), which its status shows; or it has ended."""
    try:
        status = dict(line.split(":", 1) for line in Path(f"/proc/{pid}/status").read_text().splitlines())
    except FileNotFoundError:
        return True
    ignored = int(status["SigIgn"], 16)
    both = (1 << (signal.SIGINT - 1)) | (1 << (signal.SIGTERM - 1))
    return status["State"].split()[0] in ("Z", "X") or ignored & both == both


def wait_for(path: Path, process) -> None:
    deadline = time.monotonic() + HANG_LIMIT  # only against a hang: the loop ends when the FMU says it hangs
    while not path.exists():
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline, "the FMU never reached its hang"
        time.sleep(0.02)
