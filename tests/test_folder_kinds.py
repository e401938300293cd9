"""Folders of one kind stay that kind (sdl_fmu/results/folder.py: folder_kind; docs/results.md, Results folders): a
folder sdl-fmu wrote for `run`, `verify`, `export` or `sweep` is replaced only by the same command; every other
command refuses it in one line naming the folder and what it holds, before anything runs, and leaves it as it was.
A manifest of an earlier sdl-fmu, which did not record its kind, is told by its files."""

import json
import shutil

import distributed
import pytest

from sdl_fmu import api, ownership, search, sweep
from sdl_fmu.cli import main
from sdl_fmu.results.folder import EARLIER, HOLDS, MANIFEST_NAME, folder_kind

KINDS = ("run", "verify", "export", "sweep", "search")


@pytest.fixture(scope="module")
def folders(tmp_path_factory, simple_fmu):
    """A folder of each kind, written by its command (short: a second of the demo, one manoeuvre, one sweep run)."""
    root = tmp_path_factory.mktemp("kinds")
    api.run("demo", fmu=simple_fmu, until_time=1.0, out=root / "run", plot=False)
    api.verify(fmu=simple_fmu, only=["braking"], out=root / "verify")
    api.export("head_on", fmu=simple_fmu, until_time=1.0, out=root / "export")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        sweep.sweep(str(api.resolve_scenario("demo")), {"until_time": [1.0]}, root / "sweep", client=client,
                    fmu=str(simple_fmu), progress=False)
        search.search(str(api.resolve_scenario("demo")), search.parse_ranges(["until_time=1..1.5"]), root / "search",
                      objective=search.objective_of("collisions", None, None), budget=1, client=client,
                      fmu=str(simple_fmu), progress=False)
    return {kind: root / kind for kind in KINDS}


def command(kind: str, out, simple_fmu) -> list[str]:
    """The command of that kind, cheap, into `out`."""
    return {"run": ["run", "demo", "--fmu", simple_fmu, "--until-time", "1"],
            "verify": ["verify", "--only", "braking", "--fmu", simple_fmu],
            "export": ["export", "head_on", "--fmu", simple_fmu, "--until-time", "1"],
            "sweep": ["sweep", "demo", "--fmu", simple_fmu, "--vary", "until_time=1", "--workers", "1"],
            "search": ["search", "demo", "--fmu", simple_fmu, "--vary", "until_time=1..1.5", "--minimize", "collisions",
                       "--budget", "1", "--workers", "1"]}[kind] + [
        "--out", out]


def contents(folder) -> dict:
    return {path.name: contents(path) if path.is_dir() else path.read_bytes() for path in sorted(folder.iterdir())}


def test_each_command_writes_a_folder_of_its_kind(folders):
    assert {kind: folder_kind(folder) for kind, folder in folders.items()} == {kind: kind for kind in KINDS}


@pytest.mark.parametrize("made, by", [(made, by) for made in KINDS for by in KINDS if made != by])
def test_a_folder_of_another_command_is_refused_in_one_line_and_left_alone(folders, made, by, tmp_path, simple_fmu,
                                                                            capsys):
    folder = tmp_path / f"{made}-folder"
    shutil.copytree(folders[made], folder)  # the same bytes: the signed manifest still proves them sdl-fmu's
    before = contents(folder)
    code = main([str(arg) for arg in command(by, folder, simple_fmu)])
    out, err = capsys.readouterr()
    assert (code, out) == (2, "")
    assert err.splitlines() == [f"sdl-fmu: --out {folder}: holds {HOLDS[made]}, which sdl-fmu {by} does not "
                                f"replace; give a new or empty folder or {EARLIER[by]}"]
    assert contents(folder) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == [folder.name]  # no partial sibling either


@pytest.mark.parametrize("kind", ["run", "export"])
def test_a_folder_of_its_own_kind_is_replaced(folders, kind, tmp_path, simple_fmu, capsys):
    """(verify and sweep: tests/verify/test_verify.py replaces an earlier verify folder, tests/test_sweep.py resumes a
    sweep's.)"""
    folder = tmp_path / kind
    shutil.copytree(folders[kind], folder)
    assert main([str(arg) for arg in command(kind, folder, simple_fmu)]) == 0, capsys.readouterr().err
    assert folder_kind(folder) == kind


@pytest.mark.parametrize("kind, expected", [("run", "run"), ("verify", "verify"), ("export", "export")])
def test_a_manifest_without_its_kind_is_told_by_its_files(folders, kind, expected, tmp_path):
    """An sdl-fmu before kinds signed the same manifest without `kind`: an .ssp means export, verify.json verify."""
    folder = tmp_path / kind
    shutil.copytree(folders[kind], folder)
    data = json.loads((folder / MANIFEST_NAME).read_text())
    assert data.pop("kind") == kind
    data.pop("signature")
    (folder / MANIFEST_NAME).write_text(json.dumps(ownership.signed(data)))
    assert folder_kind(folder) == expected


def test_an_unsigned_manifest_proves_no_kind(folders, tmp_path):
    """A manifest anyone could write (no valid signature) proves nothing: not sdl-fmu's, so no kind."""
    folder = tmp_path / "planted"
    shutil.copytree(folders["export"], folder)
    data = json.loads((folder / MANIFEST_NAME).read_text())
    data["signature"] = "0" * 64
    (folder / MANIFEST_NAME).write_text(json.dumps(data))
    assert folder_kind(folder) is None
