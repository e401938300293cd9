"""plot.png: one figure that shows a run at a glance (time histories above, the road seen from above below).

The figure is built on a bare matplotlib `Figure` with an explicit Agg canvas: no display is needed and the
caller's pyplot backend is left alone.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.colors import TwoSlopeNorm
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, Rectangle

from ..names import WHEELS
from ..units import from_si, length_label, speed_label
from . import scenario_units

if TYPE_CHECKING:
    from .record import RunRecord

LABEL_GAP_PX = 4.0  # pixels between two labels in one row
LABEL_TOP = 0.97  # axis fraction of the first row of event labels
LABEL_ROW = 0.075  # axis fraction per row of event labels
MAX_LABEL_ROWS = 6
MAX_LABELLED_VEHICLES = 12  # vehicles named in the legend and on the road; the rest summarised
MAX_LINE_POINTS = 4000  # lines are decimated to this many points: the figure is ~1800 px wide anyway
MAX_TRAFFIC_POINTS = 60_000  # points of all traffic paths together, when more than MAX_LABELLED_VEHICLES are drawn
NOMINAL_MU = 0.8
WHEEL_STYLES = {"fl": "-", "fr": "--", "rl": "-.", "rr": ":"}
TRAFFIC_COLORS = ("tab:orange", "tab:green", "tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:cyan",
                  "tab:gray")
EVENT_COLORS = {"BRK": "tab:red", "A": "tab:purple", "RSA": "#9a7b00", "ES": "black"}
ATTRIBUTE_COLORS = ("#ffffff", "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
                    "#17becf", "#bcbd22")
EGO_COLOR = "tab:blue"
LEAD_COLOR = "tab:green"
BRK_COLOR = "tab:red"
LANE_FILL = "#f7f7f7"
SHOULDER_FILL = "#d9d9d9"
GROUND_FILL = "#edf4e8"


# The figure's layout, fixed (figure fractions): measured once against matplotlib's constrained layout of the
# shipped examples, it leaves room for the titles, the axis labels and the twin axes' labels; the road panels
# are narrowed at run time to fit their legend. A layout engine would cost more than the rest of the plot.
FIGURE_SIZE = (16, 13.5)  # inches
FIGURE_DPI = 110
LAYOUT = dict(left=0.055, right=0.955, top=0.92, bottom=0.04, hspace=0.4, wspace=0.22)
COLORBAR_LEFT = 0.935  # figure fraction: the RSA colorbar beside the road panels


def _stride(samples: int) -> int:
    """Step that keeps a line under MAX_LINE_POINTS points (spans and markers still use every sample)."""
    return max(1, math.ceil(samples / MAX_LINE_POINTS))


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) sample indices of each run of True in mask."""
    padded = np.concatenate(([False], np.asarray(mask, dtype=bool), [False]))
    edges = np.flatnonzero(np.diff(padded.astype(np.int8)))
    return [(int(start), int(stop) - 1) for start, stop in zip(edges[::2], edges[1::2])]


def _event_label(event: dict) -> str:
    """Short text for an event marker: 'BRK on', 'A1 spawn', 'A1 m2', 'A1 collision', 'RSA 1=3', 'ES'."""
    code, action = event.get("code", "?"), event.get("action", "")
    if code == "A":
        vehicle = f"A{event.get('vehicle', '?')}"
        if action == "maneuver":
            return f"{vehicle} m{event.get('index', '?')}"
        return f"{vehicle} {action}"
    if code == "BRK":
        reason = event.get("reason")
        return f"BRK {action} ({reason})" if action == "off" and reason else f"BRK {action}"
    if code == "RSA":
        return f"RSA {event.get('lane', '?')}={event.get('value', '?')}"
    return str(code) if code == "ES" or not action else f"{code} {action}"


def _event_color(event: dict) -> str:
    """Red for collisions and braking, one colour per event code otherwise."""
    if event.get("action") == "collision":
        return "red"
    return EVENT_COLORS.get(event.get("code"), "tab:gray")


def _timed_events(result: RunRecord) -> list[dict]:
    """Events that carry a finite time, in time order, in the scenario's units."""
    timed = [e for e in scenario_units.Events(result.events, result.units)
             if isinstance(e.get("time_s"), (int, float)) and math.isfinite(e["time_s"])]
    return sorted(timed, key=lambda e: e["time_s"])


def _mark_events(ax, events: list[dict]) -> None:
    """Thin vertical lines at event instants (the speed panel adds the labels); one artist per style,
    however many events."""
    transform = ax.get_xaxis_transform()
    fade = min(1.0, 100 / max(len(events), 1))  # thousands of markers would hide the curves: fainter
    for collision, lw, alpha, ls in ((False, 0.9, 0.35 * fade, "--"), (True, 1.6, 0.8, "-")):
        chosen = [event for event in events if (event.get("action") == "collision") == collision]
        if chosen:
            times, colors = _marker_lines([event["time_s"] for event in chosen],
                                          [_event_color(event) for event in chosen])
            ax.vlines(times, 0, 1, transform=transform, lw=lw, alpha=alpha, linestyles=ls, colors=colors, zorder=1)


MAX_EVENT_MARKERS = 2000  # more event lines than this are merged where they fall on one of MAX_LINE_POINTS slots


def _marker_lines(times: list[float], colors: list[str]) -> tuple[list[float], list[str]]:
    """The event lines to draw: all of them, or beyond MAX_EVENT_MARKERS one per colour and slot of the run's span
    (MAX_LINE_POINTS slots, finer than the panel's pixels), so that the lines follow the picture, not the events."""
    if len(times) <= MAX_EVENT_MARKERS:
        return times, colors
    low, span = min(times), (max(times) - min(times)) or 1.0
    kept = {}
    for time, color in zip(times, colors):
        kept.setdefault((round((time - low) / span * MAX_LINE_POINTS), color), time)
    return list(kept.values()), [color for _, color in kept]


def _label_rows(spans: list[tuple[float, float]], right: float) -> list[tuple[int | None, str]]:
    """(row, alignment) for labels of the given (x, width) in pixels, in time order: each drawn rightward from its
    line, or leftward where it would pass the axes' right end at `right`, and greedily packed into the first of
    MAX_LABEL_ROWS rows where it clears the previous label by LABEL_GAP_PX; row None: no row has room (the label
    is left out rather than drawn over another)."""
    row_ends: list[float] = []  # right end (pixels) of the last label in each row
    placed = []
    for x, width in spans:
        start, end, align = (x, x + width, "left") if x + width <= right else (x - width, x, "right")
        row = next((k for k, row_end in enumerate(row_ends) if row_end + LABEL_GAP_PX < start), None)
        if row is None and len(row_ends) < MAX_LABEL_ROWS:
            row_ends.append(-math.inf)
            row = len(row_ends) - 1
        if row is not None:
            row_ends[row] = end
        placed.append((row, align))
    return placed


LABEL_PRIORITY = {"collision": 0, "BRK": 1, "ES": 1, "RSA": 2, "maneuver": 3, "spawn": 4, "despawn": 5}
MAX_EVENT_LABELS = 48  # more events than this (long runs, many vehicles): the most telling ones are labelled


def _label_events(ax, events: list[dict]) -> list:
    """Event labels at the top of the panel, placed by `_pack_labels` once the figure's layout is known. With
    more than MAX_EVENT_LABELS events only that many are labelled, collisions and BRK first, spawns and departures
    last."""
    if len(events) > MAX_EVENT_LABELS:
        # within one priority, a low-discrepancy order (k x golden ratio mod 1) spreads the labels over the run
        ranked = sorted(range(len(events)), key=lambda k: (LABEL_PRIORITY.get(events[k].get("action"),
                                                           LABEL_PRIORITY.get(events[k].get("code"), 3)),
                                                           (k * 0.6180339887) % 1.0))
        events = [events[k] for k in sorted(ranked[:MAX_EVENT_LABELS])]
    transform = ax.get_xaxis_transform()
    return [ax.text(event["time_s"], LABEL_TOP, f" {_event_label(event)} ", transform=transform, ha="left",
                    va="top", fontsize=7.5, color=_event_color(event), clip_on=True, zorder=3,
                    bbox=dict(boxstyle="square,pad=0.1", facecolor="white", edgecolor="none", alpha=0.8))
            for event in events]


def _pack_labels(figure, ax, labels: list, top: float) -> None:
    """Places the event labels in rows by their drawn widths (measured on the fixed layout, without a draw), so that none
    overlaps another (a label no row has room for is left out), and leaves the panel's curve (up to `top`) below
    the rows."""
    if labels:
        renderer = figure.canvas.get_renderer()  # the layout is fixed: widths are measured without drawing
        box = ax.get_window_extent(renderer)
        spans = [(ax.transData.transform((label.get_position()[0], 0.0))[0],
                  label.get_window_extent(renderer).width) for label in labels]
        placed = _label_rows(spans, box.x1)
        for label, (row, align) in zip(labels, placed):
            if row is None:
                label.set_visible(False)
            else:
                label.set_y(LABEL_TOP - row * LABEL_ROW)
                label.set_horizontalalignment(align)
        rows = 1 + max((row for row, _ in placed if row is not None), default=-1)
    else:
        rows = 0
    free = LABEL_TOP - rows * LABEL_ROW - 0.03  # axis fraction left below the labels
    ax.set_ylim(0, max(top, 1e-6) / max(free, 0.5))


def _shade_brk(ax, time: np.ndarray, brk_runs: list[tuple[int, int]], label: bool) -> None:
    """Shade the spans where a BRK event holds the pedals (one artist, however many spans)."""
    if not brk_runs:
        return
    spans = [[(time[first], 0.0), (time[first], 1.0), (time[last], 1.0), (time[last], 0.0)]
             for first, last in brk_runs]
    ax.add_collection(PolyCollection(spans, transform=ax.get_xaxis_transform(), facecolor=BRK_COLOR, alpha=0.12,
                                     lw=0, label="BRK active" if label else None), autolim=False)


def _final_text(result: RunRecord, time: np.ndarray, distance: np.ndarray) -> str:
    """'final: 1234.5 ft at t = 20.00 s' from the summary's final entry, else the last sample."""
    final = scenario_units.final(result.final or {}, result.units)

    def number(key: str, fallback: np.ndarray) -> float:
        value = final.get(key)
        if isinstance(value, (int, float)):
            return float(value)
        return float(fallback[-1]) if len(fallback) else float("nan")

    final_distance, final_time = number("distance", distance), number("time_s", time)
    final_speed = final.get("speed")
    text = f"final: {final_distance:.1f} {length_label(result.units)} at t = {final_time:.2f} s"
    if isinstance(final_speed, (int, float)):
        text += f", {final_speed:.1f} {speed_label(result.units)}"
    return text


def _plot_time_panels(result: RunRecord, axes: dict, time: np.ndarray, brk_runs, lead: dict | None) -> tuple:
    """Speed (the lead vehicle's too), distance, pedals + steer and friction over time; returns the speed panel's
    event labels and its highest speed (for `_pack_labels`)."""
    units = result.units
    cols = result.columns
    step = _stride(len(time))
    t = time[::step]
    events = _timed_events(result)

    ax = axes["speed"]
    speed = from_si(np.asarray(cols["v"], dtype=float), units)
    _shade_brk(ax, time, brk_runs, label=True)
    ax.plot(t, speed[::step], color=EGO_COLOR, lw=1.5, label="ego speed")
    speed_top = np.nanmax(speed) if len(speed) and np.isfinite(speed).any() else 1.0
    if lead is not None:
        lead_speed = from_si(np.where(lead["present"], lead["speed"], np.nan), units)
        ax.plot(t, lead_speed[::step], color=LEAD_COLOR, lw=1.3, ls="--", label="lead vehicle speed")
        speed_top = max(speed_top, float(np.nanmax(lead_speed)))
    _mark_events(ax, events)
    labels = _label_events(ax, events)
    ax.set_ylabel(f"speed [{speed_label(units)}]")
    ax.set_title("speed (BRK spans shaded, events marked)", fontsize=10, loc="left", y=1.0)
    ax.legend(loc="lower left", fontsize=8)

    ax = axes["distance"]
    distance = from_si(np.asarray(cols["s"], dtype=float), units)
    _shade_brk(ax, time, brk_runs, label=False)
    ax.plot(t, distance[::step], color=EGO_COLOR, lw=1.5)
    _mark_events(ax, events)
    dots = [event for event in events if isinstance(event.get("distance"), (int, float))]
    if dots:
        ax.scatter([event["time_s"] for event in dots], [event["distance"] for event in dots], s=16, zorder=3,
                   color=[_event_color(event) for event in dots])
    ax.set_ylabel(f"distance travelled [{length_label(units)}]")
    ax.set_title("distance travelled (dots: events)", fontsize=10, loc="left", y=1.0)

    ax = axes["pedals"]
    _shade_brk(ax, time, brk_runs, label=False)
    ax.plot(t, np.asarray(cols["throttle"], dtype=float)[::step], color="tab:green", lw=1.3, label="throttle")
    ax.plot(t, np.asarray(cols["brake"], dtype=float)[::step], color="tab:red", lw=1.3, label="brake")
    _mark_events(ax, events)
    ax.set_ylim(-0.05, 1.08)
    ax.set_ylabel("pedal [1]")
    ax.set_xlabel("time [s]")
    steer_ax = ax.twinx()
    steer = np.asarray(cols["steer"], dtype=float)
    steer_ax.plot(t, steer[::step], color="tab:purple", lw=1.1, label="steer")
    limit = max(float(np.nanmax(np.abs(steer))) if np.isfinite(steer).any() else 0.0, 0.01) * 1.2
    steer_ax.set_ylim(-limit, limit)
    steer_ax.set_ylabel("steer [rad] (+ left)", color="tab:purple")
    steer_ax.tick_params(axis="y", colors="tab:purple")
    handles = ax.get_legend_handles_labels()[0] + steer_ax.get_legend_handles_labels()[0]
    ax.legend(handles=handles, loc="upper right", fontsize=8, ncols=3)
    ax.set_title("driver inputs", fontsize=10, loc="left", y=1.0)

    ax = axes["friction"]
    _mark_events(ax, events)
    simple = any(f"mu_{w}" in cols for w in WHEELS)
    prefix = "mu" if simple else "surface"
    values = []
    for wheel in WHEELS:
        if f"{prefix}_{wheel}" in cols:
            value = np.asarray(cols[f"{prefix}_{wheel}"], dtype=float)
            values.append(value)
            ax.plot(t, value[::step], ls=WHEEL_STYLES[wheel], lw=1.4, drawstyle="steps-post", label=wheel)
    top = float(np.nanmax(values)) if values and np.isfinite(values).any() else 1.0
    if simple:
        ax.set_ylim(0, max(1.0, top) * 1.1)
        ax.set_ylabel("mu [1]")
        ax.set_title("friction coefficient under each wheel", fontsize=10, loc="left", y=1.0)
    else:
        ax.set_ylim(-0.5, top + 0.5)
        ax.yaxis.get_major_locator().set_params(integer=True)
        ax.set_ylabel("surface attribute")
        ax.set_title("road surface attribute under each wheel", fontsize=10, loc="left", y=1.0)
    if values:
        ax.legend(loc="lower right", fontsize=8, ncols=4)
    ax.set_xlabel("time [s]")
    return labels, speed_top


def _plot_yaw_panel(result: RunRecord, ax, time: np.ndarray, brk_runs, narrow: bool = False) -> None:
    """Heading, side slip and road-wheel steer (deg, left axis) and yaw rate (deg/s, right axis): a skid or
    spin and the driver's counter-steer at a glance. ISO 8855 signs: + left (counter-clockwise)."""
    cols = result.columns
    step = _stride(len(time))
    t = time[::step]
    _shade_brk(ax, time, brk_runs, label=False)
    _mark_events(ax, _timed_events(result))
    heading = np.degrees(np.asarray(cols["psi"], dtype=float))
    sideslip = np.degrees(np.arctan2(np.asarray(cols["vy"], dtype=float), np.asarray(cols["vx"], dtype=float)))
    steer = np.degrees(np.asarray(cols["steer"], dtype=float))
    ax.plot(t, heading[::step], color="tab:blue", lw=1.5, label="heading psi")
    ax.plot(t, sideslip[::step], color="tab:orange", lw=1.2, label="side slip beta")
    ax.plot(t, steer[::step], color="tab:purple", lw=1.2, label="steer (road wheels)")
    ax.set_ylabel("angle [deg] (+ left)")
    rate_ax = ax.twinx()
    yaw_rate = np.degrees(np.asarray(cols["yaw_rate"], dtype=float))
    rate_ax.plot(t, yaw_rate[::step], color="tab:red", lw=1.0, ls="--", label="yaw rate")
    limit = max(float(np.nanmax(np.abs(yaw_rate))) if np.isfinite(yaw_rate).any() else 0.0, 1.0) * 1.15
    rate_ax.set_ylim(-limit, limit)
    rate_ax.set_ylabel("yaw rate [deg/s]", color="tab:red")
    rate_ax.tick_params(axis="y", colors="tab:red")
    angles = np.concatenate([heading, sideslip, steer])
    angle_limit = max(float(np.nanmax(np.abs(angles))) if np.isfinite(angles).any() else 0.0, 1.0) * 1.15
    ax.set_ylim(-angle_limit, angle_limit)  # zero of both axes on one line
    handles = ax.get_legend_handles_labels()[0] + rate_ax.get_legend_handles_labels()[0]
    ax.legend(handles=handles, loc="upper right", fontsize=8, ncols=4)
    ax.set_title("heading, side slip, steering and yaw rate" + ("" if narrow else " (a skid: heading and yaw rate "
                 "away from 0, counter-steer opposite)"), fontsize=10, loc="left", y=1.0)
    ax.set_xlabel("time [s]")


def _plot_lead_panel(result: RunRecord, ax, time: np.ndarray, lead: dict) -> None:
    """The lead vehicle (a vehicle ahead in the ego's path, docs/results.md): the bumper-to-bumper gap to it (left
    axis) and its speed relative to the ego's along the road (right axis, negative while the gap closes), each
    stretch named by the vehicle's id."""
    units = result.units
    step = _stride(len(time))
    t = time[::step]
    present = lead["present"]
    gap = from_si(np.where(present, lead["gap"], np.nan), units)
    relative = from_si(np.where(present, lead["relative_speed"], np.nan), units)
    ax.plot(t, gap[::step], color=LEAD_COLOR, lw=1.5, label="bumper gap")
    ax.set_ylim(0, max(float(np.nanmax(gap)), 1e-6) * 1.15)
    ax.set_ylabel(f"gap to the lead [{length_label(units)}]")
    for first, last in _runs(present):
        # a new stretch where the lead vehicle changes: named at its start
        index = lead["index"][first:last + 1]
        for start in [first] + (np.flatnonzero(np.diff(index)) + first + 1).tolist():
            ax.annotate(f"A{int(lead['index'][start]) + 1}", (time[start], gap[start]), xytext=(2, 4),
                        textcoords="offset points", fontsize=8, color=LEAD_COLOR, fontweight="bold")
    rate_ax = ax.twinx()
    rate_ax.plot(t, relative[::step], color="tab:gray", lw=1.0, ls="--", label="lead speed - ego speed")
    rate_ax.axhline(0.0, color="tab:gray", lw=0.6, alpha=0.5)
    rate_ax.set_ylabel(f"relative speed [{speed_label(units)}]", color="tab:gray")
    rate_ax.tick_params(axis="y", colors="tab:gray")
    handles = ax.get_legend_handles_labels()[0] + rate_ax.get_legend_handles_labels()[0]
    ax.legend(handles=handles, loc="upper right", fontsize=8)
    ax.set_title("lead vehicle (ahead in the ego's path): gap and relative speed", fontsize=10, loc="left", y=1.0)
    ax.set_xlabel("time [s]")


def _surface_style(result: RunRecord):
    """(colour of a section value, colorbar mappable or None, legend handles) for the RSA patches."""
    values = [section.value for section in result.surfaces]
    if result.friction_meaning != "attribute":
        top = max([NOMINAL_MU * 1.5] + [value / 10 for value in values])
        norm = TwoSlopeNorm(vmin=0.0, vcenter=NOMINAL_MU, vmax=top)
        cmap = colormaps["RdBu"]
        return (lambda value: cmap(norm(value / 10))), ScalarMappable(norm=norm, cmap=cmap), []

    def color(value):
        return ATTRIBUTE_COLORS[int(value) % len(ATTRIBUTE_COLORS)]

    handles = [Patch(facecolor=color(value), edgecolor="gray", alpha=0.6,
                     label=f"surface attribute {int(value)}" + (" (standard)" if int(value) == 0 else ""))
               for value in sorted(set(values))]
    return color, None, handles


MAX_LANE_LINES = 200  # lane lines drawn at most; more within the view would be a grey smear anyway
NEAR_LANES = 4  # lanes shown beyond the outermost path on either side (the rest of a wide road is not drawn)


def _draw_road(ax, result: RunRecord, x_min: float, x_max: float,
               shown: tuple[float, float]) -> tuple[float, float]:
    """Lanes, shoulders, lane lines and RSA patches between stations x_min..x_max and lateral positions
    shown[0]..shown[1] (scenario units): what lies beyond is not drawn, so the cost does not grow with lanes
    nothing uses."""
    road, units = result.road, result.units
    width = from_si(road.lane_width, units)
    left, right = from_si(road.left_edge, units), from_si(road.right_edge, units)
    span = x_max - x_min
    ax.set_facecolor(GROUND_FILL)
    ax.add_patch(Rectangle((x_min - span, left - width), 3 * span, width, color=SHOULDER_FILL, lw=0, zorder=0))
    ax.add_patch(Rectangle((x_min - span, right), 3 * span, width, color=SHOULDER_FILL, lw=0, zorder=0))
    ax.add_patch(Rectangle((x_min - span, left), 3 * span, right - left, color=LANE_FILL, lw=0, zorder=0))

    color, _, _ = _surface_style(result)
    boxes, colors = [], []  # one collection however many sections: thousands stay fast
    for section in result.surfaces:
        start = from_si(section.start, units)
        end = x_max + span if section.end is None else from_si(section.end, units)
        if end < x_min or start > x_max or not road.has_lane(section.lane):  # a lane the road lacks
            continue
        low = from_si(road.lane_center(section.lane), units) - width / 2
        if low > shown[1] or low + width < shown[0]:
            continue
        start, end = max(start, x_min - span), min(end, x_max + span)
        boxes.append(((start, low), (start, low + width), (end, low + width), (end, low)))
        colors.append(color(section.value))
    if boxes:
        ax.add_collection(PolyCollection(boxes, facecolors=colors, alpha=0.6, lw=0, zorder=1), autolim=False)

    line = dict(zorder=2, solid_capstyle="butt")
    low, high = shown
    for edge in (left, right):
        if low <= edge <= high:
            ax.axhline(edge, color="black", lw=1.3, **line)
    for edge in (left - width, right + width):
        if low <= edge <= high:
            ax.axhline(edge, color="gray", lw=0.6, **line)
    # the lane lines k * width inside the view only: k from the first line above `low` to the last below `high`
    first_k = max(-road.lanes_left + 1, math.ceil(low / width))
    last_k = min(road.lanes_right - 1, math.floor(high / width))
    if last_k - first_k + 1 <= MAX_LANE_LINES:
        lines = [k * width for k in range(first_k, last_k + 1) if k != 0]
        if lines:
            ax.hlines(lines, x_min - span, x_max + span, colors="dimgray", lw=1.0, linestyles=(0, (6, 6)), zorder=2)
    if road.lanes_left and road.lanes_right and low <= 0.0 <= high:  # double yellow: a wide yellow line split by a lane-coloured one
        ax.axhline(0.0, color="#e6b800", lw=4.0, **line)
        ax.axhline(0.0, color=LANE_FILL, lw=1.2, **line)
    return left - width, right + width


def _lateral_limits(result: RunRecord) -> tuple[float, float]:
    """Lateral range shown: the road with shoulders as far as it lies within NEAR_LANES lanes of the ego's and
    the vehicles' paths, widened for any path that leaves it."""
    road, units = result.road, result.units
    width = from_si(road.lane_width, units)
    outer_left = from_si(road.left_edge, units) - width
    outer_right = from_si(road.right_edge, units) + width
    lows, highs = [], []
    for series in [result.columns["lateral"]] + [track.lateral for track in result.vehicles]:
        values = from_si(np.asarray(series, dtype=float), units)
        if np.isfinite(values).any():
            lows.append(float(np.nanmin(values)))
            highs.append(float(np.nanmax(values)))
    if not lows:
        lows, highs = [outer_left], [outer_right]
    low = min(max(outer_left, min(lows) - NEAR_LANES * width), min(lows))
    high = max(min(outer_right, max(highs) + NEAR_LANES * width), max(highs))
    pad = 0.04 * (high - low) if high > low else width
    return low - pad, high + pad


def _draw_paths(ax, result: RunRecord, brk_runs, x_min: float, x_max: float, annotate: bool) -> list:
    """Ego path (red where BRK holds the pedals), traffic paths and collision points; legend handles."""
    units = result.units
    station = from_si(np.asarray(result.columns["station"], dtype=float), units)
    lateral = from_si(np.asarray(result.columns["lateral"], dtype=float), units)
    visible = (station >= x_min) & (station <= x_max)
    step = _stride(int(visible.sum()) or 1)
    handles = []
    ax.plot(station[::step], lateral[::step], color=EGO_COLOR, lw=1.8, zorder=4)
    handles.append(Line2D([], [], color=EGO_COLOR, lw=1.8, label="ego"))
    if brk_runs:
        braking = np.zeros(len(station), dtype=bool)
        for first, last in brk_runs:
            braking[first:last + 1] = True
        ax.plot(station[::step], np.where(braking, lateral, np.nan)[::step], color=BRK_COLOR, lw=4, alpha=0.45,
                zorder=3, solid_capstyle="butt")
        handles.append(Line2D([], [], color=BRK_COLOR, lw=4, alpha=0.45, label="ego, BRK active"))
    if len(station):
        ax.plot(station[0], lateral[0], ">", color=EGO_COLOR, ms=8, zorder=5)

    # Traffic: one line collection and one marker call however many vehicles; legend entries and labels
    # for the first few only (MAX_LABELLED_VEHICLES), the rest summarised in one legend entry.
    many = len(result.vehicles) > MAX_LABELLED_VEHICLES
    # many vehicles share MAX_TRAFFIC_POINTS (each at least its first, middle and last point): the collection's
    # size follows the picture, not the samples
    per_vehicle = max(2, min(200, MAX_TRAFFIC_POINTS // max(len(result.vehicles), 1)))
    paths, path_colors, spawns, spawn_colors = [], [], [], []
    for number, track in enumerate(result.vehicles):
        color = TRAFFIC_COLORS[number % len(TRAFFIC_COLORS)]
        x = from_si(np.asarray(track.station, dtype=float), units)
        y = from_si(np.asarray(track.lateral, dtype=float), units)
        present = np.flatnonzero(np.isfinite(x) & np.isfinite(y))
        if not len(present) or x[present].max() < x_min or x[present].min() > x_max:
            continue
        stride = max(1, math.ceil(len(present) / per_vehicle)) if many else step
        keep = present[::stride]
        if keep[-1] != present[-1]:
            keep = np.append(keep, present[-1])
        paths.append(np.column_stack([x[keep], y[keep]]))
        path_colors.append(color)
        spawn = present[0]
        spawns.append((x[spawn], y[spawn]))
        spawn_colors.append(color)
        if number < MAX_LABELLED_VEHICLES:
            handles.append(Line2D([], [], color=color, lw=1.6, label=f"A{track.vehicle} {track.name}"))
            if annotate and x_min <= x[spawn] <= x_max:
                ax.annotate(f"A{track.vehicle}", (x[spawn], y[spawn]), xytext=(0, 7), textcoords="offset points",
                            ha="center", va="bottom", fontsize=8, color=color, fontweight="bold", zorder=6)
    if paths:
        ax.add_collection(LineCollection(paths, colors=path_colors, lw=1.0 if many else 1.6, zorder=4),
                          autolim=False)
        points = np.array(spawns)
        ax.scatter(points[:, 0], points[:, 1], c=spawn_colors, s=12 if many else 36, zorder=5)
    if many:
        handles.append(Line2D([], [], color="gray", lw=1.0, marker="o", ms=4,
                              label=f"... {len(result.vehicles) - MAX_LABELLED_VEHICLES} more vehicles"))

    if result.collision_points:
        points = np.array([(from_si(s, units), from_si(d, units)) for s, d in result.collision_points])
        ax.plot(points[:, 0], points[:, 1], "X", color="red", mec="darkred", ms=13, zorder=7)
        handles.append(Line2D([], [], marker="X", ls="", color="red", mec="darkred", ms=10, label="collision"))
    return handles


def _focus(result: RunRecord, time: np.ndarray) -> tuple[int, str] | None:
    """Sample to zoom on: the run's criticality minimum (the smallest footprint distance to any vehicle and its
    located instant, a first collision included: its distance is 0), else the first collision, else the closest
    approach of the first traffic vehicle (a record without criticality)."""
    if not len(time):
        return None
    criticality = scenario_units.criticality(result.criticality, result.units) or {}
    instant, value = criticality.get("min_distance_time_s"), criticality.get("min_distance")
    if instant is not None and value is not None:
        index = int(np.clip(np.searchsorted(time, instant), 0, len(time) - 1))
        if index > 0 and instant - time[index - 1] < time[index] - instant:
            index -= 1  # the sample nearest the instant
        who = [vehicle for vehicle in criticality.get("vehicles", [])
               if vehicle.get("min_distance_time_s") == instant and vehicle.get("min_distance") is not None
               and abs(vehicle["min_distance"] - value) <= 1e-9 * max(1.0, abs(value))]
        name = next((track.name for track in result.vehicles if who and track.vehicle == who[0]["vehicle"]), "")
        what = "collision" if value <= 0.0 else f"minimum distance {value:.4g} {length_label(result.units)}"
        subject = f" to A{who[0]['vehicle']} {name}".rstrip() if who else ""
        return index, f"{what}{subject}, t = {instant:.2f} s (the run's criticality minimum)"
    station = np.asarray(result.columns["station"], dtype=float)
    collisions = [e for e in _timed_events(result) if e.get("action") == "collision"]
    if collisions:
        index = int(np.clip(np.searchsorted(time, collisions[0]["time_s"]), 0, len(time) - 1))
        who = f" with A{collisions[0]['vehicle']}" if "vehicle" in collisions[0] else ""
        return index, f"first collision{who}, t = {time[index]:.2f} s"
    if result.collision_points:
        target = result.collision_points[0][0]
        index = int(np.argmin(np.abs(station - target)))
        return index, f"first collision, t = {time[index]:.2f} s"
    for track in result.vehicles:
        own = np.asarray(track.station, dtype=float)
        gap = np.abs(own - station[track.first:track.first + len(own)])
        if np.isfinite(gap).any():
            index = track.first + int(np.nanargmin(gap))
            return index, f"closest approach of A{track.vehicle} {track.name}, t = {time[index]:.2f} s"
    return None


def _draw_footprints(ax, result: RunRecord, index: int, x_min: float, x_max: float) -> None:
    """Traffic vehicles' footprints (those between stations x_min..x_max) and the ego's position at one sample
    (zoom panel)."""
    units = result.units
    boxes, colors = [], []  # one collection: only the footprints within the view, however many vehicles
    for number, track in enumerate(result.vehicles):
        if not track.first <= index < track.first + len(track.station):
            continue
        x, y = float(track.station[index - track.first]), float(track.lateral[index - track.first])
        if not (math.isfinite(x) and math.isfinite(y)):
            continue
        length, width = from_si(track.length, units), from_si(track.width, units)
        x, y = from_si(x, units), from_si(y, units)
        if x + length / 2 < x_min or x - length / 2 > x_max:
            continue
        boxes.append(((x - length / 2, y - width / 2), (x - length / 2, y + width / 2), (x + length / 2, y + width / 2),
                      (x + length / 2, y - width / 2)))
        colors.append(TRAFFIC_COLORS[number % len(TRAFFIC_COLORS)])
    if boxes:
        ax.add_collection(PolyCollection(boxes, facecolors=colors, edgecolors="black", alpha=0.8, lw=0.8, zorder=6),
                          autolim=False)
    ego_x = from_si(float(result.columns["station"][index]), units)
    ego_y = from_si(float(result.columns["lateral"][index]), units)
    ax.plot(ego_x, ego_y, "D", color=EGO_COLOR, mec="black", ms=8, zorder=6)


def _plot_criticality(result: RunRecord, axes: dict, time: np.ndarray) -> None:
    """The minimum-distance instant on the speed and distance panels; TTC over time where it is defined."""
    criticality = scenario_units.criticality(result.criticality, result.units) or {}
    instant = criticality.get("min_distance_time_s")
    if instant is not None:
        for name in ("speed", "distance"):
            axes[name].axvline(instant, color="tab:red", ls=":", lw=1.3)
        axes["distance"].annotate(f"min distance {criticality['min_distance']:.4g} "
                                  f"{length_label(result.units)}", (instant, 0.02), xycoords=("data", "axes fraction"),
                                  fontsize=8, color="tab:red", ha="left")
    ttc = result.ttc_series() if result.ttc_series is not None else None
    if ttc is not None and len(ttc) == len(time) and np.isfinite(ttc).any():
        twin = axes["distance"].twinx()
        twin.plot(time, ttc, color="tab:red", lw=1.0)
        twin.set_ylim(0, min(float(np.nanmax(ttc)), 10.0) * 1.05 or 1.0)
        twin.set_ylabel("time to collision [s] (red)", color="tab:red")


def plot_run(result: RunRecord, path: Path) -> None:
    """Write plot.png: speed, distance, inputs, friction, heading and yaw over time, and the road from above.
    Values at the format's extremes (km-wide views of a lane) make matplotlib's arithmetic overflow harmlessly:
    its RuntimeWarnings are not the user's concern, so they are not printed."""
    from ..text import plain_text  # names (scenario, vehicle, map) are drawn as written: `$` is not mathtext

    with warnings.catch_warnings(), np.errstate(all="ignore"), plain_text():
        warnings.simplefilter("ignore", RuntimeWarning)
        _plot_run(result, path)


def _plot_run(result: RunRecord, path: Path) -> None:
    units = result.units
    length = length_label(units)
    time = np.asarray(result.columns["time"], dtype=float)
    brk_runs = _runs(np.asarray(result.columns["brk"], dtype=float) > 0.5) if len(time) else []
    focus = _focus(result, time)

    figure = Figure(figsize=FIGURE_SIZE, dpi=FIGURE_DPI)  # a fixed layout (LAYOUT): no layout engine's passes
    FigureCanvasAgg(figure)
    lead = result.lead_series() if result.lead_series is not None and len(time) else None
    if lead is not None and not lead["present"].any():
        lead = None  # no vehicle was ever ahead in the ego's path
    grid = figure.add_gridspec(5, 2, height_ratios=[1.15, 1.0, 0.95, 1.05, 1.05], **LAYOUT)
    axes = {"speed": figure.add_subplot(grid[0, 0])}
    axes["distance"] = figure.add_subplot(grid[0, 1], sharex=axes["speed"])
    axes["pedals"] = figure.add_subplot(grid[1, 0], sharex=axes["speed"])
    axes["friction"] = figure.add_subplot(grid[1, 1], sharex=axes["speed"])
    axes["yaw"] = figure.add_subplot(grid[2, 0] if lead is not None else grid[2, :], sharex=axes["speed"])
    if lead is not None:
        axes["lead"] = figure.add_subplot(grid[2, 1], sharex=axes["speed"])
    road_ax = figure.add_subplot(grid[3, :] if focus else grid[3:, :])
    zoom_ax = figure.add_subplot(grid[4, :]) if focus else None
    for ax in axes.values():
        ax.grid(True, alpha=0.3)
    labels, top = [], 1.0
    if len(time):
        labels, top = _plot_time_panels(result, axes, time, brk_runs, lead)
        _plot_yaw_panel(result, axes["yaw"], time, brk_runs, narrow=lead is not None)
        if lead is not None:
            _plot_lead_panel(result, axes["lead"], time, lead)
        _plot_criticality(result, axes, time)
        axes["speed"].set_xlim(time[0], time[-1] if time[-1] > time[0] else time[0] + 1)

    # bird's-eye view of the whole run
    x_min, x_max = 0.0, 0.0  # the stations of every path (one vehicle at a time: nothing grows with the traffic)
    for series in [result.columns["station"]] + [track.station for track in result.vehicles]:
        x = from_si(np.asarray(series, dtype=float), units)
        x = x[np.isfinite(x)]
        if len(x):
            x_min, x_max = min(x_min, float(x.min())), max(x_max, float(x.max()))
    low, high = _lateral_limits(result)
    road_width = high - low
    pad = max(0.01 * (x_max - x_min), 2.0 * road_width - 0.5 * (x_max - x_min))  # short runs: show some road
    x_min, x_max = x_min - pad, x_max + pad
    _draw_road(road_ax, result, x_min, x_max, (low, high))
    handles = _draw_paths(road_ax, result, brk_runs, x_min, x_max, annotate=True)
    _, mappable, surface_handles = _surface_style(result)
    road_ax.set_xlim(x_min, x_max)
    road_ax.set_ylim(high, low)  # + right drawn downward: seen from above, driving left to right
    road_ax.set_ylabel(f"lateral [{length}]\n(+ right, drawn down)")
    road_ax.set_xlabel(f"station along the road [{length}]")
    road_ax.set_title("the road from above (stretched across; shoulders grey, RSA sections coloured per lane)",
                      fontsize=10, loc="left", y=1.0)
    legend = road_ax.legend(handles=handles + surface_handles, loc="upper left", bbox_to_anchor=(1.005, 1.0),
                            fontsize=8, borderaxespad=0)

    if focus:
        index, what = focus
        centre = from_si(float(result.columns["station"][index]), units)
        speed = from_si(abs(float(result.columns["v"][index])), units)
        half = max(4.0 * (high - low), 4.0 * speed)
        z_min, z_max = centre - half, centre + half
        _draw_road(zoom_ax, result, z_min, z_max, (low, high))
        _draw_paths(zoom_ax, result, brk_runs, z_min, z_max, annotate=True)
        _draw_footprints(zoom_ax, result, index, z_min, z_max)
        zoom_ax.set_xlim(z_min, z_max)
        zoom_ax.set_ylim(high, low)
        zoom_ax.set_ylabel(f"lateral [{length}]\n(+ right, drawn down)")
        zoom_ax.set_xlabel(f"station along the road [{length}]")
        zoom_ax.set_title(f"zoom: {what} (footprints and ego \u25c6 at that instant)", fontsize=10, loc="left", y=1.0)
        road_ax.add_patch(Rectangle((z_min, low), z_max - z_min, high - low, fill=False, edgecolor="black",
                                    lw=1.0, ls="--", zorder=8))

    # the road panels end where their legend (measured, without a draw) and the colorbar leave room
    colorbar = mappable is not None and bool(result.surfaces)
    legend_width = legend.get_window_extent(figure.canvas.get_renderer()).width / figure.bbox.width
    right = (COLORBAR_LEFT - 0.012 if colorbar else 0.99) - legend_width - 0.012
    road_axes = [road_ax, zoom_ax] if zoom_ax is not None else [road_ax]
    for ax in road_axes:
        box = ax.get_position()
        ax.set_position([box.x0, box.y0, max(right - box.x0, 0.3), box.height])
    if colorbar:
        low_end, high_end = road_axes[-1].get_position().y0, road_ax.get_position().y1
        colorbar = figure.colorbar(mappable, cax=figure.add_axes([COLORBAR_LEFT, low_end, 0.01, high_end - low_end]))
        colorbar.set_label("mu (RSA value / 10)")

    name = Path(str(result.scenario_path)).stem or "scenario"
    title = (f"{name} \u2014 {result.dynamics} dynamics \u2014 collisions: {result.collisions} \u2014 "
             f"{_final_text(result, time, from_si(np.asarray(result.columns['s'], dtype=float), units))}")
    subtitle = f"{Path(str(result.scenario_path)).name}  |  {units} units  |  seed {result.seed}"
    if result.warnings:
        first = result.warnings[0] if len(result.warnings[0]) <= 90 else result.warnings[0][:87] + "..."
        subtitle += f"  |  {len(result.warnings)} warning(s): {first}"
    figure.suptitle(f"{title}\n{subtitle}", fontsize=13)
    _pack_labels(figure, axes["speed"], labels, top)
    figure.savefig(Path(path), format="png", pil_kwargs={"compress_level": 1})  # 0.2 s less than 6, 11 % larger
