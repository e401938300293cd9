"""Every command ends on Ctrl-C and on SIGTERM with its documented exit code and line (docs/decisions.md: 130 and
143, `nothing was written`; an interrupted sweep keeps its finished rows) and leaves no temporary folder, partial file,
process or lock behind.

Each command is caught mid-way at a hold point of the test hook (sdl_fmu/hold.py: it waits while $SDL_FMU_TEST_HOLD
names a file and says so in that file + ".running"), never after a guessed sleep: run, a sweep's run on its Dask
worker, a manoeuvre of the vehicle test pack, an AEB car-to-car test on a Dask worker, export's reference run, check
once the scenario is checked, build with an FMU's copy written into --out but not yet in place (its first, or its
second: the first it printed stays); and build into an empty FMU cache, held by a compiler that keeps the same
protocol (the cache's code is a build input: a hold point there would rebuild every FMU). Ctrl-C goes to the
command's whole process group, as a terminal sends it; SIGTERM comes from coreutils `timeout`, which relays it to the
command and then to its process group, as on expiry. The hold is released once sdl-fmu's process has acted on the
signal, so that no command can finish first, however the machine schedules `timeout`.
Each command runs under the 1.5 GB cap with a private, empty $TMPDIR, which must be empty afterwards, and its working
folder must hold nothing new."""

import os
from pathlib import Path

import pytest

from hostile_fmus import assert_clean, capped, environment, held_work, interrupted

pytestmark = [pytest.mark.slow,  # a command started and interrupted per case (some start a Dask cluster)
              # the FMUs the commands take from the cache, built as setup: a command building one on first use
              # says so on stderr
              pytest.mark.usefixtures("simple_fmus", "example_aeb_fmus", "scenario_binaries")]
SIGNALS = {"ctrl-c": (130, "interrupted (Ctrl-C)"), "sigterm": (143, "terminated (SIGTERM)")}


@pytest.fixture
def work(tmp_path):
    return held_work(tmp_path)


def arguments(name: str, out, simple_fmu) -> list:
    return {"run": ["run", "demo", "--fmu", simple_fmu, "--out", out],
            "sweep": ["sweep", "demo", "--vary", "until_time=2,3", "--workers", "1", "--fmu", simple_fmu, "--out",
                      out],
            "verify": ["verify", "--only", "braking", "--fmu", simple_fmu, "--out", out],
            "verify-aeb": ["verify", "--pack", "aeb-ccr", "--only", "CCRs", "--controller", "example-aeb",
                           "--workers", "1", "--fmu", simple_fmu, "--out", out],
            "export": ["export", "head_on", "--fmu", simple_fmu, "--out", out],
            "check": ["check", "demo"],
            "build": ["build", "--dynamics", "simple", "--fmi-version", "2", "--out", out],
            "build-cache": ["build", "--dynamics", "simple", "--fmi-version", "2", "--out", out]}[name]


def held_compiler(work) -> Path:
    """A C compiler that is gcc, held at the hold point of the test hook's protocol (sdl_fmu/hold.py) before it
    compiles: the FMU cache's build is then caught with its temporary folders made and its compilers running."""
    wrapper = work / "held-gcc"
    wrapper.write_text('#!/bin/sh\n'
                       'case " $* " in *" -o "*)\n'
                       '  if [ -e "$SDL_FMU_TEST_HOLD" ]; then\n'
                       '    echo $$ >> "$SDL_FMU_TEST_HOLD.running"\n'
                       '    while [ -e "$SDL_FMU_TEST_HOLD" ]; do sleep 0.01; done\n'
                       '  fi;;\n'
                       'esac\n'
                       'exec gcc "$@"\n')
    wrapper.chmod(0o755)
    return wrapper


@pytest.mark.parametrize("how", list(SIGNALS))
@pytest.mark.parametrize("name", ["run", "verify", "export", "check", "build", "build-cache"])
def test_an_interrupted_command_ends_with_its_code_and_leaves_nothing(work, simple_fmu, name, how):
    out = work / "work" / "out"
    extra = {}
    if name == "build-cache":  # a cache without the FMU: the build is held at its first compiler run
        extra = {"SDL_FMU_CACHE": str(work / "cache"), "CC": str(held_compiler(work))}
    code, stdout, stderr = interrupted(work, arguments(name, out, simple_fmu), how, **extra)
    expected_code, what = SIGNALS[how]
    assert (code, stderr.splitlines()) == (expected_code, [f"sdl-fmu: {what}; nothing was written"]), stderr
    assert stdout == "" and os.listdir(work / "work") == []
    if name == "build-cache":
        assert os.listdir(work / "cache") == []  # the temporary build folder (.building-<pid>-...) is gone
    assert_clean(work)


@pytest.mark.parametrize("how", list(SIGNALS))
def test_an_interrupted_sweep_keeps_its_folder_resumable_and_leaves_no_lock(work, simple_fmu, how):
    """The sweep says where its finished runs are; the same command then resumes it (the folder's lock went with the
    interrupted process) and finishes both runs."""
    out = work / "work" / "sweep"
    command = arguments("sweep", out, simple_fmu)
    code, stdout, stderr = interrupted(work, command, how)
    expected_code, what = SIGNALS[how]
    assert (code, stderr.splitlines()) == (expected_code, [
        f"sdl-fmu: sweep {what}; the finished runs are in {out / 'sweep-rows.jsonl'}: the same command resumes the "
        "sweep"]), stderr
    assert stdout == "" and os.listdir(work / "work") == ["sweep"]
    assert_clean(work)
    resumed = capped(*command, cwd=work / "work", env=environment(work))
    assert resumed.returncode == 0, resumed.stderr
    assert "2 runs: 2 ok" in resumed.stdout
    assert_clean(work)


@pytest.mark.parametrize("how", list(SIGNALS))
def test_an_interrupted_aeb_pack_on_dask_ends_with_its_code_and_leaves_nothing(work, simple_fmu, how):
    out = work / "work" / "aeb"
    code, stdout, stderr = interrupted(work, arguments("verify-aeb", out, simple_fmu), how)
    expected_code, what = SIGNALS[how]
    assert (code, stderr.splitlines()) == (expected_code, [f"sdl-fmu: {what}; nothing was written"]), stderr
    assert stdout == "" and os.listdir(work / "work") == []
    assert_clean(work)


@pytest.mark.parametrize("how", list(SIGNALS))
def test_a_build_interrupted_at_its_second_fmu_keeps_the_first_it_printed(work, simple_fmus, how):
    """build --fmi-version all, held at its second FMU's copy (the hold file's number: sdl_fmu/hold.py): the FMI 2.0
    FMU it printed stays, whole; the FMI 3.0 one was never put in place and its folder, made for it, is gone."""
    out = work / "work" / "out"
    (work / "hold").write_text("2")
    code, stdout, stderr = interrupted(work, ["build", "--dynamics", "simple", "--fmi-version", "all", "--out", out],
                                       how)
    expected_code, what = SIGNALS[how]
    first = out / "fmi2" / "EgoVehicleSimple.fmu"
    assert (code, stdout.splitlines(), stderr.splitlines()) == (
        expected_code, [str(first)], [f"sdl-fmu: build {what}; only the FMUs listed above were written"]), stderr
    assert sorted(path.relative_to(out).as_posix() for path in out.rglob("*")) == ["fmi2", "fmi2/EgoVehicleSimple.fmu"]
    assert first.read_bytes() == simple_fmus[2].read_bytes()
    assert_clean(work)
