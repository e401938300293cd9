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


def _load_scenario(path: str):
    """The parsed scenario and the vehicle table; every problem in the file raises ScenarioError."""
    from .sdl import ScenarioError, check_models, default_vehicle_table_path, load_scenario, load_vehicle_table

    scenario = load_scenario(path)
    table = load_vehicle_table(default_vehicle_table_path())
    problems = check_models(scenario, table)
    if problems:
        raise ScenarioError(problems)
    return scenario, table


def _check(args) -> int:
    from .sdl import describe

    scenario, _ = _load_scenario(args.scenario)
    print(describe(scenario))
    return 0


def _parse_parameters(assignments: list[str]) -> dict[str, float]:
    parameters = {}
    for assignment in assignments:
        name, separator, value = assignment.partition("=")
        try:
            if not separator or not name:
                raise ValueError
            parameters[name.strip()] = float(value)
        except ValueError:
            raise UsageError(f"--param {assignment!r}: expected NAME=VALUE with a number (SI units)") from None
    return parameters


def _ego_fmu(args) -> Path:
    if args.fmu:
        path = Path(args.fmu)
        if not path.exists():
            raise UsageError(f"--fmu {args.fmu}: no such file")
        return path
    path = fmu_path(Path("dist"), args.dynamics)
    if not path.exists():
        print(f"building {path} (first use)", file=sys.stderr)
        build_fmu(args.dynamics, Path("dist"))
    return path


def _run(args) -> int:
    from .cosim.ego import FmuError
    from .cosim.master import RunOptions, run_scenario
    from .results import write_results
    from .units import length_label, speed_label, to_si

    scenario, table = _load_scenario(args.scenario)
    units = scenario.units
    for name in ("speed", "until_distance", "until_time", "step", "driver_period"):
        value = getattr(args, name)
        if value is not None and (value <= 0 if name != "speed" else value < 0):
            raise UsageError(f"--{name.replace('_', '-')} {value:g}: must be {'>= 0' if name == 'speed' else '> 0'}")
    options = RunOptions(
        dynamics=args.dynamics,
        speed=None if args.speed is None else to_si(args.speed, units),
        seed=args.seed,
        **({"step": args.step} if args.step is not None else {}),
        **({"driver_period": args.driver_period} if args.driver_period is not None else {}),
        until_distance=None if args.until_distance is None else to_si(args.until_distance, units),
        until_time=args.until_time,
        parameters=_parse_parameters(args.param),
    )
    if args.dynamics == "advanced":
        from .dynamics.tires import default_attribute_file, slot_parameters

        try:
            starts, attribute_slots, tire_warnings = slot_parameters(Path(args.tires) if args.tires
                                                                      else default_attribute_file())
        except ValueError as error:
            raise UsageError(str(error)) from None
        options.tire_parameters = starts
        options.known_attributes = set(attribute_slots)
    elif args.tires:
        raise UsageError("--tires applies to --dynamics advanced only")
    out = Path(args.out) if args.out else Path("runs") / Path(args.scenario).stem
    try:
        result = run_scenario(scenario, _ego_fmu(args), options, table)
    except FmuError as error:
        raise UsageError(str(error)) from None
    if args.dynamics == "advanced":
        result.warnings[:0] = tire_warnings
    write_results(result, out)
    final = result.final
    print(f"{Path(args.scenario).name}: {args.dynamics} dynamics, {result.collisions} collision(s), "
          f"ended at {final['time_s']:.2f} s, distance {final['distance']:.1f} {length_label(units)}, "
          f"speed {final['speed']:.1f} {speed_label(units)}")
    for warning in result.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    print(f"results: {out / 'timeseries.csv'}, {out / 'summary.json'}")
    print(f"plot: {out / 'plot.png'}")
    return 0


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

    run = commands.add_parser("run", help="co-simulate a scenario against the ego FMU")
    run.add_argument("scenario")
    run.add_argument("--dynamics", choices=list(MODELS), default="simple")
    run.add_argument("--fmu", help="ego FMU (default: dist/fmi2/<Model>.fmu, built on first use)")
    run.add_argument("--speed", type=float, help="driver's start and target speed, scenario units (default 88 ft/s)")
    run.add_argument("--seed", type=int, default=1, help="seed of the random vehicle models (default 1)")
    run.add_argument("--step", type=float, help="longest communication step, s (default 1; triggers are exact at "
                     "any step, driver samples and triggers cut steps shorter)")
    run.add_argument("--driver-period", type=float, help="the driver model's sampling period, s (default 0.05)")
    run.add_argument("--until-distance", type=float, help="end at this distance, scenario units")
    run.add_argument("--until-time", type=float, help="end at this time, s")
    run.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                     help="FMU start value, SI (repeatable)")
    run.add_argument("--tires", help="Tire Attribute File (advanced dynamics)")
    run.add_argument("--out", help="results folder (default: runs/<scenario name>)")
    run.set_defaults(handler=_run)

    verify = commands.add_parser("verify", help="simulated braking distances against the closed forms")
    verify.add_argument("--fmu", help="Simple FMU to verify (default: dist/fmi2/EgoVehicleSimple.fmu, built if missing)")
    verify.set_defaults(handler=_verify)
    return main


def main(argv: list[str] | None = None) -> int:
    from .sdl import ScenarioError

    args = parser().parse_args(argv)
    try:
        return args.handler(args)
    except ScenarioError as error:
        print(error, file=sys.stderr)
        return 1
    except (UsageError, BuildError) as error:
        print(f"sdl-fmu: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
