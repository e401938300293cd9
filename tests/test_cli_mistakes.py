"""No user mistake shows a traceback: a generated set of bad invocations and inputs, driven through the real command
line in-process (sdl_fmu.cli.main), plus Ctrl-C on a real subprocess.

Every case must: raise nothing, exit 1 (the scenario file) or 2 (anything else), print one line per
problem on stderr, each naming the file (and line) or the option, print nothing on stdout, and leave
the working folder exactly as it was (the default results folder runs/ would appear there)."""

import os
import shutil
import zipfile
from pathlib import Path

import pytest

from sdl_fmu.cli import main
from sdl_fmu.results.folder import MANIFEST_NAME
from sdl_fmu.tire_files import DEFAULT_ATTRIBUTE_FILE

from helpers import sdl_fmu
from hostile_fmus import held_work, interrupted

GOOD = "English\n100,BRK,100,1,50\n200,ES\n"
DRY_TIRE = DEFAULT_ATTRIBUTE_FILE.parent / "dry_asphalt.tir"


def _case(argv, code, needle, lines=1, id=None):
    return pytest.param(argv, code, needle, lines, id=id or " ".join(argv)[:90])


# --- numeric options: NaN, inf, negative, zero, huge, not numbers -------------------------------------
NUMERIC = {
    "--speed": ["nan", "NaN", "inf", "-inf", "-1", "-0.001", "493", "1e308", "1e400", "1e", "x", "", "0x10"],
    "--step": ["nan", "inf", "-inf", "-1", "0", "1e-9", "10.5", "1e308", "x", ""],
    "--until-distance": ["nan", "inf", "-inf", "-1", "0", "1e10", "1e308", "x", ""],
    "--until-time": ["nan", "inf", "-inf", "-1", "0", "3600.5", "1e308", "x", ""],
    "--seed": ["nan", "inf", "-1", str(2**64), "1e3", "1.5", "x", ""],
}
CASES = [_case(["run", "{good}", option, value, "--fmu", "{fmu}"], 2, option)
         for option, values in NUMERIC.items() for value in values]
CASES += [_case(["run", "{metric}", "--speed", value, "--fmu", "{fmu}"], 2, "--speed", id=f"metric speed {value}")
          for value in ("151", "-5", "nan")]

# --- --param: syntax, unknown names, non-parameters, and every range the FMU declares -----------------
PARAM_SIMPLE = ["mass", "=1", "mass=", "mass=abc", "mass=1=2", "no_such=1", "x=1", "throttle=0.5", "stopped=1",
                "mass=nan", "mass=inf", "mass=-inf", "mass=0", "mass=-1500", "mass=0.5", "wheelbase=0",
                "wheelbase=-2.7", "wheelbase=nan", "wheelbase=0.05", "brake_decel_max=-9.81", "brake_decel_max=-inf",
                "drag_area=-0.1", "air_density=-1", "rolling_resistance=-0.01", "length=-1", "width=-1",
                "solver_step=0", "solver_step=1e-9", "v0=-1", "drive_power_max=-1", "drive_accel_max=-4"]
CASES += [_case(["run", "{good}", "--param", value, "--fmu", "{fmu}"], 2, "--param") for value in PARAM_SIMPLE]
PARAM_ADVANCED = ["brake_front_share=1.5", "brake_front_share=-0.1", "brake_front_share=1e308",
                  "roll_stiffness_front_share=2", "drive_front_share=-1", "cg_to_front_axle=0", "wheel_radius=0",
                  "yaw_inertia=0", "wheel_inertia=0", "track_front=0", "load_transfer_time_constant=0", "mass=0",
                  "mu_fl=0.5", "surface_fl=1", "tire0_LMUX=-1", "tire7_LYKA=-0.5", "tire3_PDX1=nan"]
CASES += [_case(["run", "{good}", "--dynamics", "advanced", "--param", value, "--fmu", "{advanced_fmu}"], 2,
                "--param") for value in PARAM_ADVANCED]

# --- commands and options that do not exist or lack their value ---------------------------------------
CASES += [_case(argv, 2, needle) for argv, needle in [
    ([], "command"), (["frobnicate"], "frobnicate"), (["--bogus"], "command"), (["run"], "scenario"),
    (["run", "{good}", "--bogus"], "--bogus"), (["run", "{good}", "--speed"], "--speed"),
    (["run", "{good}", "--dynamics", "turbo"], "--dynamics"), (["run", "{good}", "--dynamics"], "--dynamics"),
    (["run", "{good}", "--out"], "--out"), (["run", "{good}", "--param"], "--param"),
    (["run", "{good}", "--fmu"], "--fmu"), (["run", "{good}", "--tires"], "--tires"),
    (["run", "{good}", "extra"], "extra"), (["check"], "scenario"), (["check", "{good}", "{good}"], "unrecognized"),
    (["check", "{good}", "--dynamics", "turbo"], "--dynamics"), (["verify", "--fmu"], "--fmu"),
    (["verify", "extra"], "extra"), (["build", "--fmi-version", "4"], "--fmi-version"),
    (["build", "--fmi-version", "x"], "--fmi-version"), (["build", "--dynamics", "x"], "--dynamics"),
    (["build", "--out"], "--out"), (["run", "{good}", "--tires", "{ws}/tires/attributes.txt", "--fmu", "{fmu}"],
                                     "--tires"),
]]

# --- scenario files that are not SDL text, or not readable -------------------------------------------
BAD_FILES = {
    "missing.sdl": None, "folder": "dir", "/dev/zero": "special", "/dev/null": "special",
    "binary.sdl": b"\x7fELF\x02\x01\x01\x00" + bytes(range(256)) * 4, "huge.sdl": "huge",
    "utf16_no_bom.sdl": GOOD.encode("utf-16-le"), "bad_utf16.sdl": b"\xff\xfe" + "1".encode("utf-16-le") + b"\x00\xd8",
    "undefined_cp1252.sdl": b"English\n// \x81\n10,ES\n", "ctrl_z_inside.sdl": b"English\n10,ES\x1a\n20,ES\n",
    "plot.png": b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR",
}
for name in BAD_FILES:
    for command in (["check"], ["run"]):
        path = name if name.startswith("/") else "{ws}/" + name
        CASES.append(_case([*command, path], 1, path, id=f"{command[0]} file {name}"))

# --- one bad line each (line 2, after a comment): every check of the parser ---------------------------
BAD_LINES = [
    "x,BRK,50,0,1", "-10,BRK,50,0,1", "1e400,BRK,50,0,1", "nan,BRK,50,0,1", "10,XYZ,1", "10,,1", "10,1.5,1",
    "10,BRK,50,0", "10,BRK,150,0,1", "10,BRK,-1,0,1", "10,BRK,50,4,1", "10,BRK,50,1.5,1", "10,BRK,50,0,0",
    "10,BRK,50,0,x", "10,BRK,50,0,inf", "10,RSA", "10,RSA,1,8,2", "10,RSA,1.5,8", "10,RSA,1,8,1,2",
    "10,RSA,1,-2", "10,RSA,1,nan", "0,A,20,100,-6", "0,A,20,100,-6,1,10", "0,A,fast,100,-6,1",
    "0,A,20,0,-6,1", "0,A,20,100,-6,0", "0,A,20,100,-6,*8~1", "0,A,20,100,-6,*0~3", "0,A,20,100,-6,99",
    "0,A,20,100,-6,*1~99", "0,A,20,100,-6,1,0,-6,20,1", "0,A,20,100,-6,1,5,-6,20,-1", "0,A,20,100,*,1",
    "0,A,20,*100,-6,1", "10,ROAD,12,2,1", "0,ROAD,0,2,1", "0,ROAD,12,0,0", "0,ROAD,12,2,3", "0,ROAD,12,2",
    "10,ES,1", "Metric units", "just words", "10",
    # format limits, ASCII digits, and what real STISIM files hold (errors without --skip-unsupported)
    "10,BRK,\uff15\uff10,0,1", "3280840,ES", "10,RSA,1,1001", "0,ROAD,12,1001,1", "0,ROAD,329,2,1",
    "10,BRK,50,0," + "9" * 40, "0,A,20,100,-6,*1~" + "9" * 33, "10,Signal Light,2000,1", "10,Pedestrian#5,1",
    "@10,BRK,50,0,1", "Config_Start_Y = 0{0}", "0,A#3,20,100,-6,1", "10,BRK,100{1},0,3",
]
for index, line in enumerate(BAD_LINES):
    name = f"bad{index:02d}.sdl"
    BAD_FILES[name] = f"// line 1\n{line}\n".encode()
    for command in (["check"], ["run"]):
        CASES.append(_case([*command, "{ws}/" + name], 1, "{ws}/" + name + ":2: ", id=f"{command[0]} line {line}"))
# a scenario that is only wrong for advanced dynamics: a fractional surface attribute
BAD_FILES["fraction.sdl"] = b"100,RSA,1,2.5\n"
CASES.append(_case(["run", "{ws}/fraction.sdl", "--dynamics", "advanced"], 1, "{ws}/fraction.sdl:1: "))
# several problems: one line each (a bad threshold, an unsupported code, an event beyond ES)
BAD_FILES["three.sdl"] = b"100,BRK,50,9,1\n50,ES\n60,XYZ\n70,RSA,1,4\n"
CASES.append(_case(["run", "{ws}/three.sdl"], 1, "{ws}/three.sdl:", lines=3))

# --- FMU files that are not (usable) FMUs ---------------------------------------------------------------
FMU_CASES = ["missing.fmu", "text.fmu", "empty.fmu", "folder", "/dev/zero", "nomd.fmu", "badxml.fmu",
             "nobinary.fmu", "badbinary.fmu", "{fmu}"]
for name in FMU_CASES:
    path = name if name.startswith(("/", "{")) else "{ws}/" + name
    dynamics = ["--dynamics", "advanced"] if name == "{fmu}" else []  # the Simple FMU for advanced dynamics
    CASES.append(_case(["run", "{good}", "--fmu", path, *dynamics], 2, "FMU" if name == "badbinary.fmu" else "--fmu",
                       id=f"run fmu {name}"))
    if name != "{fmu}":
        CASES.append(_case(["verify", "--fmu", path], 2, "FMU" if name == "badbinary.fmu" else "--fmu",
                           id=f"verify fmu {name}"))

# --- Tire Attribute Files and tire files that cannot be used ----------------------------------------------
TIRE_CASES = {
    "missing.txt": "--tires", "folder": "--tires", "/dev/zero": "--tires", "binary.sdl": "binary.sdl",
    "tires/no_equals.txt": "no_equals.txt:1", "tires/bad_number.txt": "bad_number.txt:1",
    "tires/negative.txt": "negative.txt:1", "tires/duplicate.txt": "duplicate.txt:2",
    "tires/no_file.txt": "no_file.txt:1", "tires/missing_tire.txt": "missing_tire.txt:1",
    "tires/dev_zero.txt": "dev_zero.txt:1", "tires/syntax.txt": "syntax.tir", "tires/fnomin.txt": "fnomin.tir",
    "tires/no_pdx1.txt": "no_pdx1.tir", "tires/inch.txt": "inch.tir", "tires/binary_tire.txt": "binary.tir",
}
for name, needle in TIRE_CASES.items():
    path = name if name.startswith("/") else "{ws}/" + name
    CASES.append(_case(["run", "{good}", "--dynamics", "advanced", "--tires", path], 2, needle, id=f"tires {name}"))

# --- results folders sdl-fmu must not or cannot write -------------------------------------------------------
CASES += [_case(argv, 2, needle, id=" ".join(argv[3:])) for argv, needle in [
    (["run", "{good}", "--out", "{ws}/text.fmu/run", "--fmu", "{fmu}"], "--out"),
    (["run", "{good}", "--out", "{ws}/text.fmu", "--fmu", "{fmu}"], "--out"),
    (["run", "{good}", "--out", "/proc/sdl-fmu-run", "--fmu", "{fmu}"], "--out"),
    (["run", "{good}", "--out", "", "--fmu", "{fmu}"], "--out"),
    (["run", "{good}", "--out", "/", "--fmu", "{fmu}"], "--out"),
    (["run", "{good}", "--out", "{ws}/users", "--fmu", "{fmu}"], "--out"),
    (["run", "{good}", "--out", ".", "--fmu", "{fmu}"], "--out"),
    (["run", "{good}", "--out", "{ws}", "--fmu", "{fmu}"], "--out"),
    (["run", "{good}", "--out", "{ws}/link", "--fmu", "{fmu}"], "--out"),
    (["run", "{good}", "--out", "{ws}/fake_results", "--fmu", "{fmu}"], "--out"),
    (["build", "--dynamics", "simple", "--out", "{ws}/text.fmu/dist"], "--out"),
    (["build", "--dynamics", "simple", "--out", "/proc/sdl-fmu-dist"], "--out"),
]]


@pytest.fixture(scope="module")
def workspace(tmp_path_factory, simple_fmu):
    """A folder of bad inputs; the cases run with it as the working folder."""
    ws = tmp_path_factory.mktemp("fuzz")
    (ws / "good.sdl").write_text(GOOD)
    (ws / "metric.sdl").write_text("Metric\n10,BRK,100,1,5\n50,ES\n")
    (ws / "folder").mkdir()
    for name, content in BAD_FILES.items():
        if isinstance(content, bytes):
            (ws / name).write_bytes(content)
        elif content == "huge":
            (ws / name).write_bytes(b"// padding\n" * (1 + 10 * 2**20 // 11))
    (ws / "text.fmu").write_text("not an FMU\n")
    (ws / "empty.fmu").write_bytes(b"")
    with zipfile.ZipFile(simple_fmu) as original:
        members = {name: original.read(name) for name in original.namelist()}
    for name, keep in (("nomd.fmu", lambda n: n != "modelDescription.xml"),
                       ("badxml.fmu", lambda n: True), ("nobinary.fmu", lambda n: not n.startswith("binaries/")),
                       ("badbinary.fmu", lambda n: True)):
        with zipfile.ZipFile(ws / name, "w") as fmu:
            for member, data in members.items():
                if keep(member):
                    if name == "badxml.fmu" and member == "modelDescription.xml":
                        data = data[: len(data) // 2]
                    if name == "badbinary.fmu" and member.endswith(".so"):
                        data = b"\x7fELF garbage" * 100
                    fmu.writestr(member, data)
    tires = ws / "tires"
    tires.mkdir()
    shutil.copy(DEFAULT_ATTRIBUTE_FILE, tires / "attributes.txt")
    dry = DRY_TIRE.read_text()
    tire_files = {
        "syntax.tir": dry.replace("PDX1", "PDX1 = = 1\nXX", 1),
        "fnomin.tir": "\n".join("FNOMIN = 0" if line.strip().startswith("FNOMIN") else line
                                for line in dry.splitlines()),
        "no_pdx1.tir": "\n".join(line for line in dry.splitlines() if not line.strip().startswith("PDX1")),
        "inch.tir": dry.replace("[UNITS]", "[UNITS]\nLENGTH = 'inch'", 1),
    }
    for name, text in tire_files.items():
        (tires / name).write_text(text)
    (tires / "binary.tir").write_bytes(bytes(range(256)) * 8)
    attribute_files = {
        "no_equals.txt": f"0 {DRY_TIRE}", "bad_number.txt": f"x = {DRY_TIRE}", "negative.txt": f"-1 = {DRY_TIRE}",
        "duplicate.txt": f"0 = {DRY_TIRE}\n0 = {DRY_TIRE}", "no_file.txt": "0 =",
        "missing_tire.txt": "0 = nowhere.tir", "dev_zero.txt": "0 = /dev/zero", "syntax.txt": "0 = syntax.tir",
        "fnomin.txt": "0 = fnomin.tir", "no_pdx1.txt": "0 = no_pdx1.tir", "inch.txt": "0 = inch.tir",
        "binary_tire.txt": "0 = binary.tir",
    }
    for name, text in attribute_files.items():
        (tires / name).write_text(text + "\n")
    (ws / "users").mkdir()
    (ws / "users" / "thesis.tex").write_text("mine")
    (ws / "link").symlink_to(ws / "users")
    (ws / "fake_results").mkdir()
    (ws / "fake_results" / MANIFEST_NAME).write_text('{"format": "something else"}')
    (ws / "fake_results" / "summary.json").write_text("{}")
    return ws


def snapshot(folder: Path) -> dict:
    return {str(p.relative_to(folder)): (p.is_dir(), p.lstat().st_size, p.lstat().st_mtime_ns)
            for p in folder.rglob("*")}


def test_there_are_at_least_200_cases():
    assert len(CASES) >= 200, len(CASES)


@pytest.mark.parametrize("argv, code, needle, lines", CASES)
def test_user_mistake_is_one_line_per_problem_and_writes_nothing(argv, code, needle, lines, workspace, simple_fmu,
                                                                  advanced_fmu, monkeypatch, capsys):
    fill = {"ws": str(workspace), "good": str(workspace / "good.sdl"), "metric": str(workspace / "metric.sdl"),
            "fmu": str(simple_fmu), "advanced_fmu": str(advanced_fmu)}
    argv = [arg.format(**fill) for arg in argv]
    needle = needle.format(**fill)
    monkeypatch.chdir(workspace)
    before = snapshot(workspace)
    exit_code = main(argv)  # any exception escaping here is a traceback a user would see
    out, err = capsys.readouterr()
    problems = err.splitlines()
    assert exit_code == code, err
    assert out == ""
    assert len(problems) == lines, err
    assert all(needle in line for line in problems), err
    assert "Traceback" not in err
    assert snapshot(workspace) == before


@pytest.mark.parametrize("argv", [["run", "demo"], ["build", "--dynamics", "simple"], ["export", "demo"],
                                  ["verify", "--pack", "vehicle", "--dynamics", "advanced"]], ids=" ".join)
def test_an_fmu_cache_that_cannot_be_written_is_one_line(argv, tmp_path, monkeypatch, capsys):
    """$SDL_FMU_CACHE under a file: the first build (the Simple or Advanced FMU, the scenario binary) cannot make the
    cache. One line naming the folder and the variable, before anything is announced or written."""
    (tmp_path / "a-file").write_text("")
    monkeypatch.setenv("SDL_FMU_CACHE", str(tmp_path / "a-file" / "cache"))
    monkeypatch.chdir(tmp_path)
    exit_code = main([*argv, "--out", str(tmp_path / "out")])
    out, err = capsys.readouterr()
    assert exit_code == 2 and out == "", err
    assert err == f"sdl-fmu: the FMU cache {tmp_path / 'a-file' / 'cache'} ($SDL_FMU_CACHE): cannot write there: " \
                  "Not a directory\n"
    assert sorted(path.name for path in tmp_path.iterdir()) == ["a-file"]


def test_ctrl_c_during_a_run_exits_130_with_one_line_and_no_partial_folder(tmp_path, simple_fmu):
    # The run is held at its first communication step (the test hook, sdl_fmu/hold.py: hostile_fmus.interrupted): the
    # signal arrives mid-simulation however fast the machine is.
    work = held_work(tmp_path)
    out = work / "work" / "results"
    code, stdout, stderr = interrupted(work, ["run", "demo", "--fmu", simple_fmu, "--out", out], "ctrl-c")
    assert code == 130
    assert stderr.splitlines() == ["sdl-fmu: interrupted (Ctrl-C); nothing was written"] and stdout == ""
    assert list((work / "work").iterdir()) == []
    # the interrupted run's folder is free: the next run writes it
    completed = sdl_fmu("run", "demo", "--fmu", simple_fmu, "--until-time", "1", "--out", out, cwd=work / "work")
    assert completed.returncode == 0, completed.stderr
    assert os.listdir(work / "work") == ["results"]
