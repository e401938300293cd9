"""`sdl-fmu verify`: the vehicle test pack run on the shipped Simple and Advanced FMUs, on a foreign FMU built by the
test suite, and on a vehicle that cannot reach the entry speed."""

import base64
import csv
import json
import os
import re
from functools import partial
from pathlib import Path

import pytest

from sdl_fmu import api
from sdl_fmu.verify import MANOEUVRES, braking

import helpers

SPEC_METRICS = {  # verify.json's metric names per manoeuvre (docs/verification.md)
    "braking": {"stopping_distance_m", "mfdd_mps2"},
    "steady_state_circular": {"understeer_gradient_deg_per_g", "max_lateral_acceleration_mps2"},
    "step_steer": {"yaw_rate_response_time_s", "yaw_rate_peak_response_time_s", "yaw_rate_overshoot_pct",
                   "lateral_acceleration_response_time_s"},
    "sine_with_dwell": {"yaw_rate_ratio_1_00s", "yaw_rate_ratio_1_75s", "lateral_displacement_1_07s_m"},
    "split_mu_braking": {"yaw_angle_deg", "yaw_angle_2s_deg", "lateral_deviation_m", "stopping_distance_m"},
    "double_lane_change": {"max_entry_speed_kmh"},
}


sdl_fmu = partial(helpers.sdl_fmu, timeout=1800)  # a whole pack may run; the limit only catches a hang


def check_results_folder(folder: Path, names) -> dict:
    """verify.json's shape, a CSV per manoeuvre that ran, and a self-contained report.html; returns verify.json."""
    document = json.loads((folder / "verify.json").read_text())
    assert list(document["manoeuvres"]) == list(names)
    for name, entry in document["manoeuvres"].items():
        assert entry["passed"] in (True, False, None)
        if entry["reason"] is not None:  # could not be driven through (False) or does not apply (None)
            assert entry["reason"] and "\n" not in entry["reason"]
        else:
            assert SPEC_METRICS[name] <= set(entry), name
        if entry["reason"] is None:
            with (folder / f"{name}.csv").open() as stream:
                rows = list(csv.DictReader(stream))
            assert rows and {"run", "time_s", "x_m", "y_m", "yaw_rate_radps", "steer_rad"} <= set(rows[0])
    page = (folder / "report.html").read_text()
    vehicle = document["vehicle"]
    for shown in (vehicle["guid"], Path(vehicle["fmu"]).name, str(vehicle["map"])):
        assert shown in page
    images = re.findall(r"src='data:image/png;base64,([A-Za-z0-9+/=]+)'", page)
    assert images and all(base64.b64decode(image).startswith(b"\x89PNG\r\n\x1a\n") for image in images)
    assert not re.search(r"(src|href)=['\"]https?:", page)  # self-contained
    return document


def test_pack_on_the_simple_fmu(tmp_path, simple_fmu):
    out = tmp_path / "simple"
    result = api.verify(dynamics="simple", out=out)
    document = check_results_folder(out, MANOEUVRES)
    entries = document["manoeuvres"]
    # R13-H's verdict recomputed from the CSV: stopping distance from brake application, limit 0.1 V + 0.006 V^2
    rows = [row for row in csv.DictReader((out / "braking.csv").open())
            if row["run"] == "Type-0 stop" and float(row["time_s"]) >= 0]
    distance = float(rows[-1]["distance_m"]) - float(rows[0]["distance_m"])
    assert entries["braking"]["stopping_distance_m"] == pytest.approx(distance, rel=1e-9)
    assert entries["braking"]["passed"] is (distance <= 0.1 * 100 + 0.006 * 100**2
                                           and entries["braking"]["mfdd_mps2"] >= 6.43
                                           and entries["braking"]["perturbed_lane_offset_m"] <= 3.5 / 2
                                           and entries["braking"]["lock_sequence_yaw_rate_growth"] <= 1.5)
    assert entries["braking"]["closed_form_cases"] == 60
    assert entries["braking"]["closed_form_max_relative_error"] <= 1e-9
    # the criteria of FMVSS 126 decide its verdict, run by run; S7.9.4's schedule at the pack's 16:1: A = 27.3 deg of
    # steering-wheel angle (six slowly increasing steer runs), 6.5 A = 177 < 270 deg, so each series runs 1.5 A, 2 A,
    # ... up to 270 deg (9.89 A): 18 runs each way
    sine = entries["sine_with_dwell"]
    assert len(sine["slowly_increasing_steer_A_swa_deg"]) == 6
    assert sine["runs_per_series"] == 18 and len(sine["runs"]) == 36
    assert max(run["amplitude_swa_deg"] for run in sine["runs"]) == pytest.approx(270.0)
    assert sine["passed"] is all(run["passed"] for run in sine["runs"])
    for run in sine["runs"]:
        assert run["passed"] is (run["yaw_rate_ratio_1_00s"] <= 0.35 and run["yaw_rate_ratio_1_75s"] <= 0.20
                                 and (run["amplitude_A"] < 5 or run["lateral_displacement_1_07s_m"] >= 1.83))
    for name in ("steady_state_circular", "step_steer", "split_mu_braking", "double_lane_change"):
        assert entries[name]["passed"] is None and entries[name]["reason"] is None  # report-only standards
    assert entries["split_mu_braking"]["yaw_angle_2s_deg"] > 0  # toward the high-mu (left) side
    # ISO 14512 at the high-friction wheels' locking limit (0.8 g / 9.81 = 0.7997 of pedal), reporting the largest yaw
    assert 0.7997 - 0.005 <= entries["split_mu_braking"]["brake_pedal"] <= 0.7997
    assert abs(entries["split_mu_braking"]["max_yaw_angle_deg"]) >= abs(entries["split_mu_braking"]["yaw_angle_deg"])
    # ISO 4138 and ISO 7401 in both directions; ISO 3888-2 reports the driver of its fastest clean run
    assert set(entries["steady_state_circular"]["directions"]) == set(entries["step_steer"]["directions"]) \
        == {"left", "right"}
    assert entries["double_lane_change"]["driver"]["preview_time_s"] > 0
    assert result.table.splitlines()[0].startswith("manoeuvre")


@pytest.mark.slow
def test_pack_on_the_advanced_fmu(tmp_path, advanced_fmu):
    out = tmp_path / "advanced"
    api.verify(dynamics="advanced", out=out)
    document = check_results_folder(out, MANOEUVRES)
    entries = document["manoeuvres"]
    assert document["vehicle"]["friction"] == "attribute"
    assert entries["split_mu_braking"]["friction"] == {"meaning": "attribute", "left": 0, "right": 2}
    assert all(entries[name]["reason"] is None for name in MANOEUVRES)  # driven through every manoeuvre


def test_command_prints_the_table_and_writes_the_folder(tmp_path, simple_fmu):
    out = tmp_path / "out"
    completed = sdl_fmu("verify", "--only", "braking,split_mu_braking", "--out", out, cwd=tmp_path)
    assert completed.returncode == 0, completed.stderr
    lines = completed.stdout.splitlines()
    assert any(line.startswith("braking ") and " pass " in line for line in lines)
    assert any(line.startswith("split_mu_braking ") and " report " in line for line in lines)
    check_results_folder(out, ["braking", "split_mu_braking"])
    # an earlier results folder is replaced; a file of the user's in it is kept
    (out / "notes.txt").write_text("mine")
    completed = sdl_fmu("verify", "--only", "braking", "--out", out, cwd=tmp_path)
    assert completed.returncode == 0, completed.stderr
    assert (out / "notes.txt").read_text() == "mine" and not (out / "split_mu_braking.csv").exists()


@pytest.mark.parametrize("argv, needle", [
    (["--only", "braking,nope"], "--only"), (["--only", ","], "--only"),
    (["--dynamics", "advanced", "--vehicle", "x.toml"], "--dynamics"), (["--vehicle", "missing.toml"], "--vehicle"),
])
def test_user_mistakes_are_one_line(tmp_path, argv, needle):
    completed = sdl_fmu("verify", *argv, "--out", tmp_path / "out", cwd=tmp_path)
    assert completed.returncode == 2 and completed.stdout == ""
    assert len(completed.stderr.strip().splitlines()) == 1 and needle in completed.stderr
    assert "Traceback" not in completed.stderr and not (tmp_path / "out").exists()


def test_folder_of_someone_else_is_refused_before_running(tmp_path, simple_fmu):
    out = tmp_path / "theirs"
    out.mkdir()
    (out / "thesis.tex").write_text("keep")
    completed = sdl_fmu("verify", "--out", out, cwd=tmp_path)
    assert completed.returncode == 2 and "--out" in completed.stderr
    assert [p.name for p in out.iterdir()] == ["thesis.tex"]


@pytest.mark.slow
def test_pack_on_a_foreign_fmu(tmp_path, foreign_vehicle):
    # The FMI 2.0 build (PythonFMU): the pythonfmu3 build's runtime corrupts the heap at the exit of a process
    # that ran the whole pack with it, in about a third of the runs, after every result is written (docs/decisions.md,
    # "Known problems"); the FMI 3.0 foreign car goes through the pack in the tests below.
    fmu, vehicle_map = foreign_vehicle(2)
    out = tmp_path / "foreign"
    completed = sdl_fmu("verify", "--fmu", fmu, "--vehicle", vehicle_map, "--out", out, cwd=tmp_path)
    assert completed.returncode == 0, completed.stderr
    document = check_results_folder(out, MANOEUVRES)
    entries = document["manoeuvres"]
    assert document["vehicle"]["map"] == Path(vehicle_map).name  # by name: no machine path in results
    assert entries["braking"]["passed"] is True  # 8.3 m/s2 of brake at full pedal, friction 0.8
    # one friction value for the whole car: left and right cannot differ
    assert entries["split_mu_braking"]["passed"] is None
    assert entries["split_mu_braking"]["reason"].startswith("not applicable")
    assert all(entries[name]["reason"] is None for name in MANOEUVRES if name != "split_mu_braking")


def test_vehicle_without_friction_input_skips_split_mu(tmp_path, foreign_vehicle):
    fmu, vehicle_map = foreign_vehicle(3)
    text = Path(vehicle_map).read_text()
    stripped = tmp_path / "no_friction.toml"
    stripped.write_text("\n".join(line for line in text.splitlines() if not line.startswith("friction")))
    result = api.verify(fmu=fmu, vehicle=stripped, only=["split_mu_braking"])
    outcome = result.outcomes[0]
    assert outcome.passed is None and outcome.reason == "not applicable: the vehicle has no friction input"


def no_friction_map(folder: Path, vehicle_map) -> Path:
    """The vehicle map without its friction input (the car is braked on its own surface)."""
    stripped = folder / "no_friction.toml"
    stripped.write_text("\n".join(line for line in Path(vehicle_map).read_text().splitlines()
                                   if not line.startswith("friction")))
    return stripped


def test_a_foreign_car_without_wheel_lock_passes_braking(tmp_path, foreign_vehicle):
    """The foreign car (a kinematic bicycle: no wheels) on its own surface, road_grip 0.8: grip 0.8 x 1450 kg x g =
    11376 N. With brake_gain 90 N/bar its full pedal, 120 bar, gives 10800 N < grip: the deceleration grows with the
    pedal all the way (10800 / 1450 = 7.45 m/s2 plus rolling resistance and drag), nothing saturates, so no wheel
    locks and R13-H Annex 5's lock sequence is n/a with its reason; the stop itself passes (about 27.8^2 / (2 x 7.6)
    = 51 m <= 70 m, MFDD >= 7.45 > 6.43 m/s2, and a kinematic car turns only while steered: 0.4 m of drift). n/a is
    no failure: braking passes, the totals count it as n/a, --strict exits 0. With its shipped brake_gain (100:
    12000 N > grip) the brakes saturate on the grip at pedal 11376 / 12000 = 0.948 (a lock, as the pack sees it) and
    the criterion is judged: pass (a kinematic car's yaw rate only falls as it slows). (PYTHONPATH: the command
    runs this checkout's sdl_fmu.)"""
    fmu, vehicle_map = foreign_vehicle(2)
    stripped = no_friction_map(tmp_path, vehicle_map)
    out = tmp_path / "weak-brakes"
    completed = sdl_fmu("verify", "--fmu", fmu, "--vehicle", stripped, "--only", "braking", "--param",
                        "brake_gain=90", "--strict", "--out", out, cwd=tmp_path,
                        env={**os.environ, "PYTHONPATH": str(Path(api.__file__).parents[1])})
    assert completed.returncode == 0, completed.stderr  # --strict: n/a is not a failed criterion
    document = json.loads((out / "verify.json").read_text())
    entry = document["manoeuvres"]["braking"]
    assert entry["passed"] is True and document["passed"] is True
    assert [v["verdict"] for v in entry["verdicts"]] == ["pass", "pass", "pass", "n/a"]
    lock = entry["verdicts"][3]
    assert lock["criterion"] == "lock sequence (front before rear)"
    assert lock["reason"].startswith("no wheel locks up to full pedal on own surface")
    assert entry["lock_sequence_yaw_rate_growth"] is None and entry["lock_sequence_no_lock"] == ["own surface"]
    assert document["totals"]["criteria"] == {"pass": 3, "FAIL": 0, "n/a": 1, "report": 0}
    assert document["totals"]["manoeuvres"]["pass"] == 1
    assert 6.43 < entry["mfdd_mps2"] and entry["stopping_distance_m"] <= 70.0
    assert re.search(r"^ +n/a +lock sequence \(front before rear\): no wheel locks", completed.stdout, re.M)
    page = (out / "report.html").read_text()
    assert "<span class='na'>lock sequence (front before rear): n/a (no wheel locks up to full pedal" in page
    assert "1 n/a" in page
    # the same car whose brakes can saturate its grip: the lock is found and the criterion judged
    judged = api.verify(fmu=fmu, vehicle=stripped, only=["braking"]).outcomes[0]
    assert [v["verdict"] for v in judged.criterion_verdicts()] == ["pass"] * 4 and judged.passed is True
    # the pack brakes at the found limit + 2 RESOLUTION; the limit is the bisection's last pedal m whose growth over
    # [m, m + RESOLUTION] is >= LOCK_GROWTH of the full one: past the saturation at p_lock nothing grows, so
    # m <= p_lock - 0.8 RESOLUTION, and the bisection ends within one RESOLUTION below that (1e-3: drag's share of
    # the light-pedal rate, 0.6 %, moves the threshold by less)
    lock, resolution = 11375.7 / 12000, 0.005
    pedal = judged.metrics["lock_sequence_brake"]["own surface"] - 2 * resolution
    assert lock - 1.8 * resolution - 1e-3 <= pedal <= lock - 0.8 * resolution + 1e-3


@pytest.mark.slow
def test_weak_vehicle_fails_what_it_cannot_reach_and_the_pack_goes_on(tmp_path, foreign_vehicle):
    """The weak foreign car's top speed is 84.7 km/h: it cannot reach braking's or split-mu's 100 km/h; it can
    still drive 80 km/h (step steer, sine with dwell) and the lane change below its top speed."""
    fmu, vehicle_map = foreign_vehicle(3, weak=True)
    out = tmp_path / "weak"
    completed = sdl_fmu("verify", "--fmu", fmu, "--vehicle", vehicle_map, "--out", out, cwd=tmp_path)
    assert completed.returncode == 0, completed.stderr
    assert "Traceback" not in completed.stderr
    entries = check_results_folder(out, MANOEUVRES)["manoeuvres"]
    assert entries["braking"]["passed"] is False
    assert entries["braking"]["reason"].startswith("cannot reach the entry speed 100 km/h")
    assert re.search(r"^braking +FAIL +cannot reach the entry speed 100 km/h", completed.stdout, re.M)
    assert entries["braking"]["reason"] in (out / "report.html").read_text()
    assert entries["step_steer"]["reason"] is None and entries["sine_with_dwell"]["reason"] is None
    assert braking.TEST_SPEED_KMH > 84.7 > entries["double_lane_change"]["max_entry_speed_kmh"]


def test_an_fmu_error_fails_the_manoeuvre_with_one_line(simple_fmu):
    """The real FMU refuses a steer outside its declared range (fmi2Error): the manoeuvre fails with one line."""
    from sdl_fmu.shipped import shipped_model
    from sdl_fmu.verify.drive import ManoeuvreFailed, drive

    with pytest.raises(ManoeuvreFailed) as failure:
        drive(shipped_model("simple"), 20.0, lambda t, state: (0.0, 0.0, 2.0 if t >= 0.5 else 0.0), 2.0)
    assert str(failure.value).startswith("the vehicle FMU failed at t = 0.50 s: ")
    assert "\n" not in str(failure.value)


# ---- for CI and for reports: --param, --strict, the data sheet, the tool and the date, rounded numbers ----------


def test_param_reaches_the_fmu_and_the_data_sheet(tmp_path, simple_fmu, defaults_simple):
    # brake_decel_max 5 m/s2 (below 0.8 g: the wheels roll) with the default drag and rolling resistance: the stop
    # from the entry speed v0 obeys dv/dt = -(A + K v^2), A = 5 + f_r g, K = rho CdA / (2 m), so its distance is
    # ln(1 + K v0^2 / A) / (2K) (docs/verification.md, the closed-form braking distances), to the solver's 1e-9; its
    # MFDD (about 5.2 m/s2) is below R13-H's 6.43: the manoeuvre fails
    out = tmp_path / "out"
    result = api.verify(dynamics="simple", only=["braking"], params={"brake_decel_max": 5.0}, out=out)
    entry = json.loads((out / "verify.json").read_text())["manoeuvres"]["braking"]
    rows = [row for row in csv.DictReader((out / "braking.csv").open()) if float(row["time_s"]) >= 0]
    v0 = float(rows[0]["speed_mps"])
    expected = helpers.braking_distance(v0, 5.0, defaults_simple["rolling_resistance"],
                                        defaults_simple["air_density"] * defaults_simple["drag_area"]
                                        / (2 * defaults_simple["mass"]))
    assert entry["stopping_distance_m"] == pytest.approx(expected, rel=1e-9)
    assert entry["passed"] is False and result.passed is False
    document = json.loads((out / "verify.json").read_text())
    assert document["passed"] is False
    assert document["datasheet"]["drive_and_brakes"]["brake_decel_max_mps2"] == 5.0
    assert document["datasheet"]["parameters_set"] == {"brake_decel_max": 5.0}


def test_the_report_holds_the_data_sheet_the_tool_and_the_date_and_rounded_numbers(tmp_path, simple_fmu):
    from sdl_fmu import __version__

    out = tmp_path / "out"
    api.verify(dynamics="simple", only=["braking"], out=out)
    document = json.loads((out / "verify.json").read_text())
    assert document["tool"]["tool"] == "sdl-fmu" and document["tool"]["version"] == __version__
    date = document["tool"]["date"]
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\+00:00", date)
    sheet = document["datasheet"]
    assert sheet["identity"]["guid"] == document["vehicle"]["guid"]
    assert len(sheet["identity"]["fmu_sha256"]) == 64
    assert sheet["mass_and_geometry"]["mass_kg"] == 1500.0 and sheet["mass_and_geometry"]["wheelbase_m"] == 2.7
    assert sheet["tires"] == {"friction_input": "mu", "friction_coefficient": 0.8,
                              "cornering_stiffness_front_N": 40000.0, "cornering_stiffness_rear_N": 70000.0}
    page = (out / "report.html").read_text()
    for shown in (f"sdl-fmu {__version__}", date, "Vehicle data sheet", "1500 kg", "2.70 m", "40000 N", "110.0 kW",
                  sheet["identity"]["fmu_sha256"]):
        assert shown in page, shown
    # the metrics rounded to their meaning, with units: the stopping distance to the cm, the MFDD to 0.01 m/s2
    entry = document["manoeuvres"]["braking"]
    assert f"{entry['stopping_distance_m']:.2f} m" in page and f"{entry['mfdd_mps2']:.2f} m/s2" in page
    assert repr(entry["stopping_distance_m"]) not in page


def test_strict_exits_1_when_a_criterion_fails(tmp_path, simple_fmu):
    failing = ["verify", "--only", "braking", "--param", "brake_decel_max=5", "--out", tmp_path / "weak"]
    assert sdl_fmu(*failing, cwd=tmp_path).returncode == 0  # a failed criterion is a result...
    completed = sdl_fmu(*failing, "--strict", cwd=tmp_path)
    assert completed.returncode == 1  # ...and with --strict, exit 1 and one line
    assert completed.stderr.strip().splitlines() == [
        f"sdl-fmu: verify --strict: a criterion failed (see {tmp_path / 'weak' / 'verify.json'})"]
    passing = sdl_fmu("verify", "--only", "braking,split_mu_braking", "--strict", "--out", tmp_path / "ok",
                      cwd=tmp_path)
    assert passing.returncode == 0, passing.stderr  # braking passes, split-mu has no criterion


@pytest.mark.parametrize("argv, needle", [
    (["--param", "mass=0"], "--param mass=0.0: below the declared minimum"),
    (["--param", "nope=1"], "--param nope=1.0: EgoVehicleSimple.fmu has no parameter 'nope'"),
    (["--param", "mass"], "--param mass: expected NAME=VALUE"),
    (["--controller", "example-aeb"], "--controller example-aeb: applies to the aeb-ccr pack"),
])
def test_param_and_controller_mistakes_are_one_line(tmp_path, argv, needle, simple_fmu):
    completed = sdl_fmu("verify", "--only", "braking", *argv, "--out", tmp_path / "out", cwd=tmp_path)
    assert completed.returncode == 2 and completed.stdout == "", completed.stderr
    assert len(completed.stderr.strip().splitlines()) == 1 and needle in completed.stderr, completed.stderr
    assert not (tmp_path / "out").exists()
