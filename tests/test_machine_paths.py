"""No results folder names a path of the machine that wrote it (docs/results.md, Results folders): every file that
`run`, `verify` (both packs), `export` and `sweep` write, and every member of the archives among them (the SSP, the
FMUs), is scanned for the machine's absolute paths: the tests' temporary folder (the scenario, the maps and the
working folder are there), $HOME, the FMU cache the FMUs come from, the package's folder (the shipped maps and the
example controller's map) and the working folder. Every file-valued option is given as an absolute path, the worst
case; the results name the files (the scenario, the maps, the FMUs) by their names."""

import os
import shutil
import tempfile
import zipfile
from pathlib import Path

import distributed
import pytest

import sdl_fmu
from helpers import local_cluster
from sdl_fmu import api, sweep
from sdl_fmu.vehicle import shipped_map_path

SCENARIO = "English\n0,A,0,400,*0,1\n1000,ES\n"  # a stopped car 400 ft ahead: a collision at 88 ft/s


@pytest.fixture(scope="module")
def inputs(tmp_path_factory, simple_fmu):
    """The runs' files, each at an absolute path: the scenario and copies of the shipped vehicle map and the example
    controller's map in a temporary folder, the FMUs in the FMU cache."""
    folder = tmp_path_factory.mktemp("inputs")
    (folder / "stopped.sdl").write_text(SCENARIO)
    vehicle = shutil.copy(shipped_map_path("simple"), folder)
    controller, controller_map = api.example_controller()
    return {"scenario": folder / "stopped.sdl", "fmu": Path(simple_fmu).absolute(), "vehicle": Path(vehicle),
            "controller": Path(controller).absolute(), "controller_map": Path(shutil.copy(controller_map, folder))}


def machine_paths(tmp_path_factory) -> list[bytes]:
    """The absolute paths no result may hold, as bytes (a folder's path with its separator after it, so that a
    path's prefix is what is sought)."""
    folders = {tmp_path_factory.getbasetemp(), Path.home(), Path(os.environ["SDL_FMU_CACHE"]),
               Path(sdl_fmu.__file__).resolve().parents[1], Path.cwd(), Path(tempfile.gettempdir())}
    found = set()
    for folder in folders:
        for form in (folder, folder.resolve()):
            found.add(str(form).rstrip("/").encode() + b"/")
    return sorted(found)


def leaks(folder: Path, needles: list[bytes]) -> list[str]:
    """Every (file or archive member, path) where a needle occurs, with the text around it."""
    found = []

    def scan(name: str, data: bytes) -> None:
        for needle in needles:
            at = data.find(needle)
            if at >= 0:
                found.append(f"{name}: {data[max(0, at - 60):at + len(needle) + 60]!r}")

    files = [path for path in sorted(folder.rglob("*")) if path.is_file()]
    assert files, folder
    for path in files:
        data = path.read_bytes()
        scan(str(path.relative_to(folder)), data)
        if zipfile.is_zipfile(path):
            with zipfile.ZipFile(path) as archive:
                for member in archive.namelist():
                    scan(f"{path.relative_to(folder)}!{member}", archive.read(member))
    return found


@pytest.fixture(scope="module")
def folders(tmp_path_factory, inputs):
    """A folder of each kind, every file-valued option absolute (short: a collision run, one manoeuvre, a
    one-second export, a one-run sweep)."""
    root = tmp_path_factory.mktemp("results")
    files = {key: inputs[key] for key in ("fmu", "vehicle", "controller", "controller_map")}
    result = api.run(inputs["scenario"], until_time=8.0, out=root / "run", **files)
    assert result.collisions == 1  # a collision event, with its relative impact speed, is in summary.json
    api.verify(fmu=inputs["fmu"], vehicle=inputs["vehicle"], only=["braking"], out=root / "verify")
    api.export(inputs["scenario"], until_time=1.0, out=root / "export", **files)
    with local_cluster(1) as cluster, distributed.Client(cluster) as client:
        sweep.sweep(str(inputs["scenario"]), {"until_time": [1.0]}, root / "sweep", client=client, progress=False,
                    **{key: str(value) for key, value in files.items()})
    return {kind: root / kind for kind in ("run", "verify", "export", "sweep")}


@pytest.mark.parametrize("kind", ["run", "verify", "export", "sweep"])
def test_no_results_folder_holds_a_machine_path(folders, tmp_path_factory, kind):
    assert leaks(folders[kind], machine_paths(tmp_path_factory)) == []


def test_the_results_name_their_files(folders, inputs):
    """What the results say of the files: their names."""
    import json

    summary = json.loads((folders["run"] / "summary.json").read_text())
    assert summary["scenario"] == "stopped.sdl"
    assert summary["vehicle"]["map"] == "simple.toml" and summary["vehicle"]["fmu"] == inputs["fmu"].name
    assert summary["controller"]["map"] == inputs["controller_map"].name
    assert summary["controller"]["fmu"] == inputs["controller"].name
    verify = json.loads((folders["verify"] / "verify.json").read_text())
    assert (verify["vehicle"]["fmu"], verify["vehicle"]["map"]) == (inputs["fmu"].name, "simple.toml")
    spec = json.loads((folders["sweep"] / "sweep.json").read_text())
    assert spec["scenario"] == "stopped.sdl"
    assert {key: spec["fixed"][key] for key in ("fmu", "vehicle", "controller", "controller_map")} == {
        key: inputs[key].name for key in ("fmu", "vehicle", "controller", "controller_map")}


@pytest.mark.slow
def test_the_aeb_packs_folder_holds_no_machine_path(tmp_path_factory, inputs):
    out = tmp_path_factory.mktemp("aeb") / "aeb"
    with local_cluster(1) as cluster:
        api.verify(fmu=inputs["fmu"], vehicle=inputs["vehicle"], pack="aeb-ccr", only=["CCRb"],
                   controller=inputs["controller"], controller_map=inputs["controller_map"], out=out,
                   scheduler=cluster.scheduler_address)
    assert leaks(out, machine_paths(tmp_path_factory)) == []


def test_a_tire_attribute_files_warnings_name_files_not_paths(tmp_path_factory, advanced_fmu):
    """The warnings of a --tires file given by its absolute path (its attribute 9 beyond the Advanced FMU's 8 slots,
    no attribute 0: the shipped standard tire) name it and the standard tire by their file names."""
    from sdl_fmu.paths import TIRE_DIRECTORY

    folder = tmp_path_factory.mktemp("tires")
    tire = shutil.copy(TIRE_DIRECTORY / "dry_asphalt.tir", folder / "slick.tir")
    attributes = folder / "attr.txt"
    attributes.write_text(f"2 = {Path(tire).name}\n9 = {Path(tire).name}\n")
    (folder / "road.sdl").write_text("English\n1000,ES\n")
    out = folder / "run"
    result = api.run(folder / "road.sdl", dynamics="advanced", fmu=advanced_fmu,
                     tires=attributes.absolute(), until_time=1.0, out=out)
    tire_warnings = [w for w in result.warnings if "attr.txt" in w]
    assert len(tire_warnings) == 2, result.warnings
    assert tire_warnings[0].startswith("attr.txt:2: attribute 9 is beyond the FMU's 8 tire slots")
    assert tire_warnings[1].startswith("attr.txt: no attribute 0 (standard tires); using the shipped standard tire ")
    assert leaks(out, machine_paths(tmp_path_factory)) == []
