"""Sweeps: many runs of one scenario over varied values, on Dask `distributed`, into one table.

    sdl-fmu sweep SCENARIO --vary NAME=VALUES ... [--workers N | --scheduler ADDRESS] [--out DIR]

NAME is `speed` (scenario units), `seed`, `until_distance` (scenario units), `until_time` (s), a scenario parameter
(a declared `NAME` or `$NAME`, an address `LINE.N`, `rsa.LINE[.LANE]`: api.value_target) or an FMU parameter (SI,
e.g. `brake_decel_max`, or `param.NAME`). VALUES is a grid or random values (distributions.py: `a,b,c`,
`start:stop:step`, `uniform`, `integers`, `normal`, `choice`, `lhs`, drawn from `--sample-seed`). The runs are every
combination of the varied values (a Latin hypercube's columns zipped). Each run goes through sdl_fmu.api
(api.apply_values, then api.run); every name and scenario value is checked before any cluster is contacted
(preflight). `--sort` ranks the table (rank()), `--rerun K` runs one row again alone (rerun()).

Every file a run reads (the scenario, the FMU, the Tire Attribute File and the tire files it names: the
options in SHIPPED) goes to the workers as bytes, through Dask (shipping.py): a future per file bundle, which Dask
keeps and recomputes if the worker holding it dies. A worker writes each bundle once into its own FMU cache,
under shipped/<hash of the contents>/, so a worker needs no shared folder and no FMU of its own.

The table (DIR/sweep.parquet and DIR/sweep.csv, one row per run) holds the varied values, the status
(ok, failed, timeout) and error, collisions, per BRK event its on/off times, reason and the distance
travelled while it held (a stop distance when it ended with the stop), the minimum longitudinal gap to
each traffic vehicle, the final state, the wall time and real-time factor; every column with a unit
names it (`final_distance_ft`, `brk1_on_time_s`). Every finished row is appended to DIR/sweep-rows.jsonl
at once, so an interrupted sweep resumes from it: `ok` rows there are kept, `failed` and `timeout` rows
are run again. A run that fails is a row with its error; one that exceeds `--timeout` is stopped by its
own deadline, and the sweep stops waiting for it after twice that, so the sweep never hangs.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import time
import traceback
from pathlib import Path
from typing import Callable, Literal, Sequence

import numpy as np

from . import journal
from .distributions import MAX_RUNS, MAX_VALUES_TEXT, SweepError, combinations, lhs_names, run_count  # noqa: F401
from .distributions import parse_values, parse_vary, value_count  # noqa: F401 (the sweep's grammar, by these names)
from .results.folder import SWEEP_MANIFEST_FORMAT, SWEEP_MANIFEST_NAME, folder_kind, other_kind_text
from .shipping import SHIPPED_FOLDER, Bundle, ClusterError, client as _cluster_client, materialize  # noqa: F401
from .shipping import one_file as _one_file, passed_on as _passed_on
from .shipping import check_scheduler, check_workers, max_workers  # noqa: F401 (the command line checks with them)
from .units import Units

Status = Literal["ok", "failed", "timeout"]
STATUSES: tuple[Status, ...] = ("ok", "failed", "timeout")
TABLE_NAME, CSV_NAME, JOURNAL_NAME, SPEC_NAME, PLOT_NAME = (
    "sweep.parquet", "sweep.csv", "sweep-rows.jsonl", "sweep.json", "sweep.png")
OWN_FILES = {TABLE_NAME, CSV_NAME, JOURNAL_NAME, SPEC_NAME, PLOT_NAME}
# the files above, each with its size and SHA-256 (the journal: its start), signed with the user's key (ownership.py)
MANIFEST_NAME, MANIFEST_FORMAT = SWEEP_MANIFEST_NAME, SWEEP_MANIFEST_FORMAT
PARTIAL = ".partial"  # a file being written: renamed into place when whole
RUN_OPTIONS = {"speed", "seed", "until_distance", "until_time"}
DEFAULT_TIMEOUT = 600.0  # s of wall clock per run
# Limits checked before anything is generated, allocated or started (docs/sweeps.md): the runs of one sweep (the
# product of the varied values' counts), the worker processes of a local cluster per core (a run is CPU-bound: more
# workers than cores only cost memory, some 100 MB each), the characters of one --vary
WORKERS_PER_CORE = 4
SCHEDULER_PROBE = 10.0  # s for a Dask scheduler to answer a connection with its handshake
GRACE = 2.0  # x timeout without any run coming back: the runs still processing are given up


# ---- what varies: distributions.py (the value grammar, counted before anything is made) ----------------------------

def check_values(varied: dict[str, list]) -> None:
    """What the table could not hold, before any run starts: every value a finite number, every seed a whole number
    in 0 .. 2^63 - 1 (a 64-bit column). A value a run refuses (outside an option's range or an FMU parameter's
    declared min/max) is that run's failed row, as any run's failure (docs/sweeps.md)."""
    from .options import LIMITS

    low, high = LIMITS["seed"]
    for name, values in varied.items():
        for value in values:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise SweepError(f"--vary {name}={value!r}: every value must be a finite number")
            if name == "seed" and (value != int(value) or not low <= value <= high):
                raise SweepError(f"--vary seed={value!r}: seeds are whole numbers from {low} to {high}")


# ---- the files a run reads, shipped to the workers as bytes -------------------------------------

def _tire_files(path: Path) -> Bundle:
    """The Tire Attribute File and every tire file it names; the shipped attribute file names them by their
    place in the bundle, each on its original line (so line numbers in messages stay the same)."""
    from .tire_files import read_attribute_file

    entries = read_attribute_file(path)
    lines = [""] * max((entry.line for entry in entries), default=0)
    names: dict[Path, str] = {}
    files = []
    for entry in entries:
        source = entry.tire_file.resolve()
        if source not in names:
            names[source] = f"tires/{len(names)}-{re.sub(r'[^A-Za-z0-9._-]', '_', source.name)}"
            files.append((names[source], source.read_bytes()))
        lines[entry.line - 1] = f"{entry.attribute} = {names[source]}"
    return Bundle(((path.name, ("\n".join(lines) + "\n").encode()), *files))


# The file-valued options of api.run: option -> how to pack what a run reads through it. A new file-valued
# option is one entry here. (The scenario itself always goes, as the bundle "scenario".)
SHIPPED: dict[str, Callable[[Path], Bundle]] = {"fmu": _one_file, "tires": _tire_files, "vehicle": _one_file,
                                                "controller": _one_file, "controller_map": _one_file}


def _pack(scenario_path: str, fixed: dict) -> dict[str, Bundle]:
    bundles = {"scenario": _one_file(Path(scenario_path))}
    for option, pack in SHIPPED.items():
        if fixed.get(option) is not None:
            bundles[option] = pack(Path(fixed[option]))
    return bundles


# ---- one run (on a worker) ------------------------------------------------------------------------

def run_one(bundles: dict[str, Bundle], values: dict, fixed: dict, timeout: float,
            measure: Callable | None = None) -> dict:
    """One run through sdl_fmu.api, its files from `bundles`; always returns a row, with the error if it
    failed. `measure(result, row)`: more of the row, computed here from the run's Result (the search's objective)."""
    from . import api

    began = time.perf_counter()
    row = {"status": "ok", "error": None}
    try:
        paths = {option: str(materialize(bundle)) for option, bundle in bundles.items()}
        options = {key: value for key, value in fixed.items() if key != "skip_unsupported"}
        scenario = api.set_parameters(paths.pop("scenario"), None,
                                      skip_unsupported=fixed.get("skip_unsupported", False))
        options.update(paths)
        scenario, options = api.apply_values(scenario, values, options)  # the row's values, where each goes
        result = api.run(scenario, timeout=timeout, **options)
        row.update(_summarise(result))
        if measure is not None:
            row.update(measure(result, row))
    except api.RunTimeout as error:
        row.update(status="timeout", error=str(error))
    except (api.InputError, api.ScenarioError, SweepError) as error:
        row.update(status="failed", error=str(error).strip().splitlines()[0])
    except Exception as error:  # a bug or an unexpected failure: still a row, never a lost run
        row.update(status="failed", error=f"{type(error).__name__}: {error}",
                   traceback=traceback.format_exc(limit=5))
    row["run_wall_s"] = time.perf_counter() - began
    return row


def _summarise(result) -> dict:
    from .units import from_si, length_label, speed_label

    raw = result.raw
    final = result.final
    length, speed = length_label(raw.units), speed_label(raw.units)
    row = {"collisions": int(result.collisions), "final_time_s": final["time_s"],
           f"final_distance_{length}": final["distance"], f"final_speed_{speed}": final["speed"],
           f"final_lateral_{length}": final["lateral"],
           "sim_wall_s": raw.timing.get("wall_s"), "real_time_factor": raw.timing.get("real_time_factor"),
           "warnings": len(result.warnings)}
    on = None
    count = 0
    for event in result.events:
        if event["code"] != "BRK":
            continue
        if event["action"] == "on":
            on, count = event, count + 1
            row[f"brk{count}_on_time_s"] = event["time_s"]
        elif event["action"] == "off" and on is not None:
            row[f"brk{count}_off_time_s"] = event["time_s"]
            row[f"brk{count}_reason"] = event.get("reason")
            row[f"brk{count}_distance_{length}"] = event["distance"] - on["distance"]
            if event.get("reason") == "stopped":
                row[f"brk{count}_stop_distance_{length}"] = event["distance"] - on["distance"]
    row.update(criticality_columns(result.criticality, raw.units))
    row.update(impact_columns(result))
    return row


def impact_columns(result) -> dict:
    """The first contact's speeds (scenario units): `impact_speed_<unit>`, the ego's speed there, and
    `relative_impact_speed_<unit>`, the ego's minus the touched vehicle's along the road (the ego's way); both 0 in a
    run without contact (an avoided collision, as the AEB pack scores it)."""
    from .units import from_si, speed_label

    raw = result.raw
    label = speed_label(raw.units)
    contact = next((event for event in raw.events if event["code"] == "A" and event["action"] == "collision"), None)
    if contact is None:
        return {f"impact_speed_{label}": 0.0, f"relative_impact_speed_{label}": 0.0}
    other = 0.0
    track = next((track for track in raw.vehicles if track.vehicle == contact.get("vehicle")), None)
    if track is not None:
        times = np.asarray(raw.columns["time"], dtype=float)
        sample = int(np.clip(np.searchsorted(times, contact["time_s"]), 0, len(times) - 1))  # contact: a sample
        speeds = track.dense("speed", len(times))
        if math.isfinite(speeds[sample]):
            other = -float(speeds[sample])  # the track's speed counts toward the ego's start
    return {f"impact_speed_{label}": from_si(contact["speed"], raw.units),
            f"relative_impact_speed_{label}": from_si(contact["speed"] - other, raw.units)}


def column_names(varied: list[str], units: Units, model=None, scenario=None) -> dict[str, str]:
    """The table's column for each varied name, with its unit: `speed_ft/s`, `until_distance_m`,
    `until_time_s`, an FMU parameter's declared unit (`brake_decel_max_m/s2`), a scenario parameter's declared unit
    (`gap_ft`, named without its `$`) or an address's field's unit (`12.2_ft`); seeds, RSA values (a friction
    coefficient or an attribute number) and parameters declared without a unit have none."""
    from .units import length_label, speed_label

    units_of = {"speed": speed_label(units), "until_distance": length_label(units), "until_time": "s"}
    declared = {} if model is None else {v.name: v.unit for v in model.variables.values() if v.unit and v.unit != "1"}
    columns = {}
    for name in varied:
        if name in RUN_OPTIONS:
            column, unit = name, units_of.get(name)
        elif scenario is not None and _scenario_value(name, scenario):
            column, unit = name.removeprefix("$"), _scenario_unit(name, scenario)
        else:
            column, unit = name, None if name.startswith("rsa.") else declared.get(name.removeprefix("param."))
        columns[name] = f"{column}_{unit}" if unit else column
    return columns


def _scenario_value(name: str, scenario) -> bool:
    from . import api

    return api.value_target(name, scenario) == "scenario"


def _scenario_unit(name: str, scenario) -> str | None:
    """The unit of a scenario parameter's column: its declared unit, or for an address LINE.N the unit of that field
    in the file's units (sdl.parser.address_unit)."""
    from .sdl.parameters import address, parameter_name
    from .sdl.parser import address_unit

    place = address(name)
    if place is None:
        return next((p.unit for p in scenario.parameters if p.name == parameter_name(name)), None)
    return None if place.rsa else address_unit(scenario, place.line, place.index)


def criticality_columns(criticality: dict | None, units: Units) -> dict:
    """The table's criticality columns from summary.json's `criticality` (docs/results.md): the run-wide measures,
    then per vehicle N the same prefixed AN_, units in the names (ft or m; DRAC in ft/s2 or m/s2); None
    where a measure never applied."""
    if criticality is None:
        return {}
    from .units import length_label

    length = length_label(units)
    names = {"min_distance": f"min_distance_{length}", "min_distance_time_s": "min_distance_time_s",
             "min_ttc_s": "min_ttc_s", "min_ttc_time_s": "min_ttc_time_s", "max_drac": f"max_drac_{length}/s2",
             "max_drac_time_s": "max_drac_time_s", "min_pet_s": "min_pet_s", "min_headway_s": "min_headway_s",
             "min_headway_time_s": "min_headway_time_s"}
    columns = {column: criticality.get(key) for key, column in names.items()}
    for vehicle in criticality.get("vehicles", []):
        columns.update({f"A{vehicle['vehicle']}_{column}": vehicle.get(key) for key, column in names.items()})
    return columns


# ---- the table ------------------------------------------------------------------------------------

def _key(index: int, values: dict) -> str:
    """A run's identity: its place in the grid and its values (repeated values, e.g. integers(1,3,8), are several
    runs, each kept)."""
    return json.dumps({"run": index, "values": {name: values[name] for name in sorted(values)}}, sort_keys=True)


def _proved(out: Path) -> set[str] | None:
    """The files of OWN_FILES in `out` that sdl-fmu's sweep provably wrote (its signed manifest lists them, unchanged;
    the journal: its start), or None without a valid manifest."""
    from . import ownership

    try:
        data = json.loads((out / MANIFEST_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("format") != MANIFEST_FORMAT or not ownership.authentic(data):
        return None
    files = data.get("files")
    if not isinstance(files, dict):
        return None
    return {name for name, entry in files.items() if name in OWN_FILES and ownership.unchanged(out / name, entry)}


def _manifest_entry(out: Path, name: str):
    """What the folder's valid manifest records for `name` (None without one)."""
    from . import ownership

    try:
        data = json.loads((out / MANIFEST_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or not ownership.authentic(data) or not isinstance(data.get("files"), dict):
        return None
    entry = data["files"].get(name)
    if isinstance(entry, list):  # the form it was exchanged to
        entry = next((form for form in reversed(entry) if form is not None), None)
    return entry


def _write_manifest(out: Path, coming: dict[str, Path] | None = None) -> None:
    """The manifest of the sweep's files as they are now (written whole, then renamed into place); `coming`: files
    about to replace some of them (name -> the file that will be renamed there), each listed in both forms, so that
    an interruption between the renames leaves every file provably the sweep's."""
    from . import ownership

    coming = coming or {}
    files = {}
    started = _manifest_entry(out, JOURNAL_NAME)  # the journal's start as compacted (rows are appended after it)
    for name in sorted(OWN_FILES):
        now = ownership.record(out / name, prefix=name == JOURNAL_NAME) if (out / name).is_file() else None
        if (name == JOURNAL_NAME and name not in coming and started is not None
                and ownership.unchanged(out / name, started)):
            files[name] = started
        elif name in coming:
            files[name] = [now, ownership.record(coming[name], prefix=name == JOURNAL_NAME)]
        elif now is not None:
            files[name] = now
    ownership.write_json(out / MANIFEST_NAME, ownership.signed({"format": MANIFEST_FORMAT, "files": files}))


def _check_folder(out: Path, spec: dict) -> list[dict]:
    """The `ok` rows of an earlier, interrupted or partly failed run of the same sweep in `out` (resume), or
    [] for a new folder. A folder holding anything sdl-fmu's sweep did not write (a file of the sweep's names
    included, unless its signed manifest proves it sdl-fmu's and unchanged), or another sweep's table, is
    refused. Files left half-written by a sweep that was killed (`*.partial`) go, in a proved folder."""
    if out.exists() and not out.is_dir():
        raise SweepError(f"--out {out}: exists and is not a folder")
    if not out.exists():
        return []
    kind = folder_kind(out)
    if kind not in (None, "sweep"):  # a run's, a test pack's or an export's folder
        raise SweepError(f"--out {other_kind_text(str(out), kind, 'sweep')}")
    names = sorted(entry.name for entry in out.iterdir())
    proved = _proved(out)
    leftovers = [name for name in names if name.endswith(PARTIAL) and name[:-len(PARTIAL)] in
                 {*OWN_FILES, MANIFEST_NAME}]
    foreign = [name for name in names if name not in {*OWN_FILES, MANIFEST_NAME}
               and not (proved is not None and name in leftovers)]
    if foreign:
        raise SweepError(f"--out {out}: holds files a sweep did not write ({', '.join(foreign[:3])}); "
                         "choose a new or empty folder")
    unproved = [name for name in names if name in OWN_FILES and name not in (proved or set())]
    if unproved:
        raise SweepError(f"--out {out}: its {unproved[0]} was not written by sdl-fmu's sweep, or was changed since; "
                         "move it away, or choose another folder")
    for name in leftovers:
        (out / name).unlink(missing_ok=True)
    if not (out / SPEC_NAME).exists():
        return []
    try:
        earlier = json.loads((out / SPEC_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        raise SweepError(f"--out {out}: its {SPEC_NAME} cannot be read ({error}); choose another folder") from None
    if not isinstance(earlier, dict):
        raise SweepError(f"--out {out}: its {SPEC_NAME} is not a sweep's description; choose another folder")
    if earlier != spec:
        differ = [part for part in ("scenario", "vary", "fixed", "files") if earlier.get(part) != spec.get(part)]
        raise SweepError(f"--out {out}: holds a different sweep ({earlier.get('scenario')}, varying "
                         f"{', '.join(earlier.get('vary', {}))}; its {' and '.join(differ)} differ: a changed "
                         "file or option); choose another folder")
    # a line cut short by the interruption (or damaged) is dropped by the journal: that run is simply run again
    return list(journal.rows(out / JOURNAL_NAME, lambda row: row.get("status") == "ok"
                             and type(row.get("run")) is int).values())


def write_table(rows: list[dict], out: Path, varied: list[str], units: Units, ranked: bool = False) -> None:
    """sweep.parquet and sweep.csv (same columns: varied values first, then the outcome), and sweep.png.
    `varied`: the varied values' column names. `ranked`: the rows in the order given, `rank` the first column (rank());
    else in run order."""
    import pyarrow as pa
    import pyarrow.csv as pa_csv
    import pyarrow.parquet as pq

    rows = list(rows) if ranked else sorted(rows, key=lambda r: r["run"])
    first = ["rank"] * ranked + ["run", *varied, "status", "error"]
    rest = sorted({key for row in rows for key in row} - set(first) - {"key", "traceback"},
                  key=_column_order)
    columns = {name: [row.get(name) for row in rows] for name in [*first, *rest]}
    table = pa.table({name: pa.array(values, from_pandas=True) for name, values in columns.items()})
    partials = [out / (name + PARTIAL) for name in (TABLE_NAME, CSV_NAME, PLOT_NAME)]
    try:
        pq.write_table(table, partials[0])
        pa_csv.write_csv(table, partials[1])
        plot_sweep(rows, varied, units, partials[2])
        _write_manifest(out, {partial.name[:-len(PARTIAL)]: partial for partial in partials})
        for partial in partials:
            os.replace(partial, partial.with_name(partial.name[:-len(PARTIAL)]))
        _write_manifest(out)
    finally:
        for partial in partials:
            partial.unlink(missing_ok=True)


def _column_order(name: str):
    match = re.match(r"(brk|A)(\d+)_(.*)", name)
    if match:
        return (1 if match.group(1) == "brk" else 2, int(match.group(2)), match.group(3))
    return (0, 0, name)


def plotted_quantities(rows: list[dict], varied: list[str]) -> list[str]:
    """The varied columns the plot shows: each that takes more than one value (the first one if none does)."""
    shown = [name for name in varied if len({row.get(name) for row in rows}) > 1]
    return shown or varied[:1]


def _axis_label(column: str) -> str:
    """`speed_ft/s` -> `speed (ft/s)`; a column without a unit stays as it is."""
    for suffix in ("_ft/s", "_m/s", "_ft", "_m", "_s"):
        if column.endswith(suffix):
            return f"{column[:-len(suffix)]} ({suffix[1:]})"
    match = re.fullmatch(r"(.*?)_([^_]*[/0-9][^_]*|kg|rad|N|W|Pa)", column)
    return f"{match.group(1)} ({match.group(2)})" if match else column


MAX_PLOT_SERIES = 8  # at most this many series (combinations of the other varied quantities) in one panel


def _series(rows: list[dict], name: str, others: list[str]) -> list[tuple[str, list[dict]]]:
    """The ok rows split into series by the values of the other varied quantities (so that one series varies
    `name` alone), each labelled `other=value, ...`; with more combinations than MAX_PLOT_SERIES, one series per
    value of the first other quantity only, and beyond that one series of every ok row."""
    ok = [r for r in rows if r.get("status") == "ok" and isinstance(r.get(name), (int, float))]
    for keys in (others, others[:1], []):
        groups: dict[tuple, list[dict]] = {}
        for r in ok:
            groups.setdefault(tuple(r.get(k) for k in keys), []).append(r)
        if len(groups) <= MAX_PLOT_SERIES:
            return [(", ".join(f"{_axis_label(k)}={v:g}" if isinstance(v, (int, float)) else f"{_axis_label(k)}={v}"
                               for k, v in zip(keys, values)), sorted(members, key=lambda r: r[name]))
                    for values, members in sorted(groups.items(), key=lambda item: str(item[0]))]
    return []


def heat_map_axes(rows: list[dict], varied: list[str]) -> tuple[str, str] | None:
    """(x, y) quantities of a 2-D grid the plot draws as heat maps: exactly two quantities take more than one value
    and one of them takes more than MAX_PLOT_SERIES (one line per value of the other would not do); else None."""
    quantities = plotted_quantities(rows, varied)
    if len(quantities) != 2:
        return None
    counts = [len({row.get(name) for row in rows}) for name in quantities]
    return (quantities[0], quantities[1]) if max(counts) > MAX_PLOT_SERIES else None


def heat_map_cells(rows: list[dict], x: str, y: str, value: Callable[[dict], float | None]):
    """(x values, y values, cells) of a 2-D grid: the sorted values of each quantity and an array (y by x) of the
    mean of `value` over each cell's ok runs (NaN where none has one; a cell holds one run unless values repeat)."""
    numeric = [r for r in rows if isinstance(r.get(x), (int, float)) and isinstance(r.get(y), (int, float))]
    xs, ys = sorted({r[x] for r in numeric}), sorted({r[y] for r in numeric})
    column, line = {v: k for k, v in enumerate(xs)}, {v: k for k, v in enumerate(ys)}
    total, count = np.zeros((len(ys), len(xs))), np.zeros((len(ys), len(xs)))
    for r in numeric:
        v = value(r) if r.get("status") == "ok" else None
        if isinstance(v, (int, float)) and math.isfinite(v):
            total[line[r[y]], column[r[x]]] += v
            count[line[r[y]], column[r[x]]] += 1
    with np.errstate(invalid="ignore"):
        return xs, ys, np.where(count > 0, total / np.maximum(count, 1), np.nan)


MAX_CELL_TEXTS = 144  # a heat map of at most this many cells writes each cell's value in it
MAX_TICK_LABELS = 12  # value labels per heat-map axis (every k-th beyond)


def plot_sweep(rows: list[dict], varied: list[str], units: Units, path: Path) -> None:
    """One row of panels per varied quantity that takes more than one value: collisions, the first BRK's
    distance and the smallest footprint distance to any vehicle against that quantity, one series (line and
    markers) per combination of the other varied quantities, so that a series varies that quantity alone; failed
    and timed-out runs marked at the bottom. Axes carry units; collisions are counted in whole numbers; names are
    drawn as written (a `$` in a --vary name is not mathtext)."""
    from .text import plain_text

    with plain_text():
        _plot_sweep(rows, varied, units, path)


def _plot_sweep(rows: list[dict], varied: list[str], units: Units, path: Path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    from .units import length_label

    length = length_label(units)
    quantities = plotted_quantities(rows, varied)
    grid = heat_map_axes(rows, varied)
    figure = Figure(figsize=(12, 0.8 + 3.0 * (1.3 if grid else len(quantities))), dpi=100, layout="constrained")
    FigureCanvasAgg(figure)
    panels = [("collisions", "collisions", lambda r: r.get("collisions")),
              ("first BRK: distance while on", f"distance ({length})", lambda r: r.get(f"brk1_distance_{length}")),
              ("smallest footprint distance to a vehicle", f"distance ({length})",
               lambda r: r.get(f"min_distance_{length}"))]
    colours = {"failed": "tab:red", "timeout": "tab:orange"}
    if grid:
        _plot_heat_maps(figure, rows, grid, panels, colours, MaxNLocator)
        quantities = []
    for row_index, name in enumerate(quantities):
        others = [other for other in plotted_quantities(rows, varied) if other != name]
        series = _series(rows, name, others)
        for k, (title, ylabel, value) in enumerate(panels):
            ax = figure.add_subplot(len(quantities), 3, 3 * row_index + k + 1)
            for number, (label, members) in enumerate(series):
                points = [(r[name], value(r)) for r in members if value(r) is not None]
                if points:
                    xs, ys = zip(*points)
                    # a series that holds some other quantity at more than one value has several runs per x: its
                    # points are drawn as markers alone (a line through them would zig-zag between the runs)
                    joined = len(set(xs)) == len(xs)
                    ax.plot(xs, ys, marker="o", ms=4, lw=1.0 if joined else 0.0, color=f"C{number % 10}",
                            label=label or None)
            for status, colour in colours.items():
                xs = [r[name] for r in rows if r.get("status") == status and isinstance(r.get(name), (int, float))]
                if xs:
                    ax.scatter(xs, [0.0] * len(xs), s=18, color=colour, marker="x", label=status, zorder=3)
            if k == 0:
                ax.yaxis.set_major_locator(MaxNLocator(integer=True))
                ax.set_ylim(bottom=-0.2)
            ax.set_xlabel(_axis_label(name))
            ax.set_ylabel(ylabel)
            ax.set_title(title, fontsize=10, loc="left")
            ax.grid(True, alpha=0.3)
            if k == 0 and (len(series) > 1 or any(r.get("status") != "ok" for r in rows)):
                ax.legend(fontsize=8)
    title = f"sweep: {len(rows)} runs, {sum(r.get('status') == 'ok' for r in rows)} ok"
    if grid:
        title += ("; each cell: the mean over its ok runs (empty: none ok); crosses: failed (red) and timed-out "
                  "(orange) runs")
    figure.suptitle(title, fontsize=11)
    figure.savefig(path, format="png")


def _plot_heat_maps(figure, rows: list[dict], grid: tuple[str, str], panels: list, colours: dict,
                    integer_ticks) -> None:
    """A 2-D grid: one heat map per panel's measure, the first quantity across, the second up, each cell the mean
    over its ok runs (written in the cell when there are few cells), empty where no run is ok; failed and
    timed-out runs marked by a cross in their cell."""
    x, y = grid
    for k, (title, label, value) in enumerate(panels):
        ax = figure.add_subplot(1, 3, k + 1)
        xs, ys, cells = heat_map_cells(rows, x, y, value)
        image = ax.imshow(cells, origin="lower", aspect="auto", interpolation="nearest",
                          cmap="Reds" if k == 0 else "viridis")
        figure.colorbar(image, ax=ax, label=label, shrink=0.9)
        if cells.size <= MAX_CELL_TEXTS:
            for (row, column), cell in np.ndenumerate(cells):
                if math.isfinite(cell):
                    red, green, blue, _ = image.cmap(image.norm(cell))
                    dark = 0.299 * red + 0.587 * green + 0.114 * blue < 0.5
                    ax.text(column, row, f"{cell:.3g}", ha="center", va="center", fontsize=7,
                            color="white" if dark else "black")
        for values, axis, name in ((xs, ax.xaxis, x), (ys, ax.yaxis, y)):
            every = max(1, math.ceil(len(values) / MAX_TICK_LABELS))
            axis.set_ticks(range(0, len(values), every), [f"{v:g}" for v in values[::every]])
            axis.set_label_text(_axis_label(name))
        if len(xs[::max(1, math.ceil(len(xs) / MAX_TICK_LABELS))]) > 6:
            ax.tick_params(axis="x", labelrotation=45)
        if k == 0:
            image.colorbar.ax.yaxis.set_major_locator(integer_ticks(integer=True))
        for status, colour in colours.items():
            marked = [(xs.index(r[x]), ys.index(r[y])) for r in rows
                      if r.get("status") == status and r.get(x) in xs and r.get(y) in ys]
            if marked:
                ax.scatter(*zip(*marked), s=30, color=colour, marker="x", label=status, zorder=3)
        ax.set_title(title, fontsize=10, loc="left")


# ---- the sweep ------------------------------------------------------------------------------------

def preflight(scenario: str, varied: dict[str, list], joint: Sequence[str], fixed: dict):
    """Everything a sweep's arguments can be told wrong by before anything runs or any cluster is contacted: the run
    count, the values (finite, seeds whole), the scenario for the runs' vehicle, the fixed options and FMU start values,
    the FMU (built once here, and instantiated), every --vary name (api.check_value_names: a name that is no run
    option, scenario parameter or FMU parameter is one line), and the scenario with the scenario values of every run
    (each distinct combination parsed once: a value its field refuses is a ScenarioError naming file, line, field and
    parameter). Returns (the loaded scenario, the EgoModel, the scenario's absolute path)."""
    from . import api

    runs = run_count(varied, joint)
    if runs > MAX_RUNS:
        raise SweepError(f"--vary: {runs} runs, more than the {MAX_RUNS} a sweep may have")
    check_values(varied)
    scenario_path = str(api.resolve_scenario(scenario).absolute())
    # the scenario checked for the runs' vehicle (a bad file fails now, before any FMU is built or loaded)
    vehicle = {"dynamics": fixed.get("dynamics"), "vehicle": fixed.get("vehicle")}
    loaded = api.load(scenario_path, skip_unsupported=fixed.get("skip_unsupported", False), **vehicle)
    api.run_options(loaded, **{key: fixed[key] for key in api.RUN_OPTIONS if key in fixed})  # bad options fail now
    model = api.ego_model(fixed.get("dynamics"), fixed.get("fmu"), fixed.get("vehicle"))  # built once, here
    model.with_parameters(fixed.get("params"))  # and bad FMU start values
    try:  # an FMU that cannot even be instantiated is a bad --fmu, not a table of failed runs
        model.instantiate(start={"speed": 0.0, "x": 0.0, "y": 0.0, "yaw": 0.0}, instance_name="probe").close()
    except Exception as error:  # noqa: BLE001 - whatever the FMU's start raised
        reason = str(error).strip().splitlines()[0] if str(error).strip() else repr(error)
        raise api.InputError("fmu", f"the FMU {model.fmu_path} cannot be instantiated: {reason}") from None
    api.check_value_names(loaded, list(varied), model)
    settings = [name for name in varied if api.value_target(name, loaded) == "scenario"]
    if settings:
        distinct = {tuple(values.items()): values for values in
                    combinations({name: varied[name] for name in settings}, [n for n in joint if n in settings])}
        api.check_settings(loaded, distinct.values(), **vehicle)
    return loaded, model, scenario_path


_NOT_MEASURES = {"run", "rank", "status", "error", "key", "traceback"}


def sort_column(sort: str, scenario, model, varied: dict[str, list]) -> tuple[str, bool]:
    """(the table column, descending) that `--sort MEASURE[:asc|:desc]` ranks by: a numeric column of the table (a
    measure such as `min_ttc_s`, `collisions`, `A1_min_distance_ft`, a BRK's, the final state, a varied value), named
    as the table names it or without its unit (`min_distance` for `min_distance_ft`). SweepError otherwise, before
    anything runs."""
    from .units import length_label, speed_label

    measure, _, order = sort.strip().partition(":")
    if order not in ("", "asc", "desc"):
        raise SweepError(f"--sort {sort}: expected MEASURE, MEASURE:asc or MEASURE:desc")
    length, speed = length_label(scenario.units), speed_label(scenario.units)
    outcome = {"collisions", "final_time_s", f"final_distance_{length}", f"final_speed_{speed}",
               f"final_lateral_{length}", "sim_wall_s", "real_time_factor", "run_wall_s", "warnings"}
    measures = set(criticality_columns({}, scenario.units))  # the run-wide measures' columns
    brk = {"on_time_s", "off_time_s", f"distance_{length}", f"stop_distance_{length}"}
    known = outcome | measures | set(column_names(list(varied), scenario.units, model, scenario).values())

    def is_column(name: str) -> bool:
        if name in known:
            return True
        per = re.fullmatch(r"(A|brk)([1-9][0-9]*)_(.+)", name)
        return per is not None and per[3] in (measures if per[1] == "A" else brk)

    units = ("ft", "m", "ft/s", "m/s", "s", "ft/s2", "m/s2", "kg", "m/s2", "1/s", "rad", "N", "W", "%")
    candidates = [name for name in (measure, *(f"{measure}_{unit}" for unit in units)) if is_column(name)]
    if measure in _NOT_MEASURES or not candidates:
        raise SweepError(f"--sort {sort}: not a numeric column of the table (a measure such as min_ttc_s, "
                         f"min_distance_{length}, max_drac_{length}/s2, collisions, A1_min_distance_{length}, "
                         f"brk1_distance_{length}, final_speed_{speed}, or a varied value)")
    return candidates[0], order == "desc"


def rank(rows: list[dict], ranking: tuple[str, bool] | None) -> list[dict]:
    """The rows in run order, or (ranking: (column, descending)) ranked by that column, each with its `rank` (1 the
    first); rows without a number there (failed, timed out, a measure that never applied) come last, in run order.
    Ties keep run order."""
    rows = sorted(rows, key=lambda r: r["run"])
    if ranking is None:
        return rows
    column, descending = ranking

    def number(row):
        value = row.get(column)
        ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
        return value if ok else None

    valued = [row for row in rows if number(row) is not None]
    valued.sort(key=number, reverse=descending)  # stable, reversed or not: ties keep run order
    ranked = valued + [row for row in rows if number(row) is None]
    return [{**row, "rank": place} for place, row in enumerate(ranked, start=1)]


def rerun(scenario: str, varied: dict[str, list], index: int, out: str | os.PathLike | None, *,
          joint: Sequence[str] = (), timeout: float | None = None, **fixed):
    """Run `index` of the sweep these arguments describe (its values made again as the sweep made them: the same
    --vary and --sample-seed give the same runs), alone, in this process, into the results folder `out` (None: none)
    as `sdl-fmu run` writes one; returns (the api.Result, the run's values). The same preflight as sweep's."""
    from . import api

    runs = run_count(varied, joint)
    if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < runs:
        raise SweepError(f"--rerun {index}: the sweep has {runs} run{'s' * (runs != 1)}, numbered 0 to {runs - 1} "
                         "(the table's column run)")
    loaded, model, scenario_path = preflight(scenario, varied, joint, fixed)
    values = combinations(varied, joint)[index]
    options = {key: value for key, value in fixed.items()}
    options["fmu"] = str(model.fmu_path)
    scenario_set, options = api.apply_values(scenario_path, values, options)
    return api.run(scenario_set, out=out, timeout=timeout, **options), values


def row_commands(scenario_path: str, values: dict, scenario) -> tuple[str, str]:
    """A run's values as two command lines: `sdl-fmu resolve` of its scenario values (the row's scenario as plain
    SDL) and the `sdl-fmu run` options of the rest (run options, FMU parameters), to follow `run RESOLVED.sdl`."""
    from . import api
    from .sdl.parameters import value_text

    settings, options = [], []
    for name, value in values.items():
        target = api.value_target(name, scenario)
        shown = value_text(value) if isinstance(value, float) else str(value)
        if target == "scenario":
            settings.append(f"--set {name}={shown}")
        elif target == "option":
            options.append(f"--{name.replace('_', '-')} {shown}")
        else:
            options.append(f"--param {name.removeprefix('param.')}={shown}")
    resolve = " ".join(["sdl-fmu resolve", scenario_path, *settings, "--out", "FILE"])
    return resolve, " ".join(options)


def sweep(scenario: str, varied: dict[str, list], out: str | os.PathLike, *, workers: int | None = None,
          scheduler: str | None = None, client=None, timeout: float = DEFAULT_TIMEOUT, progress: bool | None = None,
          joint: Sequence[str] = (), sort: str | None = None, **fixed) -> list[dict]:
    """Runs every combination of `varied` (see the module docstring) on Dask and writes the table into `out`.
    `client`: an existing distributed.Client (tests); else `scheduler` (an address) or a LocalCluster of
    `workers` processes (default: one per core). `joint`: varied names zipped instead of combined (a Latin
    hypercube's, distributions.lhs_names). `sort`: rank the table by this measure (`MEASURE` ascending,
    `MEASURE:desc` descending; a `rank` column). `fixed`: keyword options of sdl_fmu.api.run for every run.
    Every name and every scenario value is checked before any cluster is contacted (preflight). Returns the rows, in
    run order (in rank order with `sort`)."""
    from . import api

    if not timeout > 0:
        raise SweepError(f"--timeout {timeout}: must be > 0")
    loaded, model, scenario_path = preflight(scenario, varied, joint, fixed)
    ranking = None if sort is None else sort_column(sort, loaded, model, varied)
    check_workers(workers if client is None and not scheduler else None)
    check_scheduler(scheduler)
    fixed, bundles = shipped_files(scenario_path, model, fixed)
    out = Path(out).absolute()
    # sweep.json: the files by name (their digests tell them apart), no machine's path (docs/sweeps.md)
    named = {key: Path(value).name if key in SHIPPED and value is not None else value for key, value in fixed.items()}
    spec = {"scenario": Path(scenario_path).name, "vary": varied, "fixed": json.loads(json.dumps(named, default=str)),
            "files": {option: bundle.digest for option, bundle in bundles.items()}}
    if joint:
        spec["joint"] = list(joint)
    from . import ownership

    if out.exists() and not out.is_dir():
        raise SweepError(f"--out {out}: exists and is not a folder")
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)  # to hold its lock from the start; removed again if nothing is written
    except OSError as error:
        raise SweepError(f"--out {out}: cannot be made: {error.strerror or error}") from None
    held = False
    try:
        with ownership.locked(out):
            held = True
            return _sweep_into(out, spec, bundles, varied, fixed, loaded, model, workers, scheduler, client, timeout,
                               progress, tuple(joint), ranking)
    except ownership.Locked:
        raise SweepError(f"--out {out}: another sweep is writing into it; wait until it ends, or choose another "
                         "folder") from None
    except OSError as error:  # a full disk, a folder that became read-only: what was written stays consistent
        done = (out / JOURNAL_NAME).exists()
        raise SweepError(f"--out {out}: cannot write: {error.strerror or error}; "
                         + ("the finished runs are kept: the same command resumes the sweep" if done else
                            "nothing was written")) from None
    finally:
        if created and held:
            with contextlib.suppress(OSError):
                out.rmdir()  # only if empty: a sweep that wrote nothing leaves nothing


def prepare(scenario: str, fixed: dict) -> tuple[str, object, object, dict, dict[str, Bundle]]:
    """What every run of a search shares, checked once here before any cluster starts (preflight with nothing
    varied, then shipped_files): the scenario's absolute path, the loaded Scenario, the EgoModel, the fixed options
    with every file as an absolute path, and the file bundles the workers get."""
    loaded, model, scenario_path = preflight(scenario, {}, (), fixed)
    fixed, bundles = shipped_files(scenario_path, model, fixed)
    return scenario_path, loaded, model, fixed, bundles


def shipped_files(scenario_path: str, model, fixed: dict) -> tuple[dict, dict[str, Bundle]]:
    """The fixed options with every file as an absolute path (the ego FMU built once, the tire file and the
    controller's map checked now, naming the local file; the map's own `fmu` resolved: the map travels alone), and the
    file bundles the workers get."""
    from . import api

    fixed = dict(fixed)
    fixed["fmu"] = str(model.fmu_path)
    if fixed.get("tires") is not None:
        model.with_tires(fixed["tires"])  # a bad tire file fails now, naming the local file
        fixed["tires"] = str(Path(fixed["tires"]).absolute())
    if fixed.get("vehicle") is not None:
        fixed["vehicle"] = str(Path(fixed["vehicle"]).absolute())
    controller = api.controller_model(fixed.get("controller"), fixed.get("controller_map"))  # a bad map fails now
    if controller is not None:  # the map's own `fmu` resolved here: the map travels alone
        fixed["controller"] = str(controller.fmu_path.absolute())
        fixed["controller_map"] = str(Path(controller.map_path).absolute())  # example-aeb: the shipped map
    return fixed, _pack(scenario_path, fixed)


def _sweep_into(out, spec, bundles, varied, fixed, loaded, model, workers, scheduler, client, timeout,
                progress, joint, ranking) -> list[dict]:
    """The sweep proper, with `out`'s lock held."""
    from . import ownership

    done = _check_folder(out, spec)
    columns = column_names(list(varied), loaded.units, model, loaded)
    runs = combinations(varied, joint)
    finished = {row["key"]: row for row in done}
    todo = [(index, values) for index, values in enumerate(runs) if _key(index, values) not in finished]
    rows = list(finished.values())
    owned = []
    try:
        if todo and client is None:  # connect before anything is written
            client, owned = _client(workers, scheduler, len(todo))
        if not (out / SPEC_NAME).exists():  # a resumed sweep's is the same
            ownership.write_json(out / SPEC_NAME, spec)
        _keep_only(out / JOURNAL_NAME, rows)  # and the manifest
        if todo:
            rows += _run_all(bundles, todo, fixed, timeout, out, client, progress, columns)
    finally:
        for thing in owned:
            thing.close()
    rows = rank(rows, ranking)
    write_table(rows, out, list(columns.values()), loaded.units, ranked=ranking is not None)  # and the manifest
    return rows


def _keep_only(path: Path, rows: list[dict]) -> None:
    """The journal with only the rows kept (the `ok` ones): the runs that failed are run again."""
    partial = path.with_name(path.name + PARTIAL)
    try:
        partial.write_text("".join(journal.line(row) for row in rows), encoding="utf-8")
        _write_manifest(path.parent, {path.name: partial})
        os.replace(partial, path)
        _write_manifest(path.parent)
    finally:
        partial.unlink(missing_ok=True)


def _client(workers: int | None, scheduler: str | None, runs: int | None = None):
    """A client of the cluster at `scheduler`, or of a new LocalCluster of `workers` processes (never more than
    `runs`); and what to close afterwards (shipping.client, its errors as SweepError)."""
    try:
        return _cluster_client(workers, scheduler, runs)
    except ClusterError as error:
        raise SweepError(str(error)) from None


def _run_all(bundles, todo, fixed, timeout, out, client, progress, columns) -> list[dict]:
    """Submits the runs, journals each row as it arrives (run_rows)."""
    from tqdm import tqdm

    rows = []
    import sys

    from .text import unescaped  # the bar's own carriage returns, not escaped

    bar = tqdm(total=len(todo), unit="run", file=unescaped(sys.stderr),
               disable=progress is False or (progress is None and not _stderr_is_terminal()))
    shipped = ship(client, bundles)
    try:
        with open(out / JOURNAL_NAME, "a", encoding="utf-8") as stream:
            def arrived(row, index, values):
                rows.append(_record(stream, row, index, values, columns))
                bar.update()

            run_rows(client, shipped, todo, fixed, timeout, arrived)
    finally:
        bar.close()
        release(shipped)
    return rows


def ship(client, bundles: dict[str, Bundle]) -> dict:
    """The file bundles as Dask futures (each moved to a worker once, recomputed if its holder dies); release() them
    when the runs are done."""
    return {option: client.submit(_passed_on, bundle, key=f"sdl-fmu-files-{bundle.digest}")
            for option, bundle in bundles.items()}


def release(shipped: dict) -> None:
    for future in shipped.values():
        future.release()


def run_rows(client, shipped: dict, todo: list[tuple[int, dict]], fixed: dict, timeout: float,
             arrived: Callable[[dict, int, dict], None], measure: Callable | None = None,
             more: Callable[[], list[tuple[int, dict]]] | None = None) -> None:
    """Runs `todo` ((index, values) pairs) on Dask with the shipped files, calling `arrived(row, index, values)` in
    this thread as each row comes back (a worker that died or a task that could not run: a failed row), and then
    `more()` for runs to add (a search's next trials). Every run stops itself at `timeout`; if no run at all comes
    back for GRACE x timeout (+ 10 s), the runs still processing are given up (cancelled and given as timeout rows),
    so a stuck worker never hangs the caller. Interrupted, the runs not yet back are cancelled."""
    patience = GRACE * timeout + 10.0
    futures: dict = {}
    pending: set = set()

    def submit(runs) -> None:
        for index, values in runs:
            future = client.submit(run_one, shipped, values, fixed, timeout, measure, pure=False)
            futures[future] = (index, values)
            pending.add(future)

    submit(todo)
    if more is not None:
        submit(more())
    try:
        last_progress = time.monotonic()
        while pending:
            finished = [future for future in pending if future.done()]
            now = time.monotonic()
            for future in finished:
                pending.discard(future)
                try:
                    row = future.result()
                except Exception as error:  # the worker died or the task could not run
                    row = {"status": "failed", "error": f"{type(error).__name__}: {error}"}
                arrived(row, *futures.pop(future))
                last_progress = now
                if more is not None:
                    submit(more())
            if finished or not pending:
                continue
            if now - last_progress > patience:
                processing = {key for keys in client.processing().values() for key in keys}
                stuck = [future for future in pending if future.key in processing] or list(pending)
                for future in stuck:
                    pending.discard(future)
                    future.cancel()
                    arrived({"status": "timeout", "error": f"no result within {patience:.0f} s: given up"},
                            *futures.pop(future))
                    if more is not None:
                        submit(more())
                last_progress = now
            time.sleep(0.05)
    finally:
        for future in pending:
            future.cancel()


def _record(stream, row: dict, index: int, values: dict, columns: dict[str, str]) -> dict:
    row = {"run": index, **{columns[name]: value for name, value in values.items()}, **row,
           "key": _key(index, values)}
    journal.append(stream, row)
    return row


def failure_line(rows: list[dict], table: Path) -> str | None:
    """One line about the runs that did not end `ok` (None when all did): "3 of 24 runs failed (TABLE,
    column error)", or, when every run failed, that and the first error."""
    bad = [row for row in rows if row.get("status") != "ok"]
    if not bad:
        return None
    timed_out = sum(row.get("status") == "timeout" for row in bad)
    what = "timed out" if timed_out == len(bad) else "failed or timed out" if timed_out else "failed"
    where = f"({table}, column error)"
    if len(bad) == len(rows):
        first = min(bad, key=lambda row: row["run"])
        error = (str(first.get("error") or "").strip().splitlines() or ["no error given"])[0]
        return f"all {len(rows)} runs {what} {where}; run {first['run']}: {error}"
    return f"{len(bad)} of {len(rows)} runs {what} {where}"


def _stderr_is_terminal() -> bool:
    import sys

    return sys.stderr.isatty()
