"""The SSP writer (sdl_fmu/ssp/document.py) on its own, with the shipped ego FMUs: what it writes validates against the
SSP 1.0 schemas fmpy ships, keeps to the portable subset, is the same bytes every time, and refuses a system the
masters would not run; and a system of two Simple FMUs (one braking to a stop, the other's throttle fed from the
first's speed through a linear transformation) runs in libcosim, ecos and fmpy through the recipes of
docs/export.md, with the closed-form stopping distance (and the FMI 3.0 FMUs in ecos)."""

import zipfile

import numpy as np
import pytest
from lxml import etree

from sdl_fmu.ssp.document import (SSC, SSD, Component, Connection, Connector, Parameter, SspError, System, Unit, ssd,
                                  ssv, write_ssp)

from helpers import G
from ssp_masters import MASTERS, run_master

V0, MU = 20.0, 0.6  # m/s; the braking FMU's friction
# without drag and rolling resistance, full pedal (brake_decel_max 9.81 > mu g): a = mu g, distance v0^2 / (2 a)
STOP = V0**2 / (2 * MU * G)
TOLERANCE = 1e-9  # relative: RODAS4 integrates the constant deceleration exactly (tests/fmu/test_importers.py)
STEP, STOP_TIME = 0.01, 5.0  # s: the stop comes at v0 / (mu g) = 3.4 s
FACTOR, OFFSET = 0.01, 0.1  # the second FMU's throttle = 0.01 * the first's speed + 0.1


def two_cars(fmu, transformed: bool = True, **changes) -> System:
    outputs = (Connector("v", "output", "Real", "m/s"), Connector("s", "output", "Real", "m"))
    braking = Component("braking", fmu, outputs,
                        tuple(Parameter(name, "Real", value) for name, value in {
                            "v0": V0, "brake": 1.0, "drag_area": 0.0, "rolling_resistance": 0.0,
                            **{f"mu_{wheel}": MU for wheel in ("fl", "fr", "rl", "rr")}}.items()))
    follower = Component("follower", fmu, (Connector("throttle" if transformed else "steer", "input", "Real"),
                                           Connector("v", "output", "Real", "m/s")),
                         (Parameter("v0", "Real", 10.0),), file_name="Follower.fmu")
    # fmpy applies no transformation (docs/export.md): without one, an identity link of a signal that stays 0
    link = Connection(("braking", "v"), ("follower", "throttle"), FACTOR, OFFSET) if transformed else \
        Connection(("braking", "psi"), ("follower", "steer"))
    if not transformed:
        braking = Component(braking.name, fmu, (*braking.connectors, Connector("psi", "output", "Real")),
                            braking.parameters)
    return System(**{"name": "two_cars", "components": (braking, follower), "connections": (link,),
                     "stop_time": STOP_TIME, "step": STEP,
                     "units": (Unit("m/s", {"m": 1, "s": -1}), Unit("m", {"m": 1})), **changes})


def test_the_document_is_ssp_1_0_with_the_literal_prefixes_and_the_same_bytes_every_time(simple_fmu, tmp_path):
    system = two_cars(simple_fmu)
    text = ssd(system)  # validated against fmpy's schemas as it is written
    root = etree.fromstring(text)
    assert root.get("version") == "1.0" and root.prefix == "ssd"
    assert b"<ssd:Connection " in text and b"<ssc:LinearTransformation " in text and b"ns0:" not in text
    connection = root.find(f".//{{{SSD}}}Connection")
    assert connection.get("suppressUnitConversion") == "true"
    assert connection.find(f"{{{SSC}}}LinearTransformation").attrib == {"factor": "0.01", "offset": "0.1"}
    assert b'name="start"' in ssv(system, system.components[0])
    first, second = write_ssp(system, tmp_path / "a.ssp"), write_ssp(system, tmp_path / "b.ssp")
    assert first.read_bytes() == second.read_bytes()
    with zipfile.ZipFile(first) as archive:
        assert archive.namelist() == ["SystemStructure.ssd", "resources/braking.ssv", "resources/follower.ssv",
                                      "resources/EgoVehicleSimple.fmu", "resources/Follower.fmu"]
        assert archive.read("resources/Follower.fmu") == simple_fmu.read_bytes()


@pytest.mark.parametrize("change, message", [
    ({"connections": (Connection(("braking", "v"), ("follower", "steer")),)}, "not declared"),
    ({"connections": (Connection(("follower", "throttle"), ("braking", "v")),)}, "from an output to an input"),
    ({"connections": (Connection(("braking", "v"), ("follower", "throttle")),) * 2}, "connected twice"),
    ({"connections": ()}, "must be connected"),
    ({"stop_time": 0.0}, "must be > 0"),
    ({"units": ()}, "is not defined"),
], ids=["unknown connector", "input to output", "twice", "an input not connected", "stop time", "unit"])
def test_a_system_the_masters_would_not_run_is_refused(simple_fmu, change, message):
    with pytest.raises(SspError, match=message):
        ssd(two_cars(simple_fmu, **change))


@pytest.mark.parametrize("file_name", ["a%20b.fmu", "a b.fmu", "a#b.fmu", "a?b.fmu", "ü.fmu"])
def test_a_file_name_its_source_uri_must_escape_is_refused(simple_fmu, file_name):
    """A source is a URI: libcosim undoes its escapes (resources/a%2520b.fmu is the file a%20b.fmu), ecos and fmpy
    read it as the file's name (measured with both: each fails to find resources/a%2520b.fmu), so only a name whose
    escape is itself is the same file to the three; the export's names are safe identifiers."""
    braking, follower = two_cars(simple_fmu).components
    renamed = Component(follower.name, follower.fmu, follower.connectors, follower.parameters, file_name=file_name)
    with pytest.raises(SspError, match="ecos and fmpy do not undo"):
        ssd(two_cars(simple_fmu, components=(braking, renamed)))


def test_connectors_of_two_types_and_a_transformation_between_integers_are_refused(simple_fmu, advanced_fmu):
    system = two_cars(simple_fmu)
    integer = Component("wheels", advanced_fmu, (Connector("surface_fl", "input", "Integer"),))
    for connection, message in ((Connection(("braking", "v"), ("wheels", "surface_fl")), "Real -> Integer"),):
        with pytest.raises(SspError, match=message):
            ssd(System("x", (*system.components, integer), (connection,), 1.0, 0.01, units=system.units))
    with pytest.raises(SspError, match="not a finite number"):
        ssd(two_cars(simple_fmu, connections=(Connection(("braking", "v"), ("follower", "throttle"), float("nan")),)))


@pytest.mark.slow
@pytest.mark.parametrize("master, version", [*((m, 2) for m in MASTERS), ("ecos", 3)],
                         ids=[*(f"{m}-fmi2" for m in MASTERS), "ecos-fmi3"])
def test_two_fmus_run_in_each_master_with_the_closed_form_stop_and_the_transformation(simple_fmus, tmp_path, master,
                                                                                     version):
    transformed = master != "fmpy"
    ssp = write_ssp(two_cars(simple_fmus[version], transformed), tmp_path / "two_cars.ssp")
    signals = {"braking.s": "Real", "braking.v": "Real", **({"follower.throttle": "Real"} if transformed else {})}
    result = run_master(master, ssp, STOP_TIME, STEP, signals)
    assert len(result["time"]) == round(STOP_TIME / STEP) and abs(result["time"][-1] - STOP_TIME) < 1e-9
    assert result["braking.v"][-1] == 0.0
    assert abs(result["braking.s"][-1] - STOP) / STOP < TOLERANCE
    if not transformed:
        return
    # the follower's throttle input: the braking car's speed through the transformation (read after step k, libcosim
    # shows the value step k used, the speed at k - 1; ecos the speed at k, for the next step)
    lag = 1 if master == "libcosim" else 0
    seen, sent = result["follower.throttle"][lag:], result["braking.v"][:len(result["time"]) - lag]
    assert np.array_equal(seen, OFFSET + FACTOR * sent), master  # the masters' arithmetic, in double
