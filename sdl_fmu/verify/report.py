"""The vehicle test pack's results folder: verify.json, one CSV of time series per manoeuvre, report.html (self-
contained: its plots are embedded PNGs), and the pass/fail table printed by the command."""

from __future__ import annotations

import base64
import html
import io
import json
import math
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Polygon

from ..results.folder import write_results_folder
from .drive import COLUMNS
from .outcome import VERDICTS, Outcome
from .quantities import label, shown

JSON_NAME, HTML_NAME = "verify.json", "report.html"
FORMAT = "sdl-fmu verify 1"
HEADLINE = {  # the metrics shown in the table, per manoeuvre
    "braking": ("stopping_distance_m", "mfdd_mps2"),
    "steady_state_circular": ("understeer_gradient_deg_per_g", "max_lateral_acceleration_mps2"),
    "step_steer": ("yaw_rate_response_time_s", "yaw_rate_overshoot_pct"),
    "sine_with_dwell": ("yaw_rate_ratio_1_00s", "yaw_rate_ratio_1_75s", "lateral_displacement_1_07s_m"),
    "split_mu_braking": ("max_yaw_angle_deg", "stopping_distance_m"),
    "double_lane_change": ("max_entry_speed_kmh",),
}


def verdict(passed: bool | None, reason: str | None = None) -> str:
    if passed is None:
        return "n/a" if reason else "report"
    return "pass" if passed else "FAIL"


def _json_ready(value):
    if isinstance(value, dict):
        return {k: _json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_ready(v) for v in value]
    if isinstance(value, (np.floating, float)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value


def passed(outcomes: list[Outcome]) -> bool:
    """Whether no criterion failed (--strict's test): every manoeuvre passed or has no criterion."""
    return all(o.passed is not False for o in outcomes)


def totals(outcomes: list[Outcome]) -> dict:
    """How many manoeuvres and how many criteria have each verdict (pass, FAIL, n/a, report): n/a is never counted
    as failed."""
    manoeuvres = [verdict(o.passed, o.reason) for o in outcomes]
    criteria = [entry["verdict"] for o in outcomes for entry in o.criterion_verdicts()]
    return {"manoeuvres": {v: manoeuvres.count(v) for v in VERDICTS},
            "criteria": {v: criteria.count(v) for v in VERDICTS}}


def totals_line(outcomes: list[Outcome]) -> str:
    counted = totals(outcomes)["criteria"]
    return "criteria: " + ", ".join(f"{counted[v]} {v}" for v in VERDICTS)


def document(vehicle: dict, outcomes: list[Outcome], sheet: dict | None = None, tool: dict | None = None) -> dict:
    return _json_ready({"format": FORMAT, "pack": "vehicle", "tool": tool, "vehicle": vehicle, "datasheet": sheet,
                        "passed": passed(outcomes), "totals": totals(outcomes), "manoeuvres": {o.name: o.to_json() for o in outcomes}})


def table(outcomes: list[Outcome]) -> str:
    lines = [f"{'manoeuvre':<22} {'result':<7} metrics", "-" * 78]
    for o in outcomes:
        values = []
        for key in HEADLINE.get(o.name, ()):
            value = o.metrics.get(key)
            if isinstance(value, float):
                values.append(f"{label(key)} {shown(key, value)}")
        text = ", ".join(values) if values else ""
        if o.reason:
            text = o.reason if not text else f"{text}; {o.reason}"
        lines.append(f"{o.name:<22} {verdict(o.passed, o.reason):<7} {text}")
        lines.extend(f"{'':<22} {'n/a':<7} {entry['criterion']}: {entry['reason']}"
                     for entry in o.criterion_verdicts() if entry["verdict"] == "n/a" and entry["reason"] != o.reason)
    lines.append(totals_line(outcomes))
    return "\n".join(lines)


def write_csv(path: Path, outcome: Outcome) -> None:
    with path.open("w", encoding="utf-8", newline="\n") as stream:
        stream.write("run," + ",".join(COLUMNS) + "\n")
        for run, trace in outcome.runs:
            block = np.column_stack([trace[c] for c in COLUMNS])
            name = run.replace(",", ";")
            for row in block:
                stream.write(name + "," + ",".join(f"{v:.9g}" for v in row) + "\n")


# --- plots: each manoeuvre's standard plot ---------------------------------------------------------------


def _braking(fig, o):
    ax = fig.add_subplot()
    for run, t in o.runs:
        after = t["time_s"] >= 0
        ax.plot(t["distance_m"][after] - t["distance_m"][after][0], t["speed_mps"][after] * 3.6, label=run)
    if "stopping_distance_limit_m" in o.metrics:
        ax.axvline(o.metrics["stopping_distance_limit_m"], color="tab:red", ls="--", label="R13-H limit")
    ax.set(xlabel="distance since brake application (m)", ylabel="speed (km/h)", title="Type-0 stop")
    ax.legend()


def _circular(fig, o):
    ax = fig.add_subplot()
    wheelbase = o.plot.get("wheelbase", 0.0)
    for (label, t), color in zip(o.runs, ("tab:blue", "tab:orange")):
        after = t["time_s"] >= 0
        sign = 1.0 if label == "left" else -1.0
        ay = sign * t["ay_mps2"][after]
        excess = np.degrees(sign * (t["steer_rad"][after] - wheelbase * t["yaw_rate_radps"][after] / np.maximum(
            t["speed_mps"][after], 0.1)))
        ax.plot(ay, excess, lw=0.6, color=color, alpha=0.6)
        entry = o.metrics.get("directions", {}).get(label, {})
        points = entry.get("steady_points", [])
        ax.plot([q["lateral_acceleration_mps2"] for q in points], [np.degrees(q["steer_excess_rad"]) for q in points],
                "o", color=color, label=f"{label}: steady points, {entry.get('understeer_gradient_deg_per_g', 0):.2f} "
                                        "deg/g")
    ax.set(xlabel="lateral acceleration (m/s2)", ylabel="road-wheel angle (deg)",
           title="constant radius 100 m: steer - Ackermann steer against lateral acceleration")
    ax.legend()


def _step(fig, o):
    ax = fig.add_subplot()
    for (label, t), color in zip(o.runs, ("tab:blue", "tab:orange")):
        entry = o.metrics.get("directions", {}).get(label.split()[0], {})
        r_ss = entry.get("steady_state_yaw_rate_radps") or 1.0
        ay_ss = entry.get("steady_state_lateral_acceleration_mps2") or 1.0
        ax.plot(t["time_s"], t["steer_rad"] / (entry.get("steer_rad") or 1.0), color="gray", lw=0.8)
        ax.plot(t["time_s"], t["yaw_rate_radps"] / r_ss, color=color, label=f"{label.split()[0]}: yaw rate / steady")
        ax.plot(t["time_s"], t["ay_mps2"] / ay_ss, color=color, ls="--", label=f"{label.split()[0]}: a_y / steady")
    ax.axhline(0.9, color="gray", ls=":", label="90 %")
    ax.set(xlim=(-0.2, o.runs[-1][1]["time_s"][-1]), xlabel="time (s)", ylabel="normalised (grey: steer)",
           title="step steer response")
    ax.legend()


def _sine(fig, o):
    ax = fig.add_subplot()
    runs = o.metrics.get("runs", [])
    traces = [tr for label, tr in o.runs if not label.startswith("slowly increasing steer")]
    for run, t in zip(runs, traces):
        sign = -1.0 if run["direction"] == "left" else 1.0
        ax.plot(t["time_s"], sign * t["yaw_rate_radps"] / run["peak_yaw_rate_radps"], lw=0.8,
                color="tab:blue" if run["direction"] == "left" else "tab:orange")
    cosi = o.plot.get("cosi", 0)
    for delay, limit in zip(o.plot.get("after_cosi", ()), o.plot.get("limits", ())):
        ax.axvline(cosi + delay, color="gray", ls=":")
        ax.plot([cosi + delay - 0.15, cosi + delay + 0.15], [limit, limit], color="tab:red", lw=2)
        ax.annotate(f"{delay:.2f} s after COSI: <= {limit}", (cosi + delay, limit), textcoords="offset points",
                    xytext=(4, 6), fontsize=8)
    ax.axvline(cosi, color="black", ls="--", lw=0.8)
    ax.set(xlabel="time from the start of the steer (s)", ylabel="yaw rate / its peak",
           title="sine with dwell: yaw rate of each run", ylim=(-1.5, 1.5))
    ax.legend(handles=[Line2D([], [], color="tab:blue", lw=0.8, label="left first"),
                       Line2D([], [], color="tab:orange", lw=0.8, label="right first"),
                       Line2D([], [], color="black", ls="--", lw=0.8, label="completion of steer (COS)"),
                       Line2D([], [], color="tab:red", lw=2, label="S5.2 limits on the ratio")], fontsize=8)


def _split(fig, o):
    ax, path = fig.subplots(1, 2)
    for _, t in o.runs:
        after = t["time_s"] >= 0
        ax.plot(t["time_s"][after], np.degrees(t["yaw_rad"][after]))
        path.plot(t["x_m"][after], t["y_m"][after])
    ax.set(xlabel="time since brake application (s)", ylabel="yaw angle (deg)", title="split-mu braking: yaw angle")
    path.set(xlabel="x (m)", ylabel="y (m)", title="path of the centre of gravity (mu 0.8 left, 0.2 right)")


def _lane_change(fig, o):
    ax = fig.add_subplot()
    for k, lane in enumerate(o.plot.get("lanes", [])):
        for j, y in enumerate((lane["right"], lane["left"])):
            ax.plot([lane["start"], lane["end"]], [y, y], color="tab:orange", marker="^", ms=6, lw=0.8,
                    label="cones (lane limits)" if k == j == 0 else None)
    if "path" in o.plot:
        ax.plot(*o.plot["path"], color="gray", ls=":", lw=1, label="driver's path")
    length, width = o.plot.get("length", 4.5), o.plot.get("width", 1.8)
    for (run, t), color in zip(o.runs, ("tab:green", "tab:red")):
        ax.plot(t["x_m"], t["y_m"], color=color, label=run)
        for k in range(0, len(t["x_m"]), 25):
            c, s = math.cos(t["yaw_rad"][k]), math.sin(t["yaw_rad"][k])
            corners = [(t["x_m"][k] + lx * c - ly * s, t["y_m"][k] + lx * s + ly * c)
                       for lx, ly in ((length / 2, width / 2), (length / 2, -width / 2),
                                      (-length / 2, -width / 2), (-length / 2, width / 2))]
            ax.add_patch(Polygon(corners, fill=False, edgecolor=color, lw=0.4))
    ax.set(xlim=(-5, 70), xlabel="x (m)", ylabel="y (m)", title="ISO 3888-2 track: path between the cones")
    ax.set_aspect("equal")
    ax.legend(fontsize=8)


PLOTS = {"braking": _braking, "steady_state_circular": _circular, "step_steer": _step, "sine_with_dwell": _sine,
         "split_mu_braking": _split, "double_lane_change": _lane_change}


def png(outcome: Outcome) -> bytes | None:
    if not outcome.runs:
        return None
    from ..text import plain_text  # the vehicle's name and any other text drawn as written (no mathtext)

    with plain_text():
        fig = Figure(figsize=(9, 4.2), dpi=100, layout="constrained")
        FigureCanvasAgg(fig)
        PLOTS[outcome.name](fig, outcome)
        buffer = io.BytesIO()
        fig.savefig(buffer, format="png")
    return buffer.getvalue()


STYLE = """body{font-family:sans-serif;max-width:1000px;margin:auto} td,th{border:1px solid #ccc;padding:3px 6px;
text-align:left;vertical-align:top} table{border-collapse:collapse;margin-bottom:8px} td.n{text-align:right}
.pass{color:#070} .FAIL{color:#b00;font-weight:bold} .na{color:#555} .reason{color:#b00} img{max-width:100%} .small{color:#555;
font-size:90%}"""
SHEET_TITLES = {"identity": "FMU", "mass_and_geometry": "Mass and geometry", "drive_and_brakes": "Drive and brakes",
                "tires": "Tires", "parameters_set": "Parameters set for this report (--param, SI)"}


def values_table(values: dict) -> str:
    """A table of key, value rows, each value rounded to its meaning with its unit; a list of records as a table of
    its own (sine-with-dwell runs, tire slots)."""
    e = html.escape
    rows = []
    for key, value in values.items():
        if isinstance(value, list) and value and all(isinstance(item, dict) for item in value):
            columns = list(value[0])
            head = "".join(f"<th>{e(label(c))}</th>" for c in columns)
            body = "".join("<tr>" + "".join(f"<td class='n'>{e(shown(c, item.get(c)))}</td>" for c in columns)
                           + "</tr>" for item in value)
            rows.append(f"<tr><th>{e(label(key))}</th><td><table><tr>{head}</tr>{body}</table></td></tr>")
        else:
            rows.append(f"<tr><th>{e(label(key))}</th><td class='n'>{e(shown(key, value))}</td></tr>")
    return f"<table>{''.join(rows)}</table>"


def datasheet_html(sheet: dict | None) -> str:
    """The vehicle data sheet (datasheet.py) as one table per section."""
    if not sheet:
        return ""
    parts = [f"<h3>{html.escape(SHEET_TITLES.get(section, section))}</h3>{values_table(values)}"
             for section, values in sheet.items() if values]
    return "<h2>Vehicle data sheet</h2>" + "".join(parts)


def provenance_html(tool: dict | None) -> str:
    if not tool:
        return ""
    return (f"<p class='small'>Made by {html.escape(tool['tool'])} {html.escape(tool['version'])} on "
            f"{html.escape(tool['date'])} (UTC).</p>")


def css(verdict_: str) -> str:
    return "na" if verdict_ == "n/a" else verdict_


def criteria_html(o: Outcome) -> str:
    """Each criterion of a manoeuvre on its line, its verdict coloured (n/a with its reason)."""
    e = html.escape
    return "<br>".join(f"<span class='{css(entry['verdict'])}'>{e(text)}</span>"
                       for entry, text in zip(o.criterion_verdicts(), o.criteria))


def report_html(vehicle: dict, outcomes: list[Outcome], sheet: dict | None = None, tool: dict | None = None) -> str:
    e = html.escape
    rows = "".join(f"<tr><td>{e(o.name)}</td><td>{e(o.standard)}</td><td class='{css(verdict(o.passed, o.reason))}'>"
                   f"{verdict(o.passed, o.reason)}</td><td>{criteria_html(o)}</td></tr>" for o in outcomes)
    identity = "".join(f"<tr><th>{e(k)}</th><td>{e(str(v))}</td></tr>" for k, v in vehicle.items())
    sections = []
    for o in outcomes:
        image = png(o)
        figure = (f"<img alt='{e(o.name)} plot' src='data:image/png;base64,{base64.b64encode(image).decode()}'>"
                  if image else "")
        reason = f"<p class='reason'>{e(o.reason)}</p>" if o.reason else ""
        sections.append(f"<h2>{e(o.name)}: {verdict(o.passed, o.reason)}</h2><p>{e(o.standard)}</p>{reason}"
                        f"{values_table(_json_ready(o.metrics))}{figure}")
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>sdl-fmu vehicle test pack: {e(str(vehicle.get('name')))}</title>
<style>{STYLE}</style>
</head><body><h1>Vehicle test pack</h1>{provenance_html(tool)}<table>{identity}</table>
<h2>Results</h2><table><tr><th>manoeuvre</th><th>source</th><th>result</th><th>criteria</th></tr>{rows}</table>
<p>{e(totals_line(outcomes))} (n/a: the criterion does not apply to this vehicle, with its reason; never a failure)</p>
{datasheet_html(sheet)}
{''.join(sections)}</body></html>
"""


def write(out, vehicle: dict, outcomes: list[Outcome], sheet: dict | None = None, tool: dict | None = None) -> Path:
    """Writes the results folder atomically (results/folder.py's rules); returns it."""

    def contents(folder: Path) -> None:
        (folder / JSON_NAME).write_text(json.dumps(document(vehicle, outcomes, sheet, tool), indent=2) + "\n",
                                        encoding="utf-8")
        for o in outcomes:
            if o.runs:
                write_csv(folder / f"{o.name}.csv", o)
        (folder / HTML_NAME).write_text(report_html(vehicle, outcomes, sheet, tool), encoding="utf-8")

    return write_results_folder(out, contents, "verify")
