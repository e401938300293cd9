"""The `sdl-fmu` command line: build, check, run, verify."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .fmu.package import MODELS, BuildError, build_fmu, fmu_path


class UsageError(Exception):
    """A user mistake: reported as one line, no traceback."""


def _build(args) -> int:
    names = list(MODELS) if args.dynamics == "all" else [args.dynamics]
    for dynamics in names:
        print(build_fmu(dynamics, Path(args.out), args.fmi_version))
    return 0


def _check(args) -> int:
    from .sdl import ScenarioError, check_models, default_vehicle_table_path, describe, load_scenario, load_vehicle_table

    try:
        scenario = load_scenario(args.scenario)
    except ScenarioError as error:
        print(error, file=sys.stderr)
        return 1
    problems = check_models(scenario, load_vehicle_table(default_vehicle_table_path()))
    print(describe(scenario))
    for problem in problems:
        print(problem, file=sys.stderr)
    return 1 if problems else 0


def _verify(args) -> int:
    from .verify import format_table, verify

    fmu = Path(args.fmu) if args.fmu else fmu_path(Path("dist"), "simple")
    if not args.fmu and not fmu.exists():
        build_fmu("simple", Path("dist"))
    results = verify(fmu)
    print(format_table(results))
    return 0


def parser() -> argparse.ArgumentParser:
    main = argparse.ArgumentParser(prog="sdl-fmu", description=__doc__)
    commands = main.add_subparsers(dest="command", required=True)

    build = commands.add_parser("build", help="build the ego-vehicle FMUs")
    build.add_argument("--dynamics", choices=[*MODELS, "all"], default="all")
    build.add_argument("--fmi-version", type=int, choices=[2, 3], default=2)
    build.add_argument("--out", default="dist", help="output folder (default: dist)")
    build.set_defaults(handler=_build)

    check = commands.add_parser("check", help="parse a scenario and report, run nothing")
    check.add_argument("scenario")
    check.set_defaults(handler=_check)

    verify = commands.add_parser("verify", help="simulated braking distances against the closed forms")
    verify.add_argument("--fmu", help="Simple FMU to verify (default: dist/fmi2/EgoVehicleSimple.fmu, built if missing)")
    verify.set_defaults(handler=_verify)
    return main


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        return args.handler(args)
    except (UsageError, BuildError) as error:
        print(f"sdl-fmu: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
