"""Export folders: a results folder (results/folder.py: written aside and moved into place whole, nothing sdl-fmu
did not write is touched) that holds an SSP and, beside it, the FMUs it holds. `--out` may be a new folder, an empty
one, or an earlier export folder (sdl-fmu's manifest lists an .ssp); a results folder of another command, or a folder
holding files sdl-fmu did not write, is refused."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from ..results.folder import ResultsFolderError, check_results_folder, read_manifest, write_results_folder
from .document import RESOURCES, System, write_ssp


def check_export_folder(out: str | os.PathLike) -> Path:
    """Refuses (ResultsFolderError, one line) an `--out` that export may not or cannot write; returns it absolute."""
    try:
        target = check_results_folder(out)
    except ResultsFolderError as error:  # the same rules, said of an export folder
        raise ResultsFolderError(str(error).replace("an earlier results folder", "an earlier export folder")) from None
    files = read_manifest(target) if target.is_dir() else None
    if files and not any(name.endswith(".ssp") for name in files):
        raise ResultsFolderError(f"{os.fspath(out)}: holds the results of another sdl-fmu command, not an export; "
                                 "give a new or empty folder or an earlier export folder")
    return target


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

    return write_results_folder(out, write)
