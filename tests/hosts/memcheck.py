"""valgrind memcheck over instantiate / step / get-serialize-deserialize-set state / free loops of FMUs.

    python tests/hosts/memcheck.py dist/fmi2/EgoVehicleSimple.fmu dist/fmi2/EgoVehicleAdvanced.fmu [--repeat 50]

Builds the plain C host (fmi_host.c, FMI 2.0 and 3.0) with gcc, runs it under valgrind on each FMU's Linux binary (one printed
simulation, then --repeat simulations with a state round trip half-way) and prints valgrind's summary; exits 1
on any memory error or leak."""

import argparse
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

from fmpy import read_model_description

from sdl_fmu.fmu.package import fmi_headers

HOST = Path(__file__).with_name("fmi_host.c")
# 2 s of braking in a curve at 10 ms steps: events (wheel lock, stop) happen inside the loops
START = {"v0": 20.0, "brake": 0.8, "steer": 0.05}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("fmu", nargs="+", type=Path)
    parser.add_argument("--repeat", type=int, default=50)
    arguments = parser.parse_args()
    failed = False
    with tempfile.TemporaryDirectory(prefix="sdl-fmu-memcheck-") as work:
        host = Path(work) / "fmi_host"
        subprocess.run(["gcc", "-std=c99", "-O1", "-g", "-Wall", "-Wextra", "-Werror", f"-I{fmi_headers()}",
                        str(HOST), "-o", str(host), "-ldl"], check=True)
        for fmu in arguments.fmu:
            unzipped = Path(work) / fmu.stem
            with zipfile.ZipFile(fmu) as archive:
                archive.extractall(unzipped)
            description = read_model_description(str(unzipped))
            references = {v.name: v.valueReference for v in description.modelVariables}
            version = int(description.fmiVersion[0])
            platform = "linux64" if version == 2 else "x86_64-linux"
            library = unzipped / "binaries" / platform / f"{description.coSimulation.modelIdentifier}.so"
            command = ["valgrind", "--tool=memcheck", "--leak-check=full", "--show-leak-kinds=all",
                       "--errors-for-leak-kinds=all", "--error-exitcode=3", str(host),
                       *(["--fmi3"] if version == 3 else []), str(library), description.guid,
                       "0.01", "2.0", "--every", "100", "--repeat", str(arguments.repeat),
                       *[f"r:{references[n]}={v!r}" for n, v in START.items()], f"o:{references['s']}"]
            completed = subprocess.run(command, capture_output=True, text=True)
            summary = [line.split("== ", 1)[-1] for line in completed.stderr.splitlines()
                       if any(key in line for key in ("ERROR SUMMARY", "in use at exit", "total heap usage",
                                                      "All heap blocks", "definitely lost"))]
            print(f"{fmu.parent.name}/{fmu.name}: {1 + arguments.repeat} simulations, exit status {completed.returncode}")
            for line in summary:
                print("    " + line)
            failed |= completed.returncode != 0
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
