"""One friction scale (sdl_fmu/dynamics/advanced.md): the shipped tire surfaces against the road values they cite,
and the same full-brake stop on each surface in both FMUs."""

import math

import numpy as np
import pytest
from fmpy import simulate_fmu

from sdl_fmu.tire_files import DEFAULT_ATTRIBUTE_FILE, mf_coefficients, read_attribute_file, read_tir

from helpers import NO_RESISTANCES, WHEELS, G

# J. Y. Wong, Theory of Ground Vehicles, 4th ed. (2008), Table 1.3, average coefficients of road adhesion
# (peak, sliding; midpoints of ranges), as cited in each tire file's header; and the Simple model's RSA
# value (10 x mu) documented beside each attribute in the README.
SURFACES = {  # attribute: (tire file, peak, sliding, Simple RSA value)
    0: ("dry_asphalt.tir", 0.85, 0.75, 8),
    1: ("wet_asphalt.tir", 0.60, 0.525, 6),
    2: ("packed_snow.tir", 0.20, 0.15, 2),
    3: ("ice.tir", 0.10, 0.07, 1),
    4: ("gravel_shoulder.tir", 0.60, 0.55, 6),
}


def magic_formula(d, c, b, e, slip):
    bs = b * slip
    return d * math.sin(c * math.atan(bs - e * (bs - math.atan(bs))))


def friction(t, fz):
    """(peak mu_x, peak mu_y, locked-wheel mu_x at kappa = -1) of a tire at wheel load fz (MF 5.2 pure slip)."""
    fz0 = t["FNOMIN"] * t["LFZO"]
    dfz = (fz - fz0) / fz0
    mux = abs(t["PDX1"] + t["PDX2"] * dfz) * t["LMUX"]
    muy = abs(t["PDY1"] + t["PDY2"] * dfz) * t["LMUY"]
    ex = min(t["PEX1"] + t["PEX2"] * dfz + t["PEX3"] * dfz**2, 1.0)
    kx = abs(t["PKX1"] + t["PKX2"] * dfz) * math.exp(t["PKX3"] * dfz) * t["LKX"]  # per unit load
    bx = kx / (t["PCX1"] * mux)
    kappas = np.linspace(0.0, 1.0, 20001)
    peak_x = max(magic_formula(mux, t["PCX1"], bx, ex, k) for k in kappas)
    locked = magic_formula(mux, t["PCX1"], bx, ex, 1.0)
    peak_y = muy if t["PCY1"] >= 1 else muy * math.sin(t["PCY1"] * math.pi / 2)  # sin reaches 1 when C >= 1
    return peak_x, peak_y, locked


def shipped_tires():
    return {e.attribute: mf_coefficients(read_tir(e.tire_file)) for e in read_attribute_file(DEFAULT_ATTRIBUTE_FILE)}


def test_each_surface_has_the_friction_of_the_road_it_cites():
    # At the tire's nominal load the peak mu (longitudinal and lateral) equals the cited peak within 2 %,
    # and the locked-wheel mu (kappa = -1, what a skid measures) the cited sliding value within 10 %.
    tires = shipped_tires()
    assert sorted(tires) == sorted(SURFACES)
    for attribute, (name, peak, sliding, _) in SURFACES.items():
        assert DEFAULT_ATTRIBUTE_FILE.parent.joinpath(name).read_text().count(f"{peak:.2f}") >= 1
        t = tires[attribute]
        peak_x, peak_y, locked = friction(t, t["FNOMIN"])
        print(f"{name}: peak mu_x {peak_x:.4f}, mu_y {peak_y:.4f} (cited {peak}); "
              f"locked {locked:.4f} (cited {sliding})")
        assert peak_x == pytest.approx(peak, rel=0.02) and peak_y == pytest.approx(peak, rel=0.02)
        assert locked == pytest.approx(sliding, rel=0.10)


def test_simple_rsa_values_lie_in_the_cited_friction_band():
    # The Simple model has one mu per wheel (peak = sliding): RSA / 10 lies between the cited sliding and
    # peak values, so both models describe the same road.
    for name, peak, sliding, rsa in SURFACES.values():
        assert sliding <= rsa / 10 <= peak, name


def band(t, mass, cg_height, wheelbase, a, b, v0):
    """Stopping distances from v0 at the most favourable peak and the least favourable locked-wheel mu over
    the wheel loads of a straight stop: static loads +- the transfer at up to the peak deceleration."""
    static = [mass * G * b / (2 * wheelbase), mass * G * a / (2 * wheelbase)]
    transfer = mass * 1.1 * G * cg_height / (2 * wheelbase)
    loads = np.linspace(min(static) - transfer, max(static) + transfer, 41)
    values = [friction(t, fz) for fz in loads]
    mu_peak = max(v[0] for v in values)
    mu_locked = min(v[2] for v in values)
    return v0**2 / (2 * mu_peak * G), v0**2 / (2 * mu_locked * G)


def test_full_brake_stops_within_the_surface_band_in_both_models(simple_fmu, advanced_fmu, defaults_advanced):
    # Full pedal from 20 m/s on each surface, drag and rolling resistance off. Without ABS a stop lies
    # between the distance at peak friction and at locked-wheel friction, v0^2 / (2 mu g): the band is taken
    # over the loads of the stop (load sensitivity of the tire, PDX2, PKX2, PEX2...). The Simple FMU stops
    # at v0^2 / (2 (RSA / 10) g) exactly; the Advanced FMU (Magic Formula tires, load transfer, brake
    # balance, wheel lock) anywhere in the band.
    advanced = defaults_advanced
    tires = shipped_tires()
    v0 = 20.0
    for attribute, (name, peak, sliding, rsa) in SURFACES.items():
        p = advanced
        shortest, longest = band(tires[attribute], p["mass"], p["cg_height"],
                                 p["cg_to_front_axle"] + p["cg_to_rear_axle"], p["cg_to_front_axle"],
                                 p["cg_to_rear_axle"], v0)
        simple = simulate_fmu(str(simple_fmu), start_values={"v0": v0, "brake": 1.0, **NO_RESISTANCES,
                                                             **{f"mu_{w}": rsa / 10 for w in WHEELS}},
                              output=["s", "stopped"], stop_time=v0 / (rsa / 10 * G) + 1, output_interval=0.1)
        result = simulate_fmu(str(advanced_fmu), start_values={"v0": v0, "brake": 1.0, **NO_RESISTANCES,
                                                               **{f"surface_{w}": attribute for w in WHEELS}},
                              output=["s", "stopped"], stop_time=v0 / (sliding * 0.9 * G) + 1, output_interval=0.1)
        print(f"{name}: band [{shortest:.2f}, {longest:.2f}] m (cited peak/sliding "
              f"[{v0**2 / (2 * peak * G):.2f}, {v0**2 / (2 * sliding * G):.2f}]); Simple (mu {rsa / 10}) "
              f"{simple['s'][-1]:.2f} m, Advanced {result['s'][-1]:.2f} m")
        assert simple["stopped"][-1] and result["stopped"][-1]
        assert simple["s"][-1] == pytest.approx(v0**2 / (2 * rsa / 10 * G), rel=1e-9)
        for distance in (simple["s"][-1], result["s"][-1]):
            assert shortest <= distance <= longest
        # the band is the cited one, widened only by the tire's load sensitivity
        assert shortest >= 0.95 * v0**2 / (2 * peak * G) and longest <= 1.05 * v0**2 / (2 * sliding * G)
