"""`sdl-fmu verify --pack aeb-ccr`: the Euro NCAP AEB car-to-car rear grid (docs/verification.md, The AEB
car-to-car pack).

The protocol's tables are written out here, from Euro NCAP Test Protocol - AEB Car-to-Car systems v3.0.2 (July 2019)
and Assessment Protocol - Safety Assist v9.1 (November 2021), as BeamNG's implementation of them encodes them
(BeamNG_NCAP_Tests, src/beamng_ncap/scenarios.py: CCRS, CCRM, CCRB and their colour schemes), and the pack's grid
and scoring are held to them."""

import itertools

import pytest

from sdl_fmu.sdl import default_vehicle_table_path, load_vehicle_table
from sdl_fmu.sdl.events import Brake
from sdl_fmu.verify.aeb import protocol
from sdl_fmu.verify.aeb.outcome import evaluate
from sdl_fmu.verify.aeb.protocol import grid, lateral_offset, score
from sdl_fmu.verify.aeb.scenario import scenario_of, start_gap

KMH = 1 / 3.6

# --- the protocol's tables --------------------------------------------------------------------------------------
OVERLAPS = [-75, -50, 50, 75, 100]  # % of the VUT's width overlapping the target
CCRS = [10, 15, 20, 25, 30, 35, 40, 45, 50]  # VUT km/h, target stationary
CCRM = [30, 35, 40, 45, 50, 55, 60, 65, 70, 75, 80]  # VUT km/h, target 20 km/h
CCRB = [(-2, 12), (-2, 40), (-6, 12), (-6, 40)]  # target m/s2, headway m; both at 50 km/h
# the colour bands, per VUT speed: (thresholds of the relative impact speed in km/h, points), as BeamNG lists them:
# a test scores the points of the last threshold its relative impact speed is below, else 0
CCRS_BANDS = {50: ([40, 30, 15, 5], [0.25, 0.5, 0.75, 1]), 45: ([35, 25, 15, 5], [0.25, 0.5, 0.75, 1]),
              40: ([35, 25, 15, 5], [0.25, 0.5, 0.75, 1]), 35: ([25, 15, 5], [0.5, 0.75, 1]),
              30: ([25, 15, 5], [0.5, 0.75, 1]), 25: ([15, 5], [0.5, 1]), 20: ([1], [1]), 15: ([1], [1]),
              10: ([1], [1])}
CCRM_BANDS = {80: ([50, 35, 20, 5], [0.25, 0.5, 0.75, 1]), 75: ([45, 30, 15, 5], [0.25, 0.5, 0.75, 1]),
              70: ([40, 30, 15, 5], [0.25, 0.5, 0.75, 1]), 65: ([35, 25, 15, 5], [0.25, 0.5, 0.75, 1]),
              60: ([35, 25, 15, 5], [0.25, 0.5, 0.75, 1]), 55: ([25, 15, 5], [0.5, 0.75, 1]),
              50: ([25, 15, 5], [0.5, 0.75, 1]), 45: ([15, 5], [0.5, 1]), 40: ([15, 5], [0.5, 1]), 35: ([5], [1]),
              30: ([5], [1])}
CCRB_BANDS = ([1], [1])


def protocol_points(thresholds, points, relative_impact_speed):
    result = 0
    for threshold, value in zip(thresholds, points):
        if relative_impact_speed < threshold:
            result = value
    return result


def test_the_grid_is_the_protocols():
    expected = ([("CCRs", v, 0, o, None, None) for v, o in itertools.product(CCRS, OVERLAPS)]
                + [("CCRm", v, 20, o, None, None) for v, o in itertools.product(CCRM, OVERLAPS)]
                + [("CCRb", 50, 50, o, -a, h) for (a, h), o in itertools.product(CCRB, OVERLAPS)])
    got = [(t.group, t.ego_speed_kmh, t.target_speed_kmh, t.overlap_pct, t.target_decel_mps2, t.headway_m)
           for t in grid()]
    assert got == expected and len(got) == 45 + 55 + 20
    assert [t.group for t in grid(["CCRb"])] == ["CCRb"] * 20


@pytest.mark.parametrize("group, bands", [("CCRs", CCRS_BANDS), ("CCRm", CCRM_BANDS)])
def test_the_scoring_is_the_protocols(group, bands):
    for speed, (thresholds, points) in bands.items():
        test = protocol.Test(group, speed, 0 if group == "CCRs" else 20, 100)
        for relative in [0.0, 0.5, 0.999, 1.0, 4.99, 5.0, 14.9, 15.0, 19.9, 20.0, 24.9, 25.0, 29.9, 30.0, 34.9, 35.0,
                         39.9, 40.0, 44.9, 45.0, 49.9, 50.0, 80.0]:
            assert score(test, relative) == protocol_points(thresholds, points, relative), (speed, relative)
    assert set(bands) == set(CCRS if group == "CCRs" else CCRM)


def test_the_ccrb_scoring_and_the_colours():
    test = protocol.Test("CCRb", 50, 50, 100, 6.0, 12.0)
    for relative in (0.0, 0.99, 1.0, 10.0):
        assert score(test, relative) == protocol_points(*CCRB_BANDS, relative)
    assert protocol.COLOURS == {1.0: "green", 0.75: "yellow", 0.5: "orange", 0.25: "brown", 0.0: "red"}


def test_the_overlaps_place_the_target():
    # ego 1.8 m wide, target 1.72 m: x % of the ego's width behind the target puts the ego's centre line
    # (x - 50) % of its width inside the target's edge; negative: the ego to the left of the target, whose centre is
    # then to the ego's right (+ lateral, the roadway frame)
    ego, target = 1.8, protocol.TARGET_WIDTH_M
    assert lateral_offset(100, ego) == 0.0
    assert lateral_offset(50, ego) == pytest.approx(-target / 2)
    assert lateral_offset(-50, ego) == pytest.approx(target / 2)
    assert lateral_offset(75, ego) == pytest.approx(-(target / 2 - 0.25 * ego))
    for overlap in (50, 75, -50, -75):  # the overlapping width is the share of the ego's
        offset = abs(lateral_offset(overlap, ego))
        assert (ego + target) / 2 - offset == pytest.approx(abs(overlap) / 100 * ego)


def test_a_test_as_a_scenario():
    # the target: the vehicle table's Euro NCAP target, its rear bumper the start gap ahead of the ego's front one:
    # 4 s x the closing speed, or the CCRb headway
    table = load_vehicle_table(default_vehicle_table_path())
    target = table[protocol.TARGET_MODEL]
    assert (target.length, target.width) == (3.95, 1.72)
    assert start_gap(protocol.Test("CCRs", 50, 0, 100)) == pytest.approx(4 * 50 * KMH)
    assert start_gap(protocol.Test("CCRm", 80, 20, 100)) == pytest.approx(4 * 60 * KMH)
    ccrb = protocol.Test("CCRb", 50, 50, -75, 6.0, 40.0)
    assert start_gap(ccrb) == 40.0
    scene = scenario_of(ccrb, 4.6, 1.8)
    (event,) = scene.events
    assert scene.units == "Metric" and not any(isinstance(e, Brake) for e in scene.events)
    assert event.gap == pytest.approx(40.0 + (4.6 + 3.95) / 2)
    assert event.speed.value == pytest.approx(-50 * KMH) and not event.speed.relative
    assert event.lateral.relative and event.lateral.value == pytest.approx(lateral_offset(-75, 1.8))
    # braking from the start at 6 m/s2 to a stop: the transition's duration is v / a, its lateral unchanged
    assert event.initial.speed.value == 0.0 and event.initial.duration == pytest.approx(50 * KMH / 6.0)
    assert event.initial.lateral == event.lateral
    assert scenario_of(protocol.Test("CCRm", 50, 20, 100), 4.6, 1.8).events[0].initial is None


# ---- the example AEB in the loop: impact or not by hand at three speeds ------------------------------------------

G = 9.80665
PERIOD = 0.01  # s: the example AEB's period (its shipped map)
A_PARTIAL, T_FULL, FACTOR = 3.0, 0.6, 1.5  # its partial deceleration, full-braking threshold and deactivation factor
A_FULL = 0.8 * G  # its full request (10 m/s2 > brake_decel_max) locks the Simple FMU's wheels: the slide at mu g
NO_RESISTANCES = {"drag_area": 0.0, "rolling_resistance": 0.0}


def hand_ccrs(v0: float, k_partial: int):
    """The CCRs test at v0 (m/s) with the example AEB, no drag or rolling resistance, worked out sample by sample in
    closed form: ('impact', ego speed) or ('stop', gap).

    From 4 s TTC the ego holds v0 (the lane driver at its target speed, no resistance: throttle 0), so the TTC is
    4 - t, and the partial stage comes on at the first controller sample t_k = k x 10 ms with TTC < 1.2 s: at
    k = 280, where the TTC is exactly 1.2 s and round-off decides, or 281 (`k_partial`). From then the AEB requests
    3 m/s2 (pedal 3 / 9.81: the wheels roll, the deceleration is 3 m/s2 exactly) and holds it until the ego no longer
    closes; full braking comes on at the first sample with TTC < 0.6 s and goes off above 0.9 s, its request locking
    the wheels (0.8 g). Between samples the deceleration is constant, so the gap is g - v t + a t^2 / 2 and the speed
    v - a t: a contact is the root of the gap, a stop v / a."""
    t, gap, v, full = k_partial * PERIOD, v0 * (4 - k_partial * PERIOD), v0, False
    decel = A_PARTIAL
    while True:
        tau_stop = v / decel
        disc = v * v - 2 * decel * gap
        if disc >= 0 and (v - disc**0.5) / decel <= min(PERIOD, tau_stop):
            return "impact", v - decel * (v - disc**0.5) / decel
        if tau_stop <= PERIOD:
            return "stop", gap - v * tau_stop + decel * tau_stop**2 / 2
        gap, v, t = gap - v * PERIOD + decel * PERIOD**2 / 2, v - decel * PERIOD, t + PERIOD
        full = gap / v <= FACTOR * T_FULL if full else gap / v < T_FULL
        decel = A_FULL if full else A_PARTIAL


@pytest.mark.parametrize("speed_kmh, expected", [(20, "stop"), (40, "stop"), (50, "impact")])
@pytest.mark.usefixtures("simple_fmus", "example_aeb_fmus")
def test_impact_or_not_by_hand_with_the_example_aeb(speed_kmh, expected):
    # hand_ccrs at k = 280: 20 km/h partial braking only, stops 1.5226 m short; 40 km/h partial, full at 3.623 s,
    # partial again at 4.675 s (TTC above 0.9 s), stops 0.3857 m short; 50 km/h partial, full at 3.575 s, contact at
    # 5.1389 m/s (18.5 km/h, 0.5 points)
    from sdl_fmu import api
    from sdl_fmu.cosim.locate import TIME_TOLERANCE

    model = api.ego_model("simple")
    test = protocol.Test("CCRs", speed_kmh, 0, 100)
    fmu, cmap = api.example_controller()
    result = api.run(scenario_of(test, model.length, model.width), speed=speed_kmh * KMH, until_time=60.0,
                     until_not_closing=1, on_collision="stop", controller=fmu, controller_map=cmap,
                     params=NO_RESISTANCES, plot=False)
    request = result.arrays["request_deceleration_m/s2"]
    first = round(result.time[request > 0][0] / PERIOD)
    assert first in (280, 281)
    kind, value = hand_ccrs(speed_kmh * KMH, first)
    outcome = evaluate(test, result)
    assert kind == expected and outcome.impact is (kind == "impact")
    if kind == "impact":
        # the contact is located within TIME_TOLERANCE, over which the sliding ego's speed changes by A_FULL x it
        assert outcome.impact_speed_kmh * KMH == pytest.approx(value, abs=A_FULL * TIME_TOLERANCE)
        assert outcome.score == score(test, outcome.relative_impact_speed_kmh) == 0.5
    else:
        # the stop is the FMU's own event (speed exactly 0), the distance exact to the solver's round-off
        assert outcome.end == "stopped" and outcome.min_gap_m == pytest.approx(value, abs=1e-9)
        assert outcome.score == 1.0 and outcome.speed_reduction_kmh == speed_kmh


# ---- the pack from the command line ------------------------------------------------------------------------------


def test_the_pack_from_the_command_line(tmp_path, simple_fmu):
    # a mapped vehicle (the Simple FMU through a copy of its map: both travel to two Dask workers as bytes), then the
    # shipped model in this process: the same results
    import json
    import re
    import shutil

    import helpers
    from sdl_fmu import __version__
    from sdl_fmu.vehicle import shipped_map_path

    shutil.copy(shipped_map_path("simple"), tmp_path / "car.toml")
    out = tmp_path / "aeb"
    argv = ["verify", "--pack", "aeb-ccr", "--only", "CCRb", "--controller", "example-aeb"]
    completed = helpers.sdl_fmu(*argv, "--fmu", simple_fmu, "--vehicle", tmp_path / "car.toml", "--workers", "2",
                                "--out", out, cwd=tmp_path, timeout=900)
    assert completed.returncode == 0, completed.stderr
    assert "CCRb: relative impact speed, km/h" in completed.stdout and "points" in completed.stdout
    document = json.loads((out / "verify.json").read_text())
    assert document["pack"] == "aeb-ccr" and document["tool"]["version"] == __version__
    assert document["protocol"].startswith("Euro NCAP Test Protocol - AEB Car-to-Car systems v3.0.2")
    tests = document["tests"]
    assert [(t["target_decel_mps2"], t["headway_m"], t["overlap_pct"]) for t in tests] == [
        (a, h, o) for a, h in ((2.0, 12.0), (2.0, 40.0), (6.0, 12.0), (6.0, 40.0)) for o in OVERLAPS]
    for t in tests:
        assert {"group", "ego_speed_kmh", "target_speed_kmh", "overlap_pct", "target_decel_mps2", "headway_m",
                "impact", "impact_speed_kmh", "relative_impact_speed_kmh", "speed_reduction_kmh", "min_gap_m",
                "min_ttc_s", "score"} <= set(t)
        assert t["error"] is None and t["end"] in ("contact", "stopped", "slower")
        assert t["impact"] is (t["end"] == "contact") and t["score"] == (0.0 if t["impact"] else 1.0)
    # the ego drives straight: the overlap does not change what the AEB sees, so each row is one result five times
    for row in range(4):
        assert len({json.dumps({k: v for k, v in t.items() if k not in ("overlap_pct", "wall_time_s")})
                    for t in tests[5 * row:5 * row + 5]}) == 1
    total = document["totals"]["CCRb"]
    assert total["tests"] == 20 and total["points"] == sum(t["score"] for t in tests)
    assert document["passed"] is (total["points"] == 20)
    assert document["controller"]["model_name"] == "ExampleAeb" and document["controller"]["period_s"] == PERIOD
    page = (out / "report.html").read_text()
    for shown in ("CCRb: Car-to-Car Rear braking", "ExampleAeb", document["controller"]["guid"], "Vehicle data sheet",
                  f"sdl-fmu {__version__}", document["tool"]["date"], "v3.0.2", "Safety Assist v9.1"):
        assert shown in page, shown
    assert len(re.findall(r"<td class='n' style='background:#", page)) == 20  # the grid's coloured cells
    assert len((out / "tests.csv").read_text().splitlines()) == 21
    # --strict: a test short of its points (the example AEB touches in CCRb 6 m/s2 12 m) fails a criterion: exit 1,
    # one line; the same tests in this process (--workers 0) give the same results
    assert document["passed"] is False
    strict = helpers.sdl_fmu(*argv, "--workers", "0", "--out", tmp_path / "strict", "--strict", cwd=tmp_path,
                             timeout=900)
    assert strict.returncode == 1 and len(strict.stderr.strip().splitlines()) == 1, strict.stderr
    again = json.loads((tmp_path / "strict" / "verify.json").read_text())["tests"]
    assert [{k: v for k, v in t.items() if k != "wall_time_s"} for t in again] == [
        {k: v for k, v in t.items() if k != "wall_time_s"} for t in tests]


# ---- the finished tests kept for a resume (verify/aeb/kept.py) ---------------------------------------------------


def test_a_resume_keeps_the_tests_of_the_same_pack_and_timeouts_only_under_a_timeout_as_long(tmp_path):
    # the journal as an interrupted pack leaves it: rows appended one by one (the last cut short), each with the
    # pack's identity and the timeout it ran under; what a resume keeps follows from the rows alone
    import json

    from sdl_fmu.verify.aeb import kept
    from sdl_fmu.verify.aeb.outcome import TestOutcome

    tests = grid(["CCRb"])[:4]
    out = tmp_path / "aeb"
    recorder = kept.Recorder(out, "pack-a", 10.0)
    scored = TestOutcome(tests[0], impact=False, relative_impact_speed_kmh=0.0, score=1.0, end="stopped")
    recorder(scored)
    recorder(TestOutcome(tests[1], end="timeout", error="the run exceeded its time limit of 10 s (wall clock)"))
    recorder(TestOutcome(tests[2], error="the controller Aeb.fmu failed: it crashed (SIGSEGV)"))
    recorder(TestOutcome(tests[3], error="KilledWorker: lost", extra={"rerun": True}))  # not the test's result
    recorder.close()
    other = kept.Recorder(out, "pack-b", 10.0)  # another pack's row, in the same journal
    other(TestOutcome(tests[3], impact=True, score=0.0, end="contact"))
    other.close()
    with (out / kept.JOURNAL_NAME).open("a") as journal:
        journal.write(json.dumps({"key": kept.key(tests[3]), "pack": "pack-a"})[:20])  # cut short
    found = kept.finished(out, tests, "pack-a", 10.0)
    assert [o.test for o in found] == tests[:3]
    assert [(o.end, o.score, o.passed, o.timed_out, o.failed) for o in found] == [
        ("stopped", 1.0, True, False, False), ("timeout", None, False, True, False),
        ("error", None, False, False, True)]
    assert found[0].to_json() == scored.to_json()
    # a longer timeout runs the timed-out test again; a shorter one keeps it; another pack keeps only its own
    assert [o.test for o in kept.finished(out, tests, "pack-a", 20.0)] == [tests[0], tests[2]]
    assert len(kept.finished(out, tests, "pack-a", 5.0)) == 3
    assert [o.test for o in kept.finished(out, tests, "pack-b", 10.0)] == [tests[3]]
    # the journal is proved sdl-fmu's by the folder's manifest; a journal the manifest does not list is not read
    (out / ".sdl-fmu-results.json").unlink()
    assert kept.finished(out, tests, "pack-a", 10.0) == []
