"""The AEB car-to-car pack's results folder: verify.json (docs/verification.md), tests.csv (one row per test) and
report.html (self-contained: the grids as coloured tables, the totals, a plot, the vehicle data sheet, the
controller), and the table the command prints."""

from __future__ import annotations

import base64
import html
import io
import json
from pathlib import Path

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ...results.folder import write_results_folder
from ..quantities import shown
from ..report import HTML_NAME, JSON_NAME, STYLE, _json_ready, datasheet_html, provenance_html, values_table
from .outcome import TestOutcome
from .pack import totals
from .protocol import (BANDS, COLOURS, DESCRIPTION, GROUPS, OVERLAPS_PCT, PROTOCOL, START_TTC_S, TARGET_LENGTH_M,
                       TARGET_WIDTH_M)

FORMAT = "sdl-fmu verify aeb-ccr 1"
CSV_NAME = "tests.csv"
# the cells' colours: the protocol's colour of the points, grey for a run that failed
FILL = {"green": "#3aa655", "yellow": "#f2d42c", "orange": "#f39a2b", "brown": "#9a6a3c", "red": "#d9352b",
        "grey": "#bbbbbb"}
CSV_KEYS = ("group", "ego_speed_kmh", "target_speed_kmh", "overlap_pct", "target_decel_mps2", "headway_m", "impact",
            "impact_speed_kmh", "relative_impact_speed_kmh", "speed_reduction_kmh", "min_gap_m", "min_ttc_s", "score",
            "passed", "end", "end_time_s", "error")


def passed(outcomes: list[TestOutcome]) -> bool:
    """--strict's test: every test scored its full points (and every run ran)."""
    return all(o.passed for o in outcomes)


def document(outcomes: list[TestOutcome], vehicle: dict, sheet: dict, controller: dict | None, tool: dict) -> dict:
    return _json_ready({"format": FORMAT, "pack": "aeb-ccr", "protocol": PROTOCOL, "tool": tool, "vehicle": vehicle,
                        "datasheet": sheet, "controller": controller,
                        "target": {"length_m": TARGET_LENGTH_M, "width_m": TARGET_WIDTH_M},
                        "passed": passed(outcomes), "totals": totals(outcomes),
                        "tests": [o.to_json() for o in outcomes]})


def table(outcomes: list[TestOutcome]) -> str:
    """Per group, one line per speed (CCRb: per deceleration and headway): the relative impact speed at each overlap
    (- avoided), then the totals."""
    lines = []
    for group in GROUPS:
        mine = [o for o in outcomes if o.test.group == group]
        if not mine:
            continue
        lines.append(f"{group}: relative impact speed, km/h ('-' avoided, '!' the run failed, 't/o' timed out), per "
                     "overlap")
        lines.append(f"  {'':<16} " + " ".join(f"{f'{p:+d}%':>6}" for p in OVERLAPS_PCT))
        for row, cells in _rows(mine):
            text = " ".join(f"{_cell_text(cells.get(p)):>6}" for p in OVERLAPS_PCT)
            lines.append(f"  {row:<16} {text}")
    lines.append("")
    for group, total in totals(outcomes).items():
        lines.append(f"{group}: {total['points']:.2f} of {total['max_points']:.0f} points ({total['score_pct']:.1f} %),"
                     f" {total['impacts']} impact(s) in {total['tests']} tests"
                     + (f", {total['errors']} run(s) failed" if total["errors"] else "")
                     + (f", {total['timeouts']} timed out" if total["timeouts"] else ""))
    return "\n".join(lines)


def _cell_text(outcome: TestOutcome | None) -> str:
    if outcome is None:
        return ""
    if outcome.timed_out:
        return "t/o"
    if outcome.error is not None:
        return "!"
    return f"{outcome.relative_impact_speed_kmh:.1f}" if outcome.impact else "-"


def _rows(outcomes: list[TestOutcome]) -> list[tuple[str, dict[int, TestOutcome]]]:
    """The grid's rows in order: (row label, overlap -> outcome)."""
    rows: dict[str, dict[int, TestOutcome]] = {}
    for o in outcomes:
        t = o.test
        key = (f"{t.target_decel_mps2:g} m/s2 {t.headway_m:g} m" if t.group == "CCRb"
               else f"{t.ego_speed_kmh:g} km/h")
        rows.setdefault(key, {})[t.overlap_pct] = o
    return list(rows.items())


def write_csv(path: Path, outcomes: list[TestOutcome]) -> None:
    with path.open("w", encoding="utf-8", newline="\n") as stream:
        stream.write(",".join(CSV_KEYS) + "\n")
        for o in outcomes:
            row = o.to_json()
            stream.write(",".join("" if row.get(k) is None else str(row[k]).replace(",", ";") for k in CSV_KEYS)
                         + "\n")


# --- report.html ------------------------------------------------------------------------------------------------


def _cell_html(outcome: TestOutcome | None) -> str:
    if outcome is None:
        return "<td></td>"
    e = html.escape
    text = ("timed out" if outcome.timed_out else "run failed" if outcome.error
            else shown("_kmh", outcome.relative_impact_speed_kmh) if outcome.impact else "avoided")
    details = outcome.error or "; ".join(
        f"{name} {shown(key, getattr(outcome, key))}" for name, key in (
            ("impact speed", "impact_speed_kmh"), ("speed reduction", "speed_reduction_kmh"),
            ("min gap", "min_gap_m"), ("min TTC", "min_ttc_s"))) + f"; ended: {outcome.end}; points {outcome.score}"
    return (f"<td class='n' style='background:{FILL[outcome.colour]}' title='{e(details)}'>{e(text)}<br>"
            f"<span class='small'>{'' if outcome.score is None else f'{outcome.score:g} pt'}</span></td>")


def grid_html(outcomes: list[TestOutcome]) -> str:
    e = html.escape
    parts = []
    for group in GROUPS:
        mine = [o for o in outcomes if o.test.group == group]
        if not mine:
            continue
        target = (f"target at {mine[0].test.target_speed_kmh:g} km/h" if group != "CCRb"
                  else f"ego and target at {mine[0].test.ego_speed_kmh:g} km/h, the target braking from the start")
        head = "".join(f"<th>{p:+d} %</th>" for p in OVERLAPS_PCT)
        rows = "".join(f"<tr><th>{e(row)}</th>{''.join(_cell_html(cells.get(p)) for p in OVERLAPS_PCT)}</tr>"
                       for row, cells in _rows(mine))
        first = "deceleration, headway" if group == "CCRb" else "ego speed"
        parts.append(f"<h3>{group}: {e(DESCRIPTION[group])}</h3><p class='small'>{e(target)}; cells: the relative "
                     f"impact speed and the points</p><table><tr><th>{first} \\ overlap</th>{head}</tr>{rows}</table>")
    return "".join(parts)


def legend_html() -> str:
    cells = "".join(f"<td style='background:{FILL[colour]}'>{points:g} pt</td>" for points, colour in COLOURS.items())
    return (f"<table><tr><th>points (colour)</th>{cells}<td style='background:{FILL['grey']}'>run failed or timed "
            "out</td></tr></table>")


def bands_html() -> str:
    rows = []
    for group, speeds in BANDS.items():
        for speed, bands in speeds.items():
            text = ", ".join(f"&lt; {below:g} km/h: {points:g}" for below, points in bands)
            rows.append(f"<tr><td>{group}</td><td class='n'>{speed} km/h</td><td>{text}; else 0</td></tr>")
    return ("<table><tr><th>group</th><th>ego speed</th><th>points by relative impact speed</th></tr>"
            + "".join(rows) + "</table>")


def plot_png(outcomes: list[TestOutcome]) -> bytes | None:
    """Relative impact speed against the ego's speed, CCRs and CCRm: one curve per overlap."""
    groups = [g for g in ("CCRs", "CCRm") if any(o.test.group == g for o in outcomes)]
    if not groups:
        return None
    fig = Figure(figsize=(9, 3.8), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(groups), squeeze=False)[0]
    markers = dict(zip(OVERLAPS_PCT, "os^vD"))
    for ax, group in zip(axes, groups):
        for overlap in OVERLAPS_PCT:
            points = sorted((o.test.ego_speed_kmh, o.relative_impact_speed_kmh) for o in outcomes
                            if o.test.group == group and o.test.overlap_pct == overlap and o.error is None)
            if points:
                ax.plot(*zip(*points), marker=markers[overlap], ms=4, lw=1, label=f"overlap {overlap:+d} %")
        ax.set(xlabel="ego speed (km/h)", ylabel="relative impact speed (km/h)", title=f"{group} (0: avoided)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    return buffer.getvalue()


def report_html(outcomes: list[TestOutcome], vehicle: dict, sheet: dict, controller: dict | None,
                tool: dict) -> str:
    e = html.escape
    rows = "".join(f"<tr><td>{g}</td><td class='n'>{t['tests']}</td><td class='n'>{t['impacts']}</td>"
                   f"<td class='n'>{t['points']:.2f} / {t['max_points']:.0f}</td><td class='n'>{t['score_pct']:.1f} %"
                   f"</td><td class='n'>{t['errors']}</td><td class='n'>{t['timeouts']}</td></tr>"
                   for g, t in totals(outcomes).items())
    image = plot_png(outcomes)
    figure = (f"<img alt='relative impact speed against ego speed' src='data:image/png;base64,"
              f"{base64.b64encode(image).decode()}'>" if image else "")
    if controller is None:
        in_the_loop = "<p>No controller in the loop: the vehicle alone, driven at the test speed.</p>"
    else:
        in_the_loop = values_table(controller)
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>sdl-fmu AEB car-to-car pack: {e(str(vehicle.get('name')))}</title>
<style>{STYLE}</style>
</head><body><h1>AEB car-to-car rear tests</h1>{provenance_html(tool)}
<p>{e(PROTOCOL)}. Each test starts at {START_TTC_S:g} s time to collision (CCRb: at the headway, the target braking)
and ends at contact, when the ego stops or when it is slower than the target. Target: {TARGET_LENGTH_M:g} m x
{TARGET_WIDTH_M:g} m. How the tests are made and scored: docs/verification.md.</p>
<table><tr><th>vehicle</th><td>{e(str(vehicle.get('name')))} ({e(str(vehicle.get('fmu')))})</td></tr>
<tr><th>GUID</th><td>{e(str(vehicle.get('guid')))}</td></tr><tr><th>map</th><td>{e(str(vehicle.get('map')))}</td></tr>
</table>
<h2>Totals</h2><table><tr><th>group</th><th>tests</th><th>impacts</th><th>points</th><th>score</th>
<th>runs failed</th><th>timed out</th></tr>{rows}</table>
<h2>The grids</h2>{legend_html()}{grid_html(outcomes)}{figure}
<h2>Controller</h2>{in_the_loop}
{datasheet_html(sheet)}
<h2>Scoring</h2>{bands_html()}
</body></html>
"""


def write(out, outcomes: list[TestOutcome], vehicle: dict, sheet: dict, controller: dict | None, tool: dict) -> Path:
    """Writes the results folder atomically (results/folder.py's rules); returns it."""

    def contents(folder: Path) -> None:
        (folder / JSON_NAME).write_text(json.dumps(document(outcomes, vehicle, sheet, controller, tool), indent=2)
                                        + "\n", encoding="utf-8")
        write_csv(folder / CSV_NAME, outcomes)
        (folder / HTML_NAME).write_text(report_html(outcomes, vehicle, sheet, controller, tool), encoding="utf-8")

    return write_results_folder(out, contents, "verify")
