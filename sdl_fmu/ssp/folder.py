"""Export folders: a results folder (results/folder.py: written aside and moved into place whole, nothing sdl-fmu
did not write is touched) of the kind `export`, that holds an SSP and, beside it, the FMUs it holds. `--out` may be a
new folder, an empty one, or an earlier export folder; a folder of another command (a run's results, a test pack's, a
sweep's), or a folder holding files sdl-fmu did not write, is refused."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from ..results.folder import check_results_folder, write_results_folder
from .document import RESOURCES, System, write_ssp


def check_export_folder(out: str | os.PathLike) -> Path:
    """Refuses (ResultsFolderError, one line) an `--out` that export may not or cannot write; returns it absolute."""
    return check_results_folder(out, "export")


def write_export(out: str | os.PathLike, ssp_name: str, system: System) -> Path:
    """Writes the SSP `ssp_name` and, beside it, each FMU it holds under the same file name as inside it, into the
    export folder `out`: all or nothing. Returns the folder (absolute)."""
    check_export_folder(out)
    names = [c.source.removeprefix(f"{RESOURCES}/") for c in system.components]
    if len(set(names)) != len(names) or ssp_name in names:
        raise ValueError(f"the files of an export must have distinct names: {ssp_name}, {names}")

    def write(folder: Path) -> None:
        for component, name in zip(system.components, names):
            shutil.copyfile(component.fmu, folder / name)
        write_ssp(system, folder / ssp_name)

    return write_results_folder(out, write, "export")
