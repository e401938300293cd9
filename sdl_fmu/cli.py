"""The `sdl-fmu` command line: build, check, resolve, run, sweep, search, verify, export. It only parses arguments,
calls sdl_fmu.api and prints; every user mistake is one line per problem on stderr (exit 1: the scenario file, 2:
anything else), Ctrl-C is one line and exit 130. A sweep in which any run failed or timed out exits 3, after one line
on stderr saying how many and where their errors are. A reader that closes the pipe early (`| head`) ends it quietly
with exit 141, as the shell reports a program that SIGPIPE stopped."""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import sys
from pathlib import Path

from . import __version__, api
from . import search as searching
from . import sweep as sweeping
from .hold import hold_here
from .names import SHIPPED
from .options import DEFAULT_DRIVER_PERIOD, DEFAULT_STEP, DEFAULT_TEST_TIMEOUT, DRIVERS, ON_COLLISION, InputError
from .sdl import ScenarioError, describe
from .text import EscapingStream
from .units import length_label, speed_label

EXIT_SCENARIO, EXIT_USAGE, EXIT_RUNS_FAILED, EXIT_INTERRUPTED, EXIT_BROKEN_PIPE = 1, 2, 3, 130, 141
EXIT_TERMINATED = 143  # SIGTERM (`timeout`, `kill`): 128 + 15, as the shell reports it
EXIT_CRITERION_FAILED = 1  # verify --strict: a test pack's criterion failed
FMI_VERSIONS = ("2", "3")


class _Parser(argparse.ArgumentParser):
    """argparse with its errors as one line (no usage block) and no sys.exit from inside the library."""

    def error(self, message: str):
        raise _ArgumentError(f"{self.prog}: {message} (see {self.prog} --help)")


class _ArgumentError(Exception):
    pass


def _build(args) -> int:
    """Builds the FMUs into the per-user cache that `run` and `verify` use (what is there already is kept: the cache
    is keyed by every build input) and copies them to --out. Interrupted, or failing, it leaves no partial copy and
    no folder it made that stayed empty; the FMUs it printed are whole."""
    from .fmu.cache import cached_fmus  # the build side: CasADi and the compilers
    from .fmu.package import fmu_path

    names = list(SHIPPED) if args.dynamics == "all" else [args.dynamics]
    versions = tuple(map(int, FMI_VERSIONS)) if args.fmi_version == "all" else (int(args.fmi_version),)
    out = Path(args.out)
    made: list[Path] = []  # the folders this command made, outermost first
    written: list[Path] = []
    try:
        made += _made_by_mkdir(out)  # fails now rather than after compiling
        for dynamics in names:
            for version, cached in zip(versions, cached_fmus(dynamics, versions)):
                target = fmu_path(out, dynamics, version)
                made += _made_by_mkdir(target.parent)
                partial = target.with_suffix(".fmu.partial")
                try:
                    shutil.copyfile(cached, partial)
                    hold_here()  # the test hook (sdl_fmu/hold.py)
                    partial.replace(target)  # atomic: never a half-copied FMU
                finally:
                    partial.unlink(missing_ok=True)  # a full disk, Ctrl-C, SIGTERM: no partial copy is left
                written.append(target)
                print(target)
    except BaseException as error:
        for folder in reversed(made):
            try:
                folder.rmdir()  # only if it stayed empty
            except OSError:
                pass
        if isinstance(error, OSError):
            raise InputError("out", f"--out {args.out}: cannot write there: {error.strerror or error}") from None
        if isinstance(error, KeyboardInterrupt) and written:  # the FMUs printed above are whole and stay
            how = "terminated (SIGTERM)" if isinstance(error, Terminated) else "interrupted (Ctrl-C)"
            print(f"sdl-fmu: build {how}; only the FMUs listed above were written", file=sys.stderr)
            return EXIT_TERMINATED if isinstance(error, Terminated) else EXIT_INTERRUPTED
        raise
    return 0


def _made_by_mkdir(folder: Path) -> list[Path]:
    """Makes `folder` and its missing parents (an error if a file is in the way); returns those it made, outermost
    first."""
    missing = [path for path in (folder, *folder.parents) if not path.exists()][::-1]
    folder.mkdir(parents=True, exist_ok=True)
    return missing


def _check(args) -> int:
    checked = api.check(args.scenario, skip_unsupported=args.skip_unsupported, dynamics=args.dynamics,
                        vehicle=args.vehicle, tires=args.tires, set=_parse_settings(args.set))
    print(describe(checked.scenario))
    for warning in checked.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    return 0


def _assignments(assignments: list[str], option: str, meaning: str) -> dict[str, float]:
    """NAME=VALUE ... (each VALUE a number) as {NAME: VALUE}; a malformed one is an InputError naming `option`."""
    values = {}
    for assignment in assignments:
        name, separator, value = assignment.partition("=")
        try:
            if not separator or not name.strip():
                raise ValueError
            values[name.strip()] = float(value)
        except ValueError:
            raise InputError(option, "", subject=f"{assignment}: expected NAME=VALUE with a number "
                                                 f"({meaning})") from None
    return values


def _parse_parameters(assignments: list[str]) -> dict[str, float]:
    """--param NAME=VALUE ...: FMU start values, SI."""
    return _assignments(assignments, "params", "SI units")


def _parse_settings(assignments: list[str]) -> dict[str, float]:
    """--set NAME=VALUE ...: scenario parameters (a declared name or an address), in the file's units."""
    return _assignments(assignments, "set", "a scenario parameter or an address LINE.N, in the file's units")


def _resolve(args) -> int:
    settings = _parse_settings(args.set)
    if args.out is None:
        sys.stdout.write(api.resolve(args.scenario, settings, skip_unsupported=args.skip_unsupported))
        return 0
    print(api.write_resolved(args.scenario, args.out, settings, skip_unsupported=args.skip_unsupported))
    return 0


def _run(args) -> int:
    out = Path(args.out) if args.out is not None else Path("runs") / api.resolve_scenario(args.scenario).stem
    result = api.run(args.scenario, dynamics=args.dynamics, fmu=args.fmu, vehicle=args.vehicle, speed=args.speed,
                     seed=args.seed, step=args.step, driver_period=args.driver_period,
                     until_distance=args.until_distance, until_time=args.until_time,
                     params=_parse_parameters(args.param), tires=args.tires, skip_unsupported=args.skip_unsupported,
                     progress=None, out=out, plot=not args.no_plot, controller=args.controller,
                     controller_map=args.controller_map, driver=args.driver, on_collision=args.on_collision,
                     set=_parse_settings(args.set))
    scenario = result.scenario
    units, final = scenario.units, result.final
    print(f"{Path(scenario.path).name}: {result.raw.dynamics} dynamics, {result.collisions} collision(s), "
          f"ended at {final['time_s']:.2f} s, distance {final['distance']:.1f} {length_label(units)}, "
          f"speed {final['speed']:.1f} {speed_label(units)}")
    for warning in result.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    print(f"results: {out / 'timeseries.csv'}, {out / 'summary.json'}")
    if not args.no_plot:
        print(f"plot: {out / 'plot.png'}")
    return 0


def _fixed_options(args) -> dict:
    """sweep's and search's options that hold for every run, as api.run's keywords."""
    fixed = {"dynamics": args.dynamics} if args.dynamics else {}
    if args.fmu:
        fixed["fmu"] = args.fmu
    if args.vehicle:
        fixed["vehicle"] = args.vehicle
    if args.param:
        fixed["params"] = _parse_parameters(args.param)
    if args.tires:
        fixed["tires"] = args.tires
    for option in ("until_time", "until_distance"):
        if getattr(args, option) is not None:
            fixed[option] = getattr(args, option)
    for option in ("controller", "controller_map"):
        if getattr(args, option):
            fixed[option] = getattr(args, option)
    if args.driver != "lane":
        fixed["driver"] = args.driver
    if args.on_collision != "continue":
        fixed["on_collision"] = args.on_collision
    if args.skip_unsupported:
        fixed["skip_unsupported"] = True
    return fixed


def _sweep(args) -> int:
    fixed = _fixed_options(args)
    scenario = api.resolve_scenario(args.scenario)
    # the scenario's declared ranges and whole parameters shape the values (lhs(n), normal truncated to the range)
    declared = api.load(scenario, skip_unsupported=args.skip_unsupported, dynamics=args.dynamics, vehicle=args.vehicle)
    varied = sweeping.parse_vary(args.vary, args.sample_seed, declared)
    joint = sweeping.lhs_names(args.vary)
    if args.rerun is not None:
        return _rerun(args, scenario, varied, joint, fixed)
    out = Path(args.out) if args.out is not None else Path("sweeps") / scenario.stem
    try:
        rows = sweeping.sweep(str(scenario), varied, out, workers=args.workers, scheduler=args.scheduler,
                              timeout=args.timeout, progress=None, joint=joint, sort=args.sort, **fixed)
    except KeyboardInterrupt as stop:
        how = "terminated (SIGTERM)" if isinstance(stop, Terminated) else "interrupted (Ctrl-C)"
        if (out / sweeping.JOURNAL_NAME).exists():
            print(f"sdl-fmu: sweep {how}; the finished runs are in {out / sweeping.JOURNAL_NAME}: "
                  "the same command resumes the sweep", file=sys.stderr)
        else:
            print(f"sdl-fmu: sweep {how}; nothing was written", file=sys.stderr)
        return EXIT_TERMINATED if isinstance(stop, Terminated) else EXIT_INTERRUPTED
    table = out / sweeping.CSV_NAME
    failures = sweeping.failure_line(rows, table)
    if failures is not None and all(row.get("status") != "ok" for row in rows):
        print(f"sdl-fmu: {failures}", file=sys.stderr)
        return EXIT_RUNS_FAILED
    counts = {status: sum(row.get("status") == status for row in rows) for status in sweeping.STATUSES}
    print(f"{scenario.name}: {len(rows)} runs: {counts['ok']} ok, {counts['failed']} failed, "
          f"{counts['timeout']} timed out")
    print(f"table: {out / sweeping.TABLE_NAME}, {table}")
    if args.sort is not None:
        column, descending = sweeping.sort_column(args.sort, declared, None, varied)
        column = next((key for key in (rows[0] if rows else {}) if key == column or key.startswith(f"{column}_")),
                      column)  # an FMU parameter's column carries the unit its FMU declares
        first = ", ".join(f"run {row['run']} ({column} {row[column]:.6g})" for row in rows[:3]
                          if isinstance(row.get(column), (int, float)))
        print(f"ranked by {column} ({'descending' if descending else 'ascending'}): {first or 'no run has it'}; "
              "the same command with --rerun RUN --out DIR runs one again")
    print(f"plot: {out / sweeping.PLOT_NAME}")
    if failures is not None:
        print(f"sdl-fmu: {failures}; the same command runs them again", file=sys.stderr)
        return EXIT_RUNS_FAILED
    return 0


def _search(args) -> int:
    ranges = searching.parse_ranges(args.vary)
    objective = searching.objective_of(args.minimize, args.maximize, args.spec)
    fixed = _fixed_options(args)
    scenario = api.resolve_scenario(args.scenario)
    out = Path(args.out)
    sweeping.check_workers(args.workers)
    sweeping.check_scheduler(args.scheduler)
    try:
        found = searching.search(str(scenario), ranges, out, objective=objective, budget=args.budget,
                                 method=args.method, seed=args.seed, workers=args.workers, scheduler=args.scheduler,
                                 timeout=args.timeout, progress=None, **fixed)
    except KeyboardInterrupt as stop:
        how = "terminated (SIGTERM)" if isinstance(stop, Terminated) else "interrupted (Ctrl-C)"
        if (out / searching.JOURNAL_NAME).exists():
            print(f"sdl-fmu: search {how}; the finished trials are in {out / searching.JOURNAL_NAME}: "
                  "the same command resumes the search", file=sys.stderr)
        else:
            print(f"sdl-fmu: search {how}; nothing was written", file=sys.stderr)
        return EXIT_TERMINATED if isinstance(stop, Terminated) else EXIT_INTERRUPTED
    rows, worst = found.rows, found.worst
    ok = sum(row["status"] == "ok" for row in rows)
    print(f"{scenario.name}: {len(rows)} trials ({ok} ok), {objective.direction} {objective.label}")
    if worst is None:
        print(f"sdl-fmu: no trial gave an objective ({out / searching.CSV_NAME}, columns status, error, objective)",
              file=sys.stderr)
        return EXIT_RUNS_FAILED
    values = ", ".join(f"{name}={value!r}" for name, value in found.values.items())
    print(f"worst: trial {worst['trial']}, objective {worst['objective']!r} ({values})")
    print(f"worst case: {out / searching.WORST_SDL}, its results {out / searching.WORST_FOLDER}; "
          f"again: {' '.join(found.command)}")
    if not found.reproduced:
        print("warning: the worst case run again gave another objective (search.json: worst)", file=sys.stderr)
    print(f"table: {out / searching.TABLE_NAME}, {out / searching.CSV_NAME}")
    print(f"report: {out / searching.REPORT_NAME}, plot: {out / searching.PLOT_NAME}")
    return 0


def _rerun(args, scenario: Path, varied: dict, joint: list, fixed: dict) -> int:
    """sweep ... --rerun K --out DIR: run K of that sweep alone, into a results folder (as `run` writes one)."""
    out = Path(args.out) if args.out is not None else Path("runs") / f"{scenario.stem}-run{args.rerun}"
    result, values = sweeping.rerun(str(scenario), varied, args.rerun, out, joint=joint, **fixed)
    units, final = result.scenario.units, result.final
    print(f"{scenario.name} run {args.rerun} ({', '.join(f'{k}={v:g}' for k, v in values.items())}): "
          f"{result.raw.dynamics} dynamics, {result.collisions} collision(s), ended at {final['time_s']:.2f} s, "
          f"distance {final['distance']:.1f} {length_label(units)}, speed {final['speed']:.1f} {speed_label(units)}")
    for warning in result.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    print(f"results: {out / 'timeseries.csv'}, {out / 'summary.json'}")
    resolve, rest = sweeping.row_commands(str(scenario), values, result.scenario)
    print(f"its scenario as plain SDL: {resolve}" + (f" (then sdl-fmu run FILE {rest})" if rest else ""))
    return 0


def _verify(args) -> int:
    only = None if args.only is None else [name.strip() for name in args.only.split(",") if name.strip()]
    out = Path(args.out) if args.out is not None else Path("verify") / _verify_folder_name(args)
    try:
        result = api.verify(dynamics=args.dynamics, fmu=args.fmu, vehicle=args.vehicle, only=only, out=out,
                            pack=args.pack, params=_parse_parameters(args.param), controller=args.controller,
                            controller_map=args.controller_map, workers=args.workers, scheduler=args.scheduler,
                            test_timeout=args.test_timeout, progress=None)
    except KeyboardInterrupt as stop:
        from .verify.aeb.kept import JOURNAL_NAME

        kept = out / JOURNAL_NAME
        if args.pack == "vehicle" or not kept.is_file():
            raise  # nothing was written
        how = "terminated (SIGTERM)" if isinstance(stop, Terminated) else "interrupted (Ctrl-C)"
        print(f"sdl-fmu: verify {how}; the finished tests are in {kept}: the same command resumes the pack",
              file=sys.stderr)
        return EXIT_TERMINATED if isinstance(stop, Terminated) else EXIT_INTERRUPTED
    print(f"{result.vehicle['name']} ({Path(result.vehicle['fmu']).name}, GUID {result.vehicle['guid']})")
    print(result.table)
    print(f"results: {result.folder / 'verify.json'}, {result.folder / 'report.html'}")
    if args.strict and not result.passed:
        print(f"sdl-fmu: verify --strict: a criterion failed (see {result.folder / 'verify.json'})", file=sys.stderr)
        return EXIT_CRITERION_FAILED
    return 0


def _export(args) -> int:
    result = api.export(args.scenario, out=args.out, dynamics=args.dynamics, fmu=args.fmu, vehicle=args.vehicle,
                        speed=args.speed, seed=args.seed, until_distance=args.until_distance,
                        until_time=args.until_time, step=args.step, fmi_version=int(args.fmi_version),
                        skip_unsupported=args.skip_unsupported, controller=args.controller,
                        controller_map=args.controller_map, driver=args.driver, on_collision=args.on_collision)
    for warning in result.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    fmus = ", ".join(f"{component} {path.name}" for component, path in result.fmus.items())
    print(f"{result.ssp}: {fmus} (also beside it); FMI {result.fmi_version}.0, step {result.step:g} s, stop time "
          f"{result.stop_time:g} s, parameter set '{result.parameter_set}'")
    print("run it in libcosim, ecos or fmpy: docs/export.md")
    return 0


def _verify_folder_name(args) -> str:
    if args.fmu is not None:
        name = Path(args.fmu).stem
    elif args.vehicle is not None:
        name = Path(args.vehicle).stem
    else:
        name = args.dynamics or "simple"
    return name if args.pack == "vehicle" else f"{name}-{args.pack}"


def _float_argument(text: str) -> float:
    """argparse type for real options; the range checks (finite, limits) are the API's."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None


DESCRIPTION = "Vehicle-dynamics FMUs (FMI 2.0 and 3.0) co-simulated with STISIM-style SDL traffic scenarios."
EPILOG = """\
'sdl-fmu command --help' shows a command's options. Try: sdl-fmu run demo
exit codes: 0 done, 1 the scenario file is wrong (verify --strict: a criterion failed), 2 another user mistake,
            3 a sweep with failed runs, 130 Ctrl-C, 141 the output pipe was closed early (e.g. by head), 143 SIGTERM"""


def _set_argument(command) -> None:
    command.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                         help="a scenario parameter: a NAME the file declares (// @param NAME = VALUE) or an address "
                              "LINE.N (parameter N of the event on line LINE, 0 its distance), in the file's units "
                              "(repeatable)")


def _loop_arguments(command, every: str = "") -> None:
    """run's and sweep's options of what drives the ego: a controller in the loop, the built-in driver, collisions."""
    command.add_argument("--controller", metavar="FMU", help=f"controller FMU in the loop{every} (AEB, ACC, ...; "
                         "default: the controller map's fmu), or example-aeb (the shipped example AEB and its map)")
    command.add_argument("--controller-map", metavar="CMAP", help="controller map (TOML): its signals, requests, "
                         "period and arbitration (docs/controllers.md)")
    command.add_argument("--driver", choices=DRIVERS, default="lane",
                         help="built-in driver: lane (default: holds its lane and speed, ignores traffic) or follow "
                              "(also follows the vehicle ahead: Gipps' car-following law)")
    command.add_argument("--on-collision", choices=ON_COLLISION, default="continue",
                         help="continue (default) or stop: end the run at the first contact")


def parser() -> argparse.ArgumentParser:
    main = _Parser(prog="sdl-fmu", description=DESCRIPTION, epilog=EPILOG,
                   formatter_class=argparse.RawDescriptionHelpFormatter)
    main.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    commands = main.add_subparsers(dest="command", required=True, parser_class=_Parser, title="commands",
                                   metavar="command")

    build = commands.add_parser("build", help="build the ego-vehicle FMUs (into the cache run uses; exported)")
    build.add_argument("--dynamics", choices=[*SHIPPED, "all"], default="all",
                       help="which model's FMUs: simple, advanced or all (default: all)")
    build.add_argument("--fmi-version", choices=[*FMI_VERSIONS, "all"], default="all",
                       help="FMI version of the FMUs: 2, 3 or all (default: all, into OUT/fmi2/ and OUT/fmi3/)")
    build.add_argument("--out", default="dist", help="output folder (default: dist)")
    build.set_defaults(handler=_build)

    check = commands.add_parser("check", help="parse a scenario and report, run nothing")
    check.add_argument("scenario", help="SDL file, or the name of a shipped example such as demo")
    check.add_argument("--dynamics", choices=SHIPPED,
                       help="check for this shipped model, as run --dynamics does (default simple; advanced: RSA "
                            "values are whole surface attribute numbers, BRK is ignored); not with --vehicle")
    check.add_argument("--vehicle", help="check for this vehicle map (TOML), as run --vehicle does")
    check.add_argument("--tires", help="Tire Attribute File, as run --tires (advanced dynamics)")
    check.add_argument("--skip-unsupported", action="store_true",
                       help="skip lines sdl-fmu does not simulate (one warning per code)")
    _set_argument(check)
    check.set_defaults(handler=_check)

    resolve = commands.add_parser("resolve", help="the plain SDL with the scenario's parameters in place")
    resolve.add_argument("scenario", help="SDL file, or the name of a shipped example such as demo")
    _set_argument(resolve)
    resolve.add_argument("--skip-unsupported", action="store_true",
                         help="read a file with lines sdl-fmu does not simulate (they are kept as they are)")
    resolve.add_argument("--out", metavar="FILE", help="a new file to write (never replaced; default: stdout)")
    resolve.set_defaults(handler=_resolve)

    run = commands.add_parser("run", help="co-simulate a scenario against the ego FMU")
    run.add_argument("scenario", help="SDL file, or the name of a shipped example such as demo")
    run.add_argument("--dynamics", choices=SHIPPED, help="a shipped model: simple (default; friction "
                     "coefficients) or advanced (Magic Formula tires); not with --vehicle")
    run.add_argument("--fmu", help="ego FMU (default: the cached build for --dynamics, built on first use)")
    run.add_argument("--vehicle", help="vehicle map (TOML) driving --fmu, any FMI 2.0/3.0 vehicle FMU")
    run.add_argument("--speed", type=_float_argument,
                     help="driver's start and target speed, scenario units (default 88 ft/s)")
    run.add_argument("--seed", type=int, default=1, help="seed of the random vehicle models (default 1)")
    run.add_argument("--step", type=_float_argument, help=f"longest communication step, s (default {DEFAULT_STEP:g}); "
                     "triggers are located exactly at any step; driver samples and triggers cut steps shorter")
    run.add_argument("--driver-period", type=_float_argument,
                     help=f"the driver model's sampling period, s (default {DEFAULT_DRIVER_PERIOD:g})")
    run.add_argument("--until-distance", type=_float_argument, help="end at this distance, scenario units")
    run.add_argument("--until-time", type=_float_argument, help="end at this time, s")
    run.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                     help="FMU start value, SI, within its declared min/max (repeatable)")
    _set_argument(run)
    run.add_argument("--tires", help="Tire Attribute File (advanced dynamics)")
    run.add_argument("--skip-unsupported", action="store_true",
                     help="skip lines sdl-fmu does not simulate (one warning per code)")
    _loop_arguments(run)
    run.add_argument("--no-plot", action="store_true", help="write no plot.png (the run and its files only)")
    run.add_argument("--out", help="results folder: new, empty, or an earlier run's results folder "
                                   "(default: runs/<scenario name>)")
    run.set_defaults(handler=_run)

    sweep = commands.add_parser("sweep", help="many runs over varied values on Dask, one table of summaries")
    sweep.add_argument("scenario", help="SDL file, or the name of a shipped example such as demo")
    sweep.add_argument("--vary", action="append", default=[], metavar="NAME=VALUES", required=True,
                       help="speed, seed, until_distance, until_time, a scenario parameter ($NAME, LINE.N, rsa.LINE"
                            "[.LANE]) or an FMU parameter (param.NAME); VALUES: a,b,c | start:stop:step | "
                            "uniform(lo,hi,n) | integers(lo,hi,n) | normal(mu,sigma,n) | choice(a,b,...,n) | "
                            "lhs(lo,hi,n); with a declared range also uniform(n), lhs(n)")
    sweep.add_argument("--sort", metavar="MEASURE[:desc]", help="rank the table by this column (min_ttc_s, "
                       "collisions, ...), ascending, or descending with :desc; a rank column first")
    sweep.add_argument("--rerun", type=int, metavar="K", help="run K of this sweep (the table's run) again, alone, "
                       "into --out as a run's results folder (default runs/<scenario>-runK)")
    where = sweep.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, help="worker processes of a local Dask cluster (default: one per core)")
    where.add_argument("--scheduler", help="address of an existing Dask scheduler (tcp://host:port)")
    sweep.add_argument("--dynamics", choices=SHIPPED, help="a shipped model for every run: simple (default) or "
                       "advanced; not with --vehicle")
    sweep.add_argument("--fmu", help="ego FMU (default: the cached build for --dynamics)")
    sweep.add_argument("--vehicle", help="vehicle map (TOML) driving --fmu, any FMI 2.0/3.0 vehicle FMU")
    sweep.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                       help="FMU start value for every run, SI (repeatable)")
    sweep.add_argument("--tires", help="Tire Attribute File for every run (advanced dynamics)")
    sweep.add_argument("--until-distance", type=_float_argument,
                       help="end every run at this distance, scenario units (or vary until_distance)")
    sweep.add_argument("--until-time", type=_float_argument, help="end every run at this time, s (or vary until_time)")
    sweep.add_argument("--sample-seed", type=int, default=0, help="seed of the random values (uniform, integers, "
                       "normal, choice, lhs; default 0)")
    sweep.add_argument("--timeout", type=_float_argument, default=600.0,
                       help="wall-clock limit per run, s (default 600)")
    sweep.add_argument("--skip-unsupported", action="store_true",
                       help="skip lines sdl-fmu does not simulate (one warning per code)")
    _loop_arguments(sweep, " for every run")
    sweep.add_argument("--out", help="table folder: new, empty or an interrupted sweep's (resumed); "
                                     "default sweeps/<scenario name>")
    sweep.set_defaults(handler=_sweep)

    search = commands.add_parser("search", help="the worst case within ranges: an optimiser's trials on Dask")
    search.add_argument("scenario", help="SDL file, or the name of a shipped example such as demo")
    search.add_argument("--vary", action="append", default=[], metavar="NAME=LOW..HIGH", required=True,
                        help="a name a sweep varies (speed, seed, until_time, an FMU parameter, rsa.LINE[.LANE]) and "
                             "its range")
    goal = search.add_mutually_exclusive_group(required=True)
    goal.add_argument("--minimize", metavar="MEASURE", help="a measure of the run to make small (min_ttc_s, "
                      "min_distance, A1_min_distance, ...: docs/search.md)")
    goal.add_argument("--maximize", metavar="MEASURE", help="a measure of the run to make large (impact_speed, "
                      "collisions, max_drac, ...)")
    goal.add_argument("--spec", metavar="STL", help="a signal temporal logic formula over timeseries.csv's columns "
                      "(rtamt): its robustness is made small (negative: violated)")
    search.add_argument("--budget", type=int, required=True, help="trials (runs) in all, a resumed search's included")
    search.add_argument("--method", choices=searching.METHODS, default="tpe",
                        help="tpe (default: optuna's TPE), cmaes (CMA-ES) or random")
    search.add_argument("--seed", type=int, default=0, help="seed of the optimiser (default 0)")
    where = search.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, help="worker processes of a local Dask cluster (default: one per core)")
    where.add_argument("--scheduler", help="address of an existing Dask scheduler (tcp://host:port)")
    search.add_argument("--dynamics", choices=SHIPPED, help="a shipped model for every run: simple (default) or "
                        "advanced; not with --vehicle")
    search.add_argument("--fmu", help="ego FMU (default: the cached build for --dynamics)")
    search.add_argument("--vehicle", help="vehicle map (TOML) driving --fmu, any FMI 2.0/3.0 vehicle FMU")
    search.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="FMU start value for every run, SI (repeatable)")
    search.add_argument("--tires", help="Tire Attribute File for every run (advanced dynamics)")
    search.add_argument("--until-distance", type=_float_argument, help="end every run at this distance, scenario "
                        "units")
    search.add_argument("--until-time", type=_float_argument, help="end every run at this time, s")
    search.add_argument("--timeout", type=_float_argument, default=600.0,
                        help="wall-clock limit per run, s (default 600)")
    search.add_argument("--skip-unsupported", action="store_true",
                        help="skip lines sdl-fmu does not simulate (one warning per code)")
    _loop_arguments(search, " for every run")
    search.add_argument("--out", required=True, help="search folder: new, empty or an earlier search's (resumed, "
                                                     "or continued to a larger --budget)")
    search.set_defaults(handler=_search)

    verify = commands.add_parser("verify", help="a test pack: vehicle manoeuvres or AEB car-to-car, report")
    verify.add_argument("--pack", choices=api.PACKS, default="vehicle",
                        help="vehicle (default): the vehicle test pack; aeb-ccr: the AEB car-to-car rear grid")
    verify.add_argument("--dynamics", choices=SHIPPED, help="a shipped model: simple (default) or advanced")
    verify.add_argument("--fmu", help="vehicle FMU (default: the cached build of --dynamics)")
    verify.add_argument("--vehicle", help="vehicle map (TOML) driving --fmu")
    verify.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="vehicle FMU start value, SI, within its declared min/max (repeatable)")
    verify.add_argument("--controller", help="aeb-ccr: controller FMU in the loop, or example-aeb (the shipped "
                        "example AEB); default: none (the vehicle alone)")
    verify.add_argument("--controller-map", help="aeb-ccr: controller map (TOML) of --controller")
    verify.add_argument("--only", metavar="NAME,...", help="run only these manoeuvres (braking, "
                        "steady_state_circular, step_steer, sine_with_dwell, split_mu_braking, double_lane_change) "
                        "or, with --pack aeb-ccr, test groups (CCRs, CCRm, CCRb)")
    where = verify.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, help="aeb-ccr: worker processes of a local Dask cluster (default: one "
                       "per core; 0: in this process)")
    where.add_argument("--scheduler", help="aeb-ccr: address of an existing Dask scheduler (tcp://host:port)")
    verify.add_argument("--test-timeout", type=_float_argument, metavar="S",
                        help=f"aeb-ccr: wall-clock limit of one test, s (default {DEFAULT_TEST_TIMEOUT:g}); a test "
                        "that outlasts it ends as timed out")
    verify.add_argument("--strict", action="store_true", help="exit 1 when a criterion fails (a manoeuvre fails; "
                        "aeb-ccr: a test scores less than its full points)")
    verify.add_argument("--out", help="results folder: new, empty, or an earlier verify folder "
                                      "(default: verify/<vehicle>, verify/<vehicle>-aeb-ccr)")
    verify.set_defaults(handler=_verify)

    export = commands.add_parser("export", help="the scenario as an FMU and an SSP that FMI masters run")
    export.add_argument("scenario", help="SDL file, or the name of a shipped example such as demo")
    export.add_argument("--dynamics", choices=SHIPPED, help="a shipped model: simple (default) or advanced; not "
                        "with --vehicle")
    export.add_argument("--fmu", help="ego FMU (default: the cached build of --dynamics)")
    export.add_argument("--vehicle", help="vehicle map (TOML) driving --fmu, any FMI 2.0/3.0 vehicle FMU")
    export.add_argument("--controller", metavar="FMU", help="controller FMU between the scenario and the ego, a third "
                        "component of the SSP (default: the controller map's fmu)")
    export.add_argument("--controller-map", metavar="CMAP", help="controller map (TOML): its signals, requests and "
                        "arbitration (docs/controllers.md)")
    export.add_argument("--driver", choices=DRIVERS, default="lane",
                        help="built-in driver: lane (default: holds its lane and speed, ignores traffic) or follow "
                             "(also follows the vehicle ahead: Gipps' car-following law)")
    export.add_argument("--on-collision", choices=ON_COLLISION, default="continue",
                        help="continue (default) or stop: the scenario ends at the first contact")
    export.add_argument("--speed", type=_float_argument,
                        help="driver's start and target speed, scenario units (default 88 ft/s)")
    export.add_argument("--seed", type=int, default=1, help="seed of the random vehicle models (default 1)")
    end = export.add_mutually_exclusive_group()
    end.add_argument("--until-distance", type=_float_argument, help="end at this distance, scenario units")
    end.add_argument("--until-time", type=_float_argument, help="end at this time, s")
    export.add_argument("--step", type=_float_argument, help="the system's communication step, s (default 0.01)")
    export.add_argument("--fmi-version", choices=FMI_VERSIONS, default="2",
                        help="FMI version of the scenario FMU and of a shipped ego FMU (default 2: libcosim and fmpy "
                             "run FMI 2.0 only)")
    export.add_argument("--skip-unsupported", action="store_true",
                        help="skip lines sdl-fmu does not simulate (one warning per code)")
    export.add_argument("--out", required=True, help="export folder: new, empty, or an earlier export folder")
    export.set_defaults(handler=_export)
    return main


def _is_build_error(error: Exception) -> bool:
    """Whether an FMU could not be built (fmu.package.BuildError: no compiler, a failing compile). The build side
    (CasADi) is imported only by a command that builds: if it was never imported, nothing was built."""
    package = sys.modules.get("sdl_fmu.fmu.package")
    return package is not None and isinstance(error, package.BuildError)


class Terminated(KeyboardInterrupt):
    """SIGTERM, handled as Ctrl-C is (everything sdl-fmu started is ended, nothing half-written is left)."""


def _stop(signum, frame):
    """Ctrl-C or SIGTERM: raised once; a repeat while sdl-fmu cleans up is ignored (`timeout` signals the command and
    then its whole process group, so the command gets the signal twice), so the clean-up is never cut short."""
    for repeated in (signal.SIGINT, signal.SIGTERM):
        signal.signal(repeated, signal.SIG_IGN)
    raise Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


def main(argv: list[str] | None = None) -> int:
    """Runs one command; returns the exit code (0 ok, 1 scenario file, 2 other mistakes, 3 a sweep with failed
    runs, 130 Ctrl-C, 141 closed output pipe, 143 SIGTERM). Everything it prints has its terminal control
    characters escaped (names come from files and FMUs)."""
    streams = sys.stdout, sys.stderr
    sys.stdout, sys.stderr = EscapingStream(sys.stdout), EscapingStream(sys.stderr)
    previous = {}
    try:
        for number in (signal.SIGINT, signal.SIGTERM):
            if signal.getsignal(number) is not signal.SIG_IGN:  # ignored by the caller: stays so
                previous[number] = signal.signal(number, _stop)
    except ValueError:  # not the main thread: the signals keep their actions
        pass
    try:
        return _main(argv)
    finally:
        sys.stdout, sys.stderr = streams
        for number, action in previous.items():
            if signal.getsignal(number) is _stop:  # after a stop they stay ignored, through the exit's clean-up
                signal.signal(number, action)


def _main(argv: list[str] | None) -> int:
    try:
        try:
            args = parser().parse_args(argv)
        except _ArgumentError as error:
            print(error, file=sys.stderr)
            return EXIT_USAGE
        except SystemExit as exit:  # --help, --version
            sys.stdout.flush()
            return exit.code if isinstance(exit.code, int) else EXIT_USAGE
        try:
            code = args.handler(args)
        except ScenarioError as error:
            print(error, file=sys.stderr)
            return EXIT_SCENARIO
        except InputError as error:
            print(f"sdl-fmu: {error.command_line()}", file=sys.stderr)
            return EXIT_USAGE
        except sweeping.ClusterError as error:  # a SweepError, or the cluster options (--workers, --scheduler)
            print(f"sdl-fmu: {error}", file=sys.stderr)
            return EXIT_USAGE
        except Exception as error:
            if not _is_build_error(error):
                raise
            print(f"sdl-fmu: {error}", file=sys.stderr)
            return EXIT_USAGE
        sys.stdout.flush()  # here, so that a closed pipe is caught below rather than at interpreter exit
        return code
    except Terminated:
        print("sdl-fmu: terminated (SIGTERM); nothing was written", file=sys.stderr)
        return EXIT_TERMINATED
    except KeyboardInterrupt:
        print("sdl-fmu: interrupted (Ctrl-C); nothing was written", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # stdout closed early (`sdl-fmu check demo | head -1`): stop quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # so the exit flush cannot fail again
        return EXIT_BROKEN_PIPE


if __name__ == "__main__":
    sys.exit(main())
