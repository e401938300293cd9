"""Results folders never destroy what sdl-fmu did not write: real folders, real runs, a real killed process."""

import json
import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from sdl_fmu import api
from sdl_fmu.cli import main
from sdl_fmu.results.folder import (MANIFEST_NAME, ResultsFolderError, check_results_folder, clean_leftovers,
                                    read_manifest, write_results_folder)

RESULT_FILES = ["plot.png", "summary.json", "timeseries.csv"]
SCENARIO = "100,BRK,100,1,50\n200,ES\n"


def tree(folder):
    """Every entry below `folder` with its bytes (files) or None (folders): what a user would notice."""
    return {str(p.relative_to(folder)): (p.read_bytes() if p.is_file() else None) for p in sorted(folder.rglob("*"))}


def write_files(*names):
    def write(folder):
        for name in names:
            (folder / name).write_text(f"new {name}")
    return write


@pytest.fixture
def scenario(tmp_path):
    path = tmp_path / "stop.sdl"
    path.write_text(SCENARIO)
    return path


def test_out_dot_in_a_folder_with_a_users_file_leaves_it_and_the_scenario_untouched(tmp_path, monkeypatch,
                                                                                     scenario, simple_fmu, capsys):
    (tmp_path / "notes.txt").write_text("my notes")
    before = tree(tmp_path)
    monkeypatch.chdir(tmp_path)
    # refused before the simulation, not after: a simulation that started would fail the test at once
    from sdl_fmu.cosim import master

    def never(*args, **kwargs):
        raise AssertionError("the simulation started although --out was refusable up front")

    monkeypatch.setattr(master, "run_scenario", never)
    assert main(["run", "stop.sdl", "--fmu", str(simple_fmu), "--out", "."]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "--out .: holds files sdl-fmu did not write" in error and "notes.txt" in error
    assert tree(tmp_path) == before


def test_out_at_the_scenarios_own_folder_is_refused(tmp_path, scenario, simple_fmu, capsys):
    before = tree(tmp_path)
    assert main(["run", str(scenario), "--fmu", str(simple_fmu), "--out", str(tmp_path)]) == 2
    assert "stop.sdl" in capsys.readouterr().err
    assert tree(tmp_path) == before


def test_new_empty_and_earlier_results_folders_are_accepted(tmp_path, scenario, simple_fmu):
    new = tmp_path / "a" / "b" / "new"
    api.run(scenario, fmu=simple_fmu, out=new)
    assert sorted(p.name for p in new.iterdir()) == [MANIFEST_NAME, *RESULT_FILES]
    assert read_manifest(new) == RESULT_FILES

    empty = tmp_path / "empty"
    empty.mkdir()
    inode = empty.stat().st_ino
    api.run(scenario, fmu=simple_fmu, out=empty, plot=False)
    assert empty.stat().st_ino == inode  # an empty folder keeps its identity (it may be the user's cwd)
    assert sorted(p.name for p in empty.iterdir()) == [MANIFEST_NAME, "summary.json", "timeseries.csv"]

    # an earlier results folder is replaced as a whole; a file it no longer gets disappears with it
    api.run(scenario, fmu=simple_fmu, out=new, plot=False)
    assert sorted(p.name for p in new.iterdir()) == [MANIFEST_NAME, "summary.json", "timeseries.csv"]
    assert [p.name for p in new.parent.iterdir()] == ["new"]  # no hidden leftovers


def test_users_files_in_an_earlier_results_folder_are_never_touched(tmp_path):
    out = tmp_path / "run"
    write_results_folder(out, write_files("summary.json", "plot.png"))
    (out / "my_analysis.py").write_text("print('mine')")
    (out / "mine").mkdir()
    (out / "mine" / "data.csv").write_text("1,2")
    stat = (out / "my_analysis.py").stat()
    write_results_folder(out, write_files("summary.json", "timeseries.csv"))
    assert (out / "my_analysis.py").read_text() == "print('mine')" and (out / "mine" / "data.csv").read_text() == "1,2"
    assert (out / "my_analysis.py").stat().st_ino == stat.st_ino
    assert (out / "my_analysis.py").stat().st_mtime_ns == stat.st_mtime_ns
    assert (out / "summary.json").read_text() == "new summary.json"
    assert not (out / "plot.png").exists()  # sdl-fmu's own old file, not written this time
    assert read_manifest(out) == ["summary.json", "timeseries.csv"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


@pytest.mark.parametrize("make, reason", [
    (lambda p: (p.mkdir(), (p / "thesis.tex").write_text("x")), "holds files sdl-fmu did not write"),
    (lambda p: (p.mkdir(), (p / MANIFEST_NAME).write_text("{not json"), (p / "x").write_text("x")),
     "holds files sdl-fmu did not write"),
    (lambda p: p.write_text("a file"), "exists and is not a folder"),
    (lambda p: (p.parent / "target").mkdir() or p.symlink_to(p.parent / "target"), "symbolic link"),
])
def test_anything_else_is_refused_and_left_alone(tmp_path, make, reason):
    out = tmp_path / "out"
    make(out)
    before = tree(tmp_path)
    with pytest.raises(ResultsFolderError, match=reason):
        write_results_folder(out, write_files("summary.json"))
    assert tree(tmp_path) == before


def test_unwritable_locations_are_refused_before_anything_is_written(tmp_path):
    (tmp_path / "file").write_text("x")
    for out, reason in ((tmp_path / "file" / "run", "is not a folder"), ("/proc/sdl-fmu-run", "cannot write"),
                        ("/", "root")):
        with pytest.raises(ResultsFolderError, match=reason):
            check_results_folder(out)
    assert [p.name for p in tmp_path.iterdir()] == ["file"]


def test_ctrl_c_while_writing_keeps_the_old_results_and_leaves_no_partial_folder(tmp_path, monkeypatch, scenario,
                                                                                 simple_fmu, capsys):
    from sdl_fmu.results import plots

    out = tmp_path / "run"
    api.run(scenario, fmu=simple_fmu, out=out, plot=False)
    before = tree(tmp_path)

    def interrupted(result, path):
        path.write_bytes(b"half a png")
        raise KeyboardInterrupt

    monkeypatch.setattr(plots, "plot_run", interrupted)
    assert main(["run", str(scenario), "--fmu", str(simple_fmu), "--out", str(out)]) == 130
    assert capsys.readouterr().err.count("\n") == 1
    assert tree(tmp_path) == before


def test_leftovers_of_a_killed_run_are_cleaned_by_the_next_run(tmp_path):
    out = tmp_path / "run"
    # a real process killed (SIGKILL) while writing its results
    child = subprocess.Popen([sys.executable, "-c", textwrap.dedent(f"""
        import time
        from pathlib import Path
        from sdl_fmu.results.folder import write_results_folder
        import threading
        def write(folder):
            (folder / "summary.json").write_text("half")
            Path({str(tmp_path / 'ready')!r}).touch()
            threading.Event().wait()  # until killed
        write_results_folder({str(out)!r}, write)
        """)])
    try:
        deadline = time.monotonic() + 300  # only against a hang: the loop ends when the child is ready
        while not (tmp_path / "ready").exists():
            assert time.monotonic() < deadline and child.poll() is None
            time.sleep(0.05)
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait()
    (tmp_path / "ready").unlink()
    leftovers = [p.name for p in tmp_path.iterdir()]
    assert len(leftovers) == 1 and leftovers[0].startswith(".run.partial-")
    # a look-alike that sdl-fmu did not write, and one of a process that is still alive, stay
    foreign = tmp_path / f".run.partial-{child.pid}-foreign"
    foreign.mkdir()
    (foreign / "keep.txt").write_text("mine")
    alive = tmp_path / f".run.partial-{os.getpid()}-alive"
    alive.mkdir()
    (alive / MANIFEST_NAME).write_text(json.dumps({"format": "sdl-fmu results 1", "files": []}))

    write_results_folder(out, write_files("summary.json"))
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([alive.name, foreign.name, "run"])
    assert (foreign / "keep.txt").read_text() == "mine"
    assert clean_leftovers(out) == []
