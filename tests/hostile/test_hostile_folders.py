"""Results and sweep folders lose nothing (sdl_fmu/ownership.py, results/folder.py, sweep.py): a file sdl-fmu did not
write is never deleted or overwritten, even under a planted manifest; repeated --vary values keep every row; two
sweeps into one folder cannot both write (a lock), runs into one folder finish one after the other; a full disk
leaves the folder as it was and the same command resumes.

Each case is the real command line under a 1.5 GB address-space cap (tests/hostile_fmus.py). The full disk is a
small tmpfs mounted in a private mount namespace (`unshare --user --map-root-user --mount`: the machine's mounts are
untouched and the tmpfs goes with the namespace)."""

import hashlib
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from sdl_fmu.api import HOLD_VARIABLE

from hostile_fmus import HANG_LIMIT, _capped, capped, capped_command, one_line, popen_capped

pytestmark = pytest.mark.slow  # whole runs, sweeps and verifications of the command line, each capped

SHORT = ["--until-time", "2"]  # a short run of the demo: a few hundred samples


@pytest.fixture
def work(tmp_path, simple_fmus):  # the runs take the Simple FMU from the cache
    (tmp_path / "work").mkdir()
    return tmp_path


def tree(folder: Path) -> dict:
    """Every file under `folder` with the SHA-256 of its bytes."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.rglob("*"))
            if p.is_file()}


# --- results folders ---------------------------------------------------------------------------------------------

def planted(folder: Path, kind: str) -> None:
    """A manifest naming the user's thesis.tex as sdl-fmu's: in the old unsigned format, in the new format with the
    file's true size and SHA-256 but no signature, and with a forged one."""
    thesis = folder / "thesis.tex"
    entry = {"size": thesis.stat().st_size, "sha256": hashlib.sha256(thesis.read_bytes()).hexdigest()}
    data = {"1": {"format": "sdl-fmu results 1", "complete": True, "files": ["thesis.tex"]},
            "unsigned": {"format": "sdl-fmu results 2", "complete": True, "files": {"thesis.tex": entry}},
            "forged": {"format": "sdl-fmu results 2", "complete": True, "files": {"thesis.tex": entry},
                       "signature": "0" * 64}}[kind]
    (folder / ".sdl-fmu-results.json").write_text(json.dumps(data))


@pytest.mark.parametrize("kind", ["1", "unsigned", "forged"])
@pytest.mark.parametrize("command", ["run", "verify"])
def test_a_planted_manifest_proves_nothing(work, kind, command):
    users = work / "work" / "users"
    users.mkdir()
    (users / "thesis.tex").write_text("three years of work\n")
    planted(users, kind)
    before = tree(users)
    arguments = ["run", "demo", *SHORT] if command == "run" else ["verify", "--only", "braking"]
    completed = capped(*arguments, "--out", users, cwd=work / "work")
    one_line(completed, 2, f"sdl-fmu: --out {users}: holds files sdl-fmu did not write ('thesis.tex')")
    assert tree(users) == before


def test_a_results_file_changed_or_added_by_the_user_is_never_overwritten(work):
    out = work / "work" / "out"
    assert capped("run", "demo", *SHORT, "--out", out, cwd=work / "work").returncode == 0
    (out / "notes.txt").write_text("mine\n")  # the user's own file beside the results: kept, and allowed
    assert capped("run", "demo", *SHORT, "--out", out, cwd=work / "work").returncode == 0
    assert (out / "notes.txt").read_text() == "mine\n"
    with open(out / "summary.json", "a") as summary:  # the user edits a result
        summary.write("\n")
    before = tree(out)
    completed = capped("run", "demo", *SHORT, "--out", out, cwd=work / "work")
    one_line(completed, 2, f"sdl-fmu: --out {out}: its summary.json is not sdl-fmu's (changed since sdl-fmu wrote it, "
                           "or never written by it) and would be overwritten")
    assert tree(out) == before
    # the user's own plot.png where sdl-fmu's was: the same
    (out / "summary.json").unlink()
    assert capped("run", "demo", *SHORT, "--out", out, cwd=work / "work").returncode == 0
    (out / "plot.png").write_bytes(b"my own picture")
    before = tree(out)
    completed = capped("run", "demo", *SHORT, "--out", out, cwd=work / "work")
    one_line(completed, 2, f"sdl-fmu: --out {out}: its plot.png is not sdl-fmu's")
    assert tree(out) == before


def test_concurrent_runs_into_one_folder_finish_one_after_the_other(work):
    """Four runs into one --out at once: each exits 0 without a traceback, the folder holds one whole run (its
    signed manifest lists every file, unchanged), and no hidden sibling is left."""
    out = work / "work" / "out"
    processes = [popen_capped("run", "demo", *SHORT, "--seed", str(seed), "--out", out, cwd=work / "work")
                 for seed in range(4)]
    results = [process.communicate(timeout=HANG_LIMIT) for process in processes]
    for process, (stdout, stderr) in zip(processes, results):
        assert process.returncode == 0 and "Traceback" not in stderr, stderr
    from sdl_fmu.results.folder import read_manifest

    assert read_manifest(out) == ["plot.png", "summary.json", "timeseries.csv"]
    assert sorted(os.listdir(work / "work")) == ["out"]
    seeds = {json.loads((out / "summary.json").read_text())["seed"]}
    assert seeds <= {0, 1, 2, 3}


# --- sweep folders -----------------------------------------------------------------------------------------------

def sweep(out: Path, *vary: str, cwd=None, env=None) -> subprocess.CompletedProcess:
    arguments = [argument for name in vary for argument in ("--vary", name)]
    return capped("sweep", "demo", *arguments, "--vary", "until_time=1", "--workers", "1", "--out", out, cwd=cwd,
                  env=env)


def table(out: Path) -> list[dict]:
    import csv

    with open(out / "sweep.csv", newline="") as file:
        return list(csv.DictReader(file))


def test_repeated_values_keep_every_row_through_a_resume(work):
    out = work / "work" / "sweep"
    first = sweep(out, "seed=integers(1,3,8)", cwd=work / "work")
    assert first.returncode == 0, first.stderr
    rows = table(out)
    assert len(rows) == 8 and len({row["seed"] for row in rows}) <= 3  # 8 runs over at most 3 seeds
    again = sweep(out, "seed=integers(1,3,8)", cwd=work / "work")  # the same command: nothing to run, 8 rows stay
    assert again.returncode == 0, again.stderr
    assert table(out) == rows


@pytest.mark.parametrize("name", ["sweep.csv", "sweep.png", "sweep.parquet", "sweep.json", "sweep-rows.jsonl"])
def test_a_users_file_named_as_the_sweeps_is_never_replaced(work, name):
    out = work / "work" / "sweep"
    out.mkdir()
    (out / name).write_text("the user's\n")
    completed = sweep(out, "speed=60", cwd=work / "work")
    one_line(completed, 2, f"sdl-fmu: --out {out}: its {name} was not written by sdl-fmu's sweep, or was changed since")
    assert tree(out) == {name: hashlib.sha256(b"the user's\n").hexdigest()}


def test_a_planted_sweep_manifest_proves_nothing(work):
    out = work / "work" / "sweep"
    out.mkdir()
    (out / "sweep.csv").write_text("the user's\n")
    entry = {"size": 11, "sha256": hashlib.sha256(b"the user's\n").hexdigest()}
    (out / ".sdl-fmu-sweep.json").write_text(json.dumps({"format": "sdl-fmu sweep 1", "files": {"sweep.csv": entry},
                                                         "signature": "f" * 64}))
    completed = sweep(out, "speed=60", cwd=work / "work")
    one_line(completed, 2, f"sdl-fmu: --out {out}: its sweep.csv was not written by sdl-fmu's sweep")
    assert (out / "sweep.csv").read_text() == "the user's\n"


def test_two_sweeps_into_one_folder_cannot_both_write(work):
    """The first sweep is held mid-run (the api's test hook); the second, into the same --out, is refused at once
    (it holds no lock); released, the first finishes with every row."""
    out, hold = work / "work" / "sweep", work / "hold"
    hold.touch()
    first = popen_capped("sweep", "demo", "--vary", "speed=60,70", "--vary", "until_time=1", "--workers", "1",
                         "--out", out, cwd=work / "work", env={HOLD_VARIABLE: str(hold)})
    try:
        deadline = time.monotonic() + HANG_LIMIT  # only against a hang: ends when a run is held
        while not (work / "hold.running").exists():
            assert first.poll() is None, first.communicate()
            assert time.monotonic() < deadline, "the first sweep's run was never held"
            time.sleep(0.05)
        second = sweep(out, "speed=60,70", cwd=work / "work")
        one_line(second, 2, f"sdl-fmu: --out {out}: another sweep is writing into it; wait until it ends")
        other = sweep(out, "speed=80", cwd=work / "work")  # another sweep's values: the same
        one_line(other, 2, f"sdl-fmu: --out {out}: another sweep is writing into it")
        hold.unlink()
        stdout, stderr = first.communicate(timeout=HANG_LIMIT)
    finally:
        if first.poll() is None:
            first.kill()
            first.wait()
    assert first.returncode == 0, stderr
    assert sorted(float(row["speed_ft/s"]) for row in table(out)) == [60.0, 70.0]


def test_a_damaged_sweep_description_or_journal_line_is_one_line_or_run_again(work):
    out = work / "work" / "sweep"
    assert sweep(out, "speed=60,70", cwd=work / "work").returncode == 0
    journal = out / "sweep-rows.jsonl"
    rows = journal.read_text().splitlines()
    with open(journal, "a") as file:  # lines appended after the journal's start: cut short, not JSON, not a row
        file.write('{"run": 1, "status": "ok"\n[1, 2]\n"text"\n{"key": 5, "run": "x", "status": "ok"}\n')
    again = sweep(out, "speed=60,70", cwd=work / "work")
    assert again.returncode == 0, again.stderr
    assert journal.read_text().splitlines() == rows  # compacted to the rows it could read: nothing run again
    spec = out / "sweep.json"
    spec.write_text(spec.read_text()[:-20])
    completed = sweep(out, "speed=60,70", cwd=work / "work")
    one_line(completed, 2, f"sdl-fmu: --out {out}: its sweep.json was not written by sdl-fmu's sweep, or was changed")


# --- a full disk -------------------------------------------------------------------------------------------------

def private_mounts() -> bool:
    return shutil.which("unshare") is not None and subprocess.run(
        ["unshare", "--user", "--map-root-user", "--mount", "true"], capture_output=True).returncode == 0


def on_small_disk(work, script: str) -> subprocess.CompletedProcess:
    """`script` (sh) in a private mount namespace where $DISK is a 192 KB tmpfs; commands in it are capped."""
    disk = work / "disk"
    disk.mkdir(exist_ok=True)
    command = f"mount -t tmpfs -o size=192k tmpfs '{disk}' && DISK='{disk}' && {script}"
    return subprocess.run(["unshare", "--user", "--map-root-user", "--mount", "sh", "-c", command],
                          capture_output=True, text=True, cwd=work / "work", timeout=HANG_LIMIT, preexec_fn=_capped,
                          env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})


def quoted(arguments) -> str:
    return " ".join(f"'{argument}'" for argument in arguments)


@pytest.mark.skipif(not private_mounts(), reason="unshare cannot make a private mount namespace here")
def test_a_full_disk_leaves_the_results_folder_as_it_was_and_the_same_command_then_writes_it(work):
    """The demo's results do not fit in 192 KB: one line, exit 2, nothing on the disk; the same command once the disk
    has room (remounted at 64 MB) writes them."""
    run = quoted(capped_command("run", "demo", *SHORT, "--out", work / "disk" / "out"))
    completed = on_small_disk(work, f"{run} 2> \"$DISK/../first.err\"; echo $? > \"$DISK/../first.code\"; "
                                    "ls -A \"$DISK\" > \"$DISK/../first.ls\"; mount -o remount,size=64m \"$DISK\" && "
                                    f"{run} > /dev/null && ls -A \"$DISK/out\"")
    assert (work / "first.code").read_text().strip() == "2"
    one_line(subprocess.CompletedProcess([], 2, "", (work / "first.err").read_text()), 2,
             f"sdl-fmu: --out {work / 'disk' / 'out'}: cannot write the results: No space left on device; the folder "
             "is as it was")
    assert (work / "first.ls").read_text() == ""  # no partial sibling, no folder
    assert completed.returncode == 0, completed.stderr
    assert completed.stdout.split() == [".sdl-fmu-results.json", "plot.png", "summary.json", "timeseries.csv"]


@pytest.mark.skipif(not private_mounts(), reason="unshare cannot make a private mount namespace here")
def test_a_full_disk_stops_a_sweep_with_one_line_and_the_same_command_resumes_it(work):
    """The disk fills while the sweep writes (a filler file leaves 48 KB): one line, exit 2, no half-written file,
    every file there provably the sweep's; with the filler gone, the same command finishes it, keeping every row
    the journal had."""
    out = work / "disk" / "sweep"
    command = quoted(capped_command("sweep", "demo", "--vary", "speed=60,70,80", "--vary", "until_time=1",
                                    "--workers", "1", "--out", out))
    probe = (f"'{sys.executable}' -c 'import json; from pathlib import Path; from sdl_fmu.sweep import _proved; "
             f"p = _proved(Path(\"{out}\")); print(json.dumps(sorted(p) if p is not None else None))'")
    completed = on_small_disk(work, "avail=$(df -k --output=avail \"$DISK\" | tail -1); "
                                    "dd if=/dev/zero of=\"$DISK/filler\" bs=1k count=$((avail - 48)) 2>/dev/null; "
                                    f"{command} 2> \"$DISK/../first.err\"; echo $? > \"$DISK/../first.code\"; "
                                    f"ls -A '{out}' > \"$DISK/../first.ls\"; {probe} > \"$DISK/../first.proved\"; "
                                    f"cp '{out}/sweep-rows.jsonl' \"$DISK/../first.journal\" 2>/dev/null; "
                                    f"rm \"$DISK/filler\" && {command} > /dev/null && cat '{out}/sweep.csv'")
    assert (work / "first.code").read_text().strip() == "2", (work / "first.err").read_text()
    one_line(subprocess.CompletedProcess([], 2, "", (work / "first.err").read_text()), 2,
             f"sdl-fmu: --out {out}: cannot write: No space left on device; ")
    listed = (work / "first.ls").read_text().split()
    assert not [name for name in listed if name.endswith(".partial")], listed
    proved = json.loads((work / "first.proved").read_text())
    assert proved is not None and set(listed) - {".sdl-fmu-sweep.json"} <= set(proved), (listed, proved)
    assert completed.returncode == 0, completed.stderr[-3000:]
    import csv
    import io

    rows = list(csv.DictReader(io.StringIO(completed.stdout)))
    assert sorted(float(row["speed_ft/s"]) for row in rows) == [60.0, 70.0, 80.0]
    assert all(row["status"] == "ok" for row in rows)
    if (work / "first.journal").exists():  # the rows finished before the disk filled were not run again
        kept = [json.loads(line) for line in (work / "first.journal").read_text().splitlines() if line.strip()]
        walls = {str(row["run"]): row["run_wall_s"] for row in kept if row.get("status") == "ok"}
        for row in rows:
            if row["run"] in walls:
                assert float(row["run_wall_s"]) == pytest.approx(walls[row["run"]], rel=1e-12)
