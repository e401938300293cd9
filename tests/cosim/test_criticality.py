"""Criticality measures (measures.py) against hand computations, their plain-float forms against the array
forms bit for bit (the master picks one or the other by the number of vehicles: the located instants must
not depend on that), and the horizons against motions that respect the bounds they assume."""

import math

import numpy as np
import pytest

from sdl_fmu.cosim.geometry import Footprint
from sdl_fmu.cosim.measures import (approach_horizon, approach_horizons, band_times, conflict_station, course_horizon,
                                    distance, distance_horizon, distance_horizons, distance_rate, distance_rates,
                                    distances, drac, drac_rate, dracs, heading_horizon, headway, headway_rate,
                                    headways, passage_known, post_encroachment_time, signed_distance,
                                    signed_distances, ttc, ttc_rate, ttcs)

EGO_LENGTH, EGO_WIDTH = 4.6, 1.8  # m
CAR_LENGTH, CAR_WIDTH = 4.5, 1.8
LANE = 3.6  # m, lane width


def bisect_root(f, lo: float, hi: float, tolerance: float = 1e-9) -> float:
    """The instant f turns from < 0 to >= 0 in [lo, hi] (f(lo) < 0 <= f(hi)), as the master's bisection."""
    assert f(lo) < 0 <= f(hi)
    while hi - lo > tolerance:
        mid = (lo + hi) / 2
        lo, hi = (lo, mid) if f(mid) >= 0 else (mid, hi)
    return hi


# ---- geometry by hand ------------------------------------------------------------------------------------

def test_rotated_ego_corner_to_vehicle_edge():
    # Ego 4 x 2 m (half 2, 1) turned by 30 deg: its front-right corner is (2 cos30 + sin30, 2 sin30 - cos30)
    # = (sqrt3 + 0.5, 1 - sqrt3 / 2) = (2.232, 0.134). A 4 x 2 vehicle centred at (5, 0) has its rear edge
    # at x = 3 for |y| <= 1, which that corner faces: distance 3 - sqrt3 - 0.5 = 0.76795.
    ego = Footprint.of(4.0, 2.0, math.radians(30))
    assert distance(ego, 5.0, 0.0, 4.0, 2.0) == pytest.approx(3 - math.sqrt(3) - 0.5, abs=1e-12)


def test_vehicle_corner_to_rotated_ego_edge():
    # Ego 4 x 2 m turned by -30 deg. The point (0, 1.5) of its body frame lies 0.5 m off the middle of its left
    # side (v = 1); in the road frame it is R(-30)(0, 1.5) = (1.5 sin30, 1.5 cos30) = (0.75, 1.299). A 4 x 2
    # vehicle with its rear-right corner there (centre (2.75, 2.299)) lies beyond that side: its other
    # corners are farther (e.g. (4.75, 1.299) is at body (3.46, 3.5)) and the ego's nearest corner, the rear
    # left at (-2 cos30 + sin30, 2 sin30 + cos30) = (-1.232, 1.866), is 1.98 m left of the vehicle's rear
    # edge x = 0.75. Distance 0.5.
    psi = math.radians(-30)
    ego = Footprint.of(4.0, 2.0, psi)
    corner = (-1.5 * math.sin(psi), 1.5 * math.cos(psi))
    assert corner == pytest.approx((0.75, 1.5 * math.cos(math.radians(30))))
    assert distance(ego, corner[0] + 2.0, corner[1] + 1.0, 4.0, 2.0) == pytest.approx(0.5, abs=1e-12)


def test_rotated_ego_corner_to_vehicle_corner():
    # Ego 4 x 2 m turned by 30 deg, front-right corner (2.232, 0.134) (as above). A 4 x 2 vehicle whose
    # front-left... rather its top-left corner sits 3 m further in x and 4 m lower in y, at (5.232, -3.866)
    # (centre (7.232, -4.866)): the closest pair is corner to corner, hypot(3, 4) = 5. (The vehicle's corner
    # seen from the ego's body frame, (2.598, -5.964), is 0.598 past the ego's front and 4.964 past its right
    # side: hypot = 5 too, the same pair.)
    ego = Footprint.of(4.0, 2.0, math.radians(30))
    front_right = (math.sqrt(3) + 0.5, 1 - math.sqrt(3) / 2)
    dx, dy = front_right[0] + 3 + 2, front_right[1] - 4 - 1
    assert distance(ego, dx, dy, 4.0, 2.0) == pytest.approx(5.0, abs=1e-12)


def test_overlapping_footprints_have_distance_zero_and_signed_minus_the_depth():
    # Both 4 x 2 m, aligned, centres 3 m apart lengthwise and 0.5 m sideways: they overlap by 4 - 3 = 1 m
    # lengthwise and 2 - 0.5 = 1.5 m sideways; the shortest separating translation is 1 m.
    ego = Footprint.of(4.0, 2.0, 0.0)
    assert signed_distance(ego, 3.0, 0.5, 4.0, 2.0) == -1.0
    assert distance(ego, 3.0, 0.5, 4.0, 2.0) == 0.0
    # touching end to end: 0, and no rate
    assert distance(ego, 4.0, 0.0, 4.0, 2.0) == 0.0
    assert distance_rate(ego, 4.0, 0.0, -10.0, 0.0, 0.0, 4.0, 2.0) == 0.0


# ---- an oncoming vehicle in the adjacent lane --------------------------------------------------------------

def oncoming(t, ego_speed=25.0, car_speed=20.0, gap0=120.0, lateral=LANE):
    """Ego at 25 m/s on y = 0 (yaw 0); a car oncoming at 20 m/s in the lane to the left (y = 3.6 m), its
    centre 120 m ahead at t = 0. Relative position (vehicle - ego) and velocity."""
    return gap0 - (ego_speed + car_speed) * t, lateral, -(ego_speed + car_speed), 0.0


def test_oncoming_vehicle_in_the_adjacent_lane_distance_is_the_lateral_clearance_over_the_whole_overlap():
    # Lateral clearance = 3.6 - 1.8 / 2 - 1.8 / 2 = 1.8 m. The footprints overlap lengthwise while
    # |dx| <= (4.6 + 4.5) / 2 = 4.55 m, i.e. for dx = 120 - 45 t in [-4.55, 4.55]: t in [115.45, 124.55] / 45.
    # There the nearest points are on the two facing sides: distance 1.8 and rate 0. Outside, corner to
    # corner: sqrt((|dx| - 4.55)^2 + 1.8^2), with rate -45 (|dx| - 4.55) / distance * sign(dx).
    ego = Footprint.of(EGO_LENGTH, EGO_WIDTH, 0.0)
    clearance = LANE - EGO_WIDTH / 2 - CAR_WIDTH / 2
    half_sum = (EGO_LENGTH + CAR_LENGTH) / 2
    start, end = (120 - half_sum) / 45, (120 + half_sum) / 45
    for k, t in enumerate(np.linspace(start, end, 101)):
        dx, dy, vx, vy = oncoming(t)
        assert distance(ego, dx, dy, CAR_LENGTH, CAR_WIDTH) == pytest.approx(clearance, abs=1e-12)
        rate = distance_rate(ego, dx, dy, vx, vy, 0.0, CAR_LENGTH, CAR_WIDTH)
        # at the two ends round-off in dx may put a corner a hair past the other's side
        assert rate == 0.0 if 0 < k < 100 else abs(rate) < 1e-12
        assert ttc(ego, dx, dy, vx, vy, CAR_LENGTH, CAR_WIDTH) == math.inf  # parallel: no collision course
    for t in (0.0, 1.0, start - 0.01, end + 0.01, 4.0):
        dx, dy, vx, vy = oncoming(t)
        along = abs(dx) - half_sum
        expected = math.sqrt(along**2 + clearance**2)
        assert distance(ego, dx, dy, CAR_LENGTH, CAR_WIDTH) == pytest.approx(expected, rel=1e-12)
        rate = distance_rate(ego, dx, dy, vx, vy, 0.0, CAR_LENGTH, CAR_WIDTH)
        assert rate == pytest.approx(-45 * along / expected * math.copysign(1, dx), rel=1e-12)
    # the closest approach located as the root of the rate (from - to >= 0): the overlap's start, where the
    # minimum is first reached, to the bisection's tolerance
    located = bisect_root(lambda t: distance_rate(ego, *oncoming(t), 0.0, CAR_LENGTH, CAR_WIDTH), 0.0, 3.0)
    assert located == pytest.approx(start, abs=1e-8)
    assert distance(ego, *oncoming(located)[:2], CAR_LENGTH, CAR_WIDTH) == pytest.approx(clearance, abs=1e-9)


# ---- head-on in the ego's lane -----------------------------------------------------------------------------

def test_head_on_in_the_ego_lane_ttc_is_gap_over_closing_speed_and_drac_closing_squared_over_twice_the_gap():
    # Same speeds, the car in the ego's lane (dy = 0): closing speed 45 m/s, bumper gap g = dx - 4.55.
    # Constant velocities: contact after g / 45 s, so TTC = g / 45 and DRAC = 45^2 / (2 g); TTC falls at
    # exactly 1 s per s (ttc_rate -1). In contact (g < 0) TTC is 0 and DRAC undefined.
    ego = Footprint.of(EGO_LENGTH, EGO_WIDTH, 0.0)
    half_sum = (EGO_LENGTH + CAR_LENGTH) / 2
    for t in np.linspace(0, 2.5, 26):
        dx, dy, vx, vy = oncoming(t, lateral=0.0)
        gap = dx - half_sum
        value = ttc(ego, dx, dy, vx, vy, CAR_LENGTH, CAR_WIDTH)
        assert value == pytest.approx(gap / 45, rel=1e-12)
        assert drac(value, vx, vy) == pytest.approx(45**2 / (2 * gap), rel=1e-12)
        assert ttc_rate(ego, dx, dy, vx, vy, 0.0, 0.0, 0.0, CAR_LENGTH, CAR_WIDTH) == pytest.approx(-1, abs=1e-12)
        assert distance(ego, dx, dy, CAR_LENGTH, CAR_WIDTH) == pytest.approx(gap, rel=1e-12)
    dx, dy, vx, vy = oncoming(2.67, lateral=0.0)  # gap 120 - 120.15 - 4.55 < 0: overlapping
    assert ttc(ego, dx, dy, vx, vy, CAR_LENGTH, CAR_WIDTH) == 0.0
    assert math.isnan(drac(0.0, vx, vy))
    # the same car 1 m to the side still hits (the footprints overlap laterally: 1 < 1.8), 2 m does not
    assert ttc(ego, 50.0, 1.0, -45.0, 0.0, CAR_LENGTH, CAR_WIDTH) == pytest.approx((50 - half_sum) / 45)
    assert ttc(ego, 50.0, 2.0, -45.0, 0.0, CAR_LENGTH, CAR_WIDTH) == math.inf
    # a car ahead moving away faster than the ego: no collision course
    assert ttc(ego, 50.0, 0.0, 5.0, 0.0, CAR_LENGTH, CAR_WIDTH) == math.inf


def test_crossing_ttc_is_the_latest_entry_over_the_axes():
    # The ego (4.6 x 1.8, yaw 0) at rest; a 4.5 x 1.8 car 20 m ahead and 10 m to the left, moving at (-2, -1)
    # relative (heading diagonally toward the ego's lane). Lengthwise the projections overlap once
    # |20 - 2t| < 4.55, i.e. t in (7.725, 12.275); sideways once |10 - t| < 1.8, i.e. t in (8.2, 11.8).
    # Both from 8.2 s: TTC = 8.2 s, and DRAC = |v| / (2 TTC) = sqrt5 / 16.4.
    ego = Footprint.of(EGO_LENGTH, EGO_WIDTH, 0.0)
    value = ttc(ego, 20.0, 10.0, -2.0, -1.0, CAR_LENGTH, CAR_WIDTH)
    assert value == pytest.approx(8.2, rel=1e-12)
    assert drac(value, -2.0, -1.0) == pytest.approx(math.sqrt(5) / 16.4, rel=1e-12)
    # moving at (-2, -0.5) it crosses y = 0 later: sideways t in (16.4, 23.6), lengthwise out by 12.275: inf
    assert ttc(ego, 20.0, 10.0, -2.0, -0.5, CAR_LENGTH, CAR_WIDTH) == math.inf


# ---- rates against finite differences of the closed forms along a motion -----------------------------------

def motion(t, start):
    """A relative motion with constant relative acceleration (ax, ay) and the ego turning at a constant yaw
    rate: (ego footprint, dx, dy, vx, vy)."""
    dx0, dy0, vx0, vy0, ax, ay, psi0, yaw_rate = start
    return (Footprint.of(EGO_LENGTH, EGO_WIDTH, psi0 + yaw_rate * t), dx0 + vx0 * t + ax * t * t / 2,
            dy0 + vy0 * t + ay * t * t / 2, vx0 + ax * t, vy0 + ay * t)


def test_distance_ttc_and_drac_rates_are_the_derivatives_along_the_motion():
    # A central difference (f(h) - f(-h)) / 2h of a smooth function errs by h^2 f''' / 6 plus round-off
    # eps |f| / h: with h = 1e-5 s, |f'''| < 1e3 and |f| < 100 that is < 2e-8 + 2e-9. The tolerance 1e-6 is
    # far above both and far below the rates (order 1..50); configurations where the nearest feature or the
    # axis setting TTC switches within +-h (a kink) are skipped by requiring one-sided differences to agree.
    rng = np.random.default_rng(3)
    h = 1e-5
    checked_distance = checked_ttc = checked_drac = 0
    for _ in range(3000):
        start = (rng.uniform(-30, 30), rng.uniform(-8, 8), rng.uniform(-40, 10), rng.uniform(-3, 3),
                 rng.uniform(-8, 8), rng.uniform(-3, 3), rng.uniform(-0.5, 0.5), rng.uniform(-0.6, 0.6))
        ego, dx, dy, vx, vy = motion(0.0, start)
        ax, ay, yaw_rate = start[4], start[5], start[7]
        before, now, after = (distance(*motion(s, start)[:3], CAR_LENGTH, CAR_WIDTH) for s in (-h, 0.0, h))
        if now > 0 and abs((after - now) - (now - before)) < 1e-9:
            rate = distance_rate(ego, dx, dy, vx, vy, yaw_rate, CAR_LENGTH, CAR_WIDTH)
            assert rate == pytest.approx((after - before) / (2 * h), abs=1e-6)
            checked_distance += 1
        value = ttc(ego, dx, dy, vx, vy, CAR_LENGTH, CAR_WIDTH)
        if 0 < value < math.inf:
            before, after = (ttc(*motion(s, start), CAR_LENGTH, CAR_WIDTH) for s in (-h, h))
            if math.isfinite(before + after) and abs((after - value) - (value - before)) < 1e-9:
                rate = ttc_rate(ego, dx, dy, vx, vy, ax, ay, yaw_rate, CAR_LENGTH, CAR_WIDTH)
                assert rate == pytest.approx((after - before) / (2 * h), abs=1e-6)
                checked_ttc += 1
                if value < 0.1:
                    continue
                # DRAC ~ S / 2T grows without bound as TTC T -> 0: its third derivative ~ 3 S / T^4, so the
                # central difference errs by ~ h^2 S / 2T^4 against a rate ~ S / 2T^2, relatively h^2 / T^2
                # <= 1e-8 for T >= 0.1 s: compared relatively, to 1e-6
                before, after = (drac(ttc(*motion(s, start), CAR_LENGTH, CAR_WIDTH), *motion(s, start)[3:])
                                 for s in (-h, h))
                rate = drac_rate(ego, dx, dy, vx, vy, ax, ay, yaw_rate, CAR_LENGTH, CAR_WIDTH)
                assert rate == pytest.approx((after - before) / (2 * h), abs=1e-6, rel=1e-6)
                checked_drac += 1
    assert checked_distance > 2000 and checked_ttc > 100 and checked_drac > 50


# ---- horizons hold on motions within their bounds ------------------------------------------------------------

def test_horizons_are_lower_bounds_on_motions_within_the_bounds():
    # Motions with |relative acceleration| <= A and |yaw rate| <= r_max (constant here, any within the
    # bounds would do): before distance_horizon the distance stays above the floor, before approach_horizon
    # and heading_horizon the rate stays below 0. Checked on a grid up to each horizon; positions out to
    # 300 m so that heading_horizon (the far one) binds in many cases.
    rng = np.random.default_rng(5)
    acceleration, yaw_rate_bound = 12.0, 0.8
    radius = math.hypot(EGO_LENGTH / 2, EGO_WIDTH / 2)
    turn = radius * yaw_rate_bound
    checked = 0
    for _ in range(400):
        angle = rng.uniform(0, 2 * math.pi)
        size = rng.uniform(0, acceleration)
        start = (rng.choice([rng.uniform(-60, 60), rng.uniform(-300, 300)]), rng.uniform(-10, 10),
                 rng.uniform(-45, 45), rng.uniform(-4, 4),
                 size * math.cos(angle), size * math.sin(angle), rng.uniform(-0.3, 0.3),
                 rng.uniform(-yaw_rate_bound, yaw_rate_bound))
        ego, dx, dy, vx, vy = motion(0.0, start)
        d = distance(ego, dx, dy, CAR_LENGTH, CAR_WIDTH)
        if d <= 0:
            continue
        frozen = distance_rate(ego, dx, dy, vx, vy, 0.0, CAR_LENGTH, CAR_WIDTH)
        floor = d * rng.uniform(0.2, 0.9)
        until = distance_horizon(d, frozen, floor, turn, acceleration)
        for s in np.linspace(0, until, 80):
            assert distance(*motion(s, start)[:3], CAR_LENGTH, CAR_WIDTH) > floor - 1e-9
        approach = max(approach_horizon(d, frozen, math.hypot(vx, vy), turn, acceleration, yaw_rate_bound),
                       heading_horizon(dx, dy, vx, vy, radius + math.hypot(CAR_LENGTH, CAR_WIDTH) / 2, turn,
                                       acceleration) if frozen < -turn else 0.0)
        if approach > 0:
            for s in np.linspace(0, approach, 80)[:-1]:
                ego_s, dx_s, dy_s, vx_s, vy_s = motion(s, start)
                assert distance_rate(ego_s, dx_s, dy_s, vx_s, vy_s, start[7], CAR_LENGTH, CAR_WIDTH) < 0
            checked += 1
    assert checked > 50


def test_heading_horizon_holds_against_the_fastest_turn_of_the_relative_velocity():
    # heading_horizon's bound is stretched (by 1.5, up to three times) while the angles themselves prove it: the
    # relative velocity's direction turns by at most asin(A tau / |v0|), the centre offset's by at most
    # asin(P / rho0) with P = |v0| tau + A tau^2 / 2. Checked against the motions that turn the relative velocity
    # fastest: an acceleration of size A at a fixed angle phi to the velocity (phi = +-90 deg turns it at A / |v|,
    # others also shrink it, which turns it faster still), integrated by the midpoint rule in 2 ms steps (its error
    # in position, ~ A^2 h^2 / |v| per step, is far below the margins of a few cm checked), with the ego turning at
    # +-r_max. Before the bound the distance's rate stays < 0 (the approach goes on).
    rng = np.random.default_rng(21)
    acceleration, yaw_rate_bound = 12.0, 0.8
    radius = math.hypot(EGO_LENGTH / 2, EGO_WIDTH / 2)
    radius_sum = radius + math.hypot(CAR_LENGTH, CAR_WIDTH) / 2
    turn = radius * yaw_rate_bound
    stretched = checked = 0
    for _ in range(150):
        rho, bearing = rng.uniform(60, 400), rng.uniform(0, 2 * math.pi)
        dx, dy = rho * math.cos(bearing), rho * math.sin(bearing)
        speed = rng.uniform(15, 60)
        heading = bearing + math.pi + rng.uniform(-0.6, 0.6)  # roughly toward the ego: approaching
        vx, vy = speed * math.cos(heading), speed * math.sin(heading)
        bound = heading_horizon(dx, dy, vx, vy, radius_sum, turn, acceleration)
        if bound <= 0:
            continue
        # the bound before stretching (heading_horizon's first formula), to show the stretch is exercised
        alpha = math.acos(max(-1.0, min(1.0, -(dx * vx + dy * vy) / (rho * speed))))
        margin = math.acos(2 * turn / speed) - math.asin(2 * radius_sum / rho) - alpha
        within = min(reach_time_for_test(rho / 2, speed, acceleration), speed / (2 * acceleration))
        first = min(within, margin / (2 * (speed + acceleration * within) / rho + 2 * acceleration / speed))
        stretched += bound > first * 1.4
        psi0, yaw_rate = rng.uniform(-0.3, 0.3), rng.choice([-1, 1]) * yaw_rate_bound
        for phi in (math.pi / 2, -math.pi / 2, rng.uniform(math.pi / 2, math.pi), -rng.uniform(math.pi / 2, math.pi)):
            cos_phi, sin_phi = math.cos(phi), math.sin(phi)
            x, y, u, w, t, h = dx, dy, vx, vy, 0.0, 2e-3
            while t < bound:
                ego = Footprint.of(EGO_LENGTH, EGO_WIDTH, psi0 + yaw_rate * t)
                assert distance_rate(ego, x, y, u, w, yaw_rate, CAR_LENGTH, CAR_WIDTH) < 0, (t, bound)
                ax, ay = turned_acceleration(u, w, acceleration, cos_phi, sin_phi)
                um, wm = u + ax * h / 2, w + ay * h / 2  # midpoint
                ax, ay = turned_acceleration(um, wm, acceleration, cos_phi, sin_phi)
                x, y, u, w, t = x + um * h, y + wm * h, u + ax * h, w + ay * h, t + h
            checked += 1
    assert checked > 400 and stretched > 50, (checked, stretched)


def turned_acceleration(u, w, size, cos_phi, sin_phi):
    """An acceleration of the given size at the angle phi to the velocity (u, w)."""
    speed = math.hypot(u, w)
    return size * (cos_phi * u - sin_phi * w) / speed, size * (sin_phi * u + cos_phi * w) / speed


def reach_time_for_test(distance_, rate, acceleration):
    """The smallest tau >= 0 with rate tau + acceleration tau^2 / 2 >= distance_ (rate >= 0 here)."""
    return (math.sqrt(rate * rate + 2 * acceleration * distance_) - rate) / acceleration


def test_passage_known_never_contradicts_a_motion_within_the_bounds():
    # The front of the ego's footprint, x(t) + (L/2) |cos psi| + (W/2) |sin psi|, for motions whose station
    # acceleration stays within A (here a(t) = A sin(w t + phase) scaled by k <= 1) and whose yaw rate stays
    # within r_max: wherever passage_known answers True or False at an instant between two known ones, the
    # front is indeed at or past / short of the station there (it answers None otherwise: a probe).
    rng = np.random.default_rng(11)
    acceleration, yaw_rate_bound = 9.0, 0.7
    radius = math.hypot(EGO_LENGTH / 2, EGO_WIDTH / 2)
    turn = radius * yaw_rate_bound
    decided = 0

    def front(t, v0, k, w, phase, r, psi0):
        # x' = v0 + k A (cos(phase) - cos(w t + phase)) / w: x'' = k A sin(w t + phase), |x''| <= A
        x = v0 * t + k * acceleration * (math.cos(phase) * t - (math.sin(w * t + phase) - math.sin(phase)) / w) / w
        psi = psi0 + r * t
        rate = v0 + k * acceleration * (math.cos(phase) - math.cos(w * t + phase)) / w
        return x + EGO_LENGTH / 2 * abs(math.cos(psi)) + EGO_WIDTH / 2 * abs(math.sin(psi)), rate

    for _ in range(300):
        args = (rng.uniform(0, 40), rng.uniform(0, 1), rng.uniform(0.5, 20), rng.uniform(0, 2 * math.pi),
                rng.uniform(-yaw_rate_bound, yaw_rate_bound), rng.uniform(-0.2, 0.2))
        low, high = 0.0, rng.uniform(1e-4, 0.1)
        (low_position, low_rate), (high_position, high_rate) = front(low, *args), front(high, *args)
        for middle in np.linspace(low, high, 23)[1:-1]:
            middle_position = front(middle, *args)[0]
            for station in (middle_position + rng.uniform(-1, 1) * 10.0 ** rng.uniform(-6, 0),
                            rng.uniform(low_position - 0.5, high_position + 0.5)):
                for known_low in (None, low_position):
                    outcome = passage_known(middle, low, known_low, low_rate, high, high_position, high_rate,
                                            station, turn, acceleration)
                    if outcome is not None:
                        assert outcome == (middle_position >= station), (args, middle, station)
                        decided += 1
    assert decided > 1000


def test_course_horizon_is_a_lower_bound_on_a_collision_course_or_headway_beginning():
    # A vehicle beside the ego's path (the next lane, or farther), relative acceleration |(ax, ay)| <= A in
    # any direction (half the cases straight at the vehicle's side, the worst for the lateral gap), the ego
    # turning at up to r_max: before course_horizon's instant TTC stays undefined (no collision course) and
    # so does the headway (given both moving forward: only the lateral overlap could start it). Checked on a
    # grid up to each horizon.
    rng = np.random.default_rng(17)
    acceleration, yaw_rate_bound = 12.0, 0.8
    radius = math.hypot(EGO_LENGTH / 2, EGO_WIDTH / 2)
    turn = radius * yaw_rate_bound
    proven = 0
    for _ in range(1500):
        side = rng.choice([-1.0, 1.0])
        dy0 = side * rng.uniform(1.0, 9.0)
        size = rng.uniform(0, acceleration)
        angle = rng.uniform(0, 2 * math.pi) if rng.uniform() < 0.5 else (-math.pi / 2 if side > 0 else math.pi / 2)
        start = (rng.uniform(-60, 60), dy0, rng.choice([rng.uniform(-45, 45), rng.uniform(-2, 2)]),
                 rng.uniform(-2, 2), size * math.cos(angle), size * math.sin(angle), rng.uniform(-0.2, 0.2),
                 rng.choice([-1.0, 1.0, rng.uniform(-1, 1)]) * yaw_rate_bound)
        ego, dx, dy, vx, vy = motion(0.0, start)
        a, b, c, s = ego
        half_x = a * abs(c) + b * abs(s) + CAR_LENGTH / 2
        half_y = a * abs(s) + b * abs(c) + CAR_WIDTH / 2
        until = course_horizon(dx, dy, vx, vy, half_x, half_y, 1.0, turn, acceleration)
        assert 0.0 <= until <= 1.0
        if until == 0.0:
            continue
        proven += 1
        for t in np.linspace(0, until, 60):
            ego_t, dx_t, dy_t, vx_t, vy_t = motion(t, start)
            assert ttc(ego_t, dx_t, dy_t, vx_t, vy_t, CAR_LENGTH, CAR_WIDTH) == math.inf
            assert headway(ego_t, dx_t, dy_t, 25.0, 20.0, CAR_LENGTH, CAR_WIDTH) == math.inf
    assert proven > 300
    # not vacuous: a car 20 m ahead in the next lane (clearance 3.6 - 1.8 = 1.8 m), closing at 40 m/s, is
    # proven off course for a while, one in the ego's lane never
    assert course_horizon(20.0, LANE, -40.0, 0.0, 4.55, 1.8, 1.0, turn, acceleration) > 0.01
    assert course_horizon(20.0, 0.5, -40.0, 0.0, 4.55, 1.8, 1.0, turn, acceleration) == 0.0


# ---- PET on a hand-built crossing -------------------------------------------------------------------------------

def test_post_encroachment_time_of_a_vehicle_crossing_into_the_ego_lane_and_back():
    # Road frame, lateral + right. The ego's lane is the band 0 < lateral < 3.6; a 4.5 x 1.8 car oncoming
    # at 10 m/s (station 200 - 10 t) in the other lane (lateral -1.8) moves into the ego's lane (to 1.8) over
    # 2 s from t = 1, and back (to -1.8) over 2 s from t = 5. Its footprint overlaps the band while its
    # centre is within (-0.9, 4.5): it enters when -1.8 + 1.8 (t - 1) = -0.9, t = 1.5, and leaves when
    # 1.8 - 1.8 (t - 5) = -0.9, t = 6.5. Then it stands at station 200 - 65 = 135, its rear (toward the ego)
    # at 132.75: the conflict area's near end. The ego (4.6 m long, front 2.3 m ahead of its centre) at a
    # constant 15 m/s from station 0 reaches it when 15 t + 2.3 = 132.75: t = 8.69667 s. PET = 2.19667 s.
    assert band_times(1.0, -1.8, 1.8, 2.0, CAR_WIDTH, 0.0, LANE) == pytest.approx((1.5, math.inf))
    enter, leave = band_times(5.0, 1.8, -1.8, 2.0, CAR_WIDTH, 0.0, LANE)
    assert enter == -math.inf and leave == pytest.approx(6.5, abs=1e-12)
    station = 200 - 10 * leave
    near_end = conflict_station(station, CAR_LENGTH)
    assert near_end == pytest.approx(132.75, abs=1e-12)
    ego_reaches = (near_end - EGO_LENGTH / 2) / 15
    assert post_encroachment_time(leave, ego_reaches) == pytest.approx((132.75 - 2.3) / 15 - 6.5, abs=1e-12)
    # at 25 m/s the ego's front is there at 5.218 s, before the car left: no post-encroachment
    assert math.isnan(post_encroachment_time(leave, (near_end - EGO_LENGTH / 2) / 25))
    # a move that stays out of the band (to -0.95: the centre never passes -0.9) never encroaches
    assert all(math.isnan(v) for v in band_times(1.0, -1.8, -0.95, 2.0, CAR_WIDTH, 0.0, LANE))


# ---- time headway ---------------------------------------------------------------------------------------------

def test_time_headway_to_a_vehicle_ahead_moving_the_same_way():
    # Ego at 25 m/s, a car 50 m ahead (centres) in its lane at 20 m/s the same way: bumper gap
    # 50 - 2.3 - 2.25 = 45.45 m, headway 45.45 / 25 = 1.818 s. Oncoming, beside (lateral offset 1.8 + 0.1:
    # no lateral overlap of the footprints) or behind: no headway.
    ego = Footprint.of(EGO_LENGTH, EGO_WIDTH, 0.0)
    assert headway(ego, 50.0, 0.0, 25.0, 20.0, CAR_LENGTH, CAR_WIDTH) == pytest.approx(45.45 / 25, rel=1e-12)
    assert headway(ego, 50.0, 0.0, 25.0, -20.0, CAR_LENGTH, CAR_WIDTH) == math.inf
    assert headway(ego, 50.0, 1.9, 25.0, 20.0, CAR_LENGTH, CAR_WIDTH) == math.inf
    assert headway(ego, -50.0, 0.0, 25.0, 20.0, CAR_LENGTH, CAR_WIDTH) == math.inf


# ---- plain floats and arrays give the same bits --------------------------------------------------------------

def mix(rng, *options):
    """Per element, one of the option arrays at random."""
    pick = rng.integers(0, len(options), len(options[0]))
    return np.choose(pick, options)


def random_vehicles(rng, n):
    """Positions from overlapping to far, exact ties (same station, same lateral, standing still), velocities
    parallel to an axis (q = 0 on it), oblique, and aimed at the ego."""
    dx = mix(rng, rng.uniform(-6, 6, n), rng.uniform(-100, 100, n), rng.choice([0.0, 4.55, -3.0], n))
    dy = mix(rng, rng.uniform(-4, 4, n), rng.choice([0.0, 1.8, 3.6], n))
    aim = rng.uniform(1, 10, n)  # s, some aimed at the ego: on a collision course
    vx = mix(rng, rng.uniform(-50, 20, n), np.zeros(n), -dx / aim)
    vy = mix(rng, rng.uniform(-3, 3, n), np.zeros(n), -dy / aim)
    return dx, dy, vx, vy, rng.uniform(3, 12, n), rng.uniform(1.5, 2.6, n)


@pytest.mark.parametrize("psi", [0.0, 0.1, -0.4, math.pi / 2, 3.0])
def test_plain_float_forms_equal_the_array_forms_bit_for_bit(psi):
    rng = np.random.default_rng(17)
    ego = Footprint.of(EGO_LENGTH, EGO_WIDTH, psi)
    dx, dy, vx, vy, length, width = random_vehicles(rng, 3000)
    rows = list(zip(dx.tolist(), dy.tolist(), vx.tolist(), vy.tolist(), length.tolist(), width.tolist()))
    expected = signed_distances(ego, dx, dy, length, width)
    assert np.array_equal([signed_distance(ego, x, y, l, w) for x, y, _, _, l, w in rows], expected)
    assert np.array_equal([distance(ego, x, y, l, w) for x, y, _, _, l, w in rows],
                          distances(ego, dx, dy, length, width))
    assert (expected < 0).sum() > 100 and (expected > 0).sum() > 1000
    for yaw_rate in (0.0, 0.3):
        assert np.array_equal([distance_rate(ego, x, y, u, v, yaw_rate, l, w) for x, y, u, v, l, w in rows],
                              distance_rates(ego, dx, dy, vx, vy, yaw_rate, length, width))
    times = ttcs(ego, dx, dy, vx, vy, length, width)
    assert np.array_equal([ttc(ego, *row) for row in rows], times)
    assert ((times > 0) & (times < math.inf)).sum() > 300
    assert np.array_equal([drac(t, u, v) for t, (_, _, u, v, _, _) in zip(times.tolist(), rows)],
                          dracs(times, vx, vy), equal_nan=True)
    for station_rate in (25.0, 0.0):
        assert np.array_equal([headway(ego, x, y, station_rate, u, l, w) for x, y, u, _, l, w in rows],
                              headways(ego, dx, dy, station_rate, vx, length, width))


# ---- the run's record, with located instants, whatever the step ------------------------------------------------

from typing import NamedTuple  # noqa: E402

from sdl_fmu.cosim.extremes import RANGE, Extremes  # noqa: E402
from sdl_fmu.cosim.measures import relative_motion  # noqa: E402
from sdl_fmu.cosim.traffic import Traffic  # noqa: E402
from sdl_fmu.results import scenario_units  # noqa: E402
from sdl_fmu.units import FOOT  # noqa: E402


class State(NamedTuple):
    """The EgoState fields the measures read (ISO 8855; body-frame velocity and acceleration)."""

    time: float
    x: float
    y: float
    psi: float
    vx: float
    vy: float
    ax: float
    ay: float
    yaw_rate: float


def traffic_of(*vehicles) -> Traffic:
    """Vehicles with one motion each: (t0, station0, lateral0, speed0, lateral1, speed1, duration)."""
    traffic = Traffic(capacity=max(len(vehicles), 1))
    traffic.size = len(vehicles)
    for i, row in enumerate(vehicles):
        for name, value in zip(("t0", "station0", "lateral0", "speed0", "lateral1", "speed1", "duration"), row):
            getattr(traffic, name)[i] = value
        traffic.length[i], traffic.width[i] = CAR_LENGTH, CAR_WIDTH
    traffic.present[:traffic.size] = True
    traffic.active = np.arange(traffic.size)
    return traffic


def braking(v0: float, deceleration: float):
    """The ego on y = 0 braking from v0 at a constant deceleration until it stops."""
    stop = v0 / deceleration

    def state(t: float) -> State:
        if t >= stop:
            return State(t, v0 * stop / 2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        return State(t, v0 * t - deceleration * t * t / 2, 0.0, 0.0, v0 - deceleration * t, 0.0, -deceleration,
                     0.0, 0.0)
    return state


def cruising(v: float):
    return lambda t: State(t, v * t, 0.0, 0.0, v, 0.0, 0.0, 0.0, 0.0)


def master_like_run(traffic: Traffic, ego, step: float, end: float, period: float = 0.05) -> Extremes:
    """What the master does with the record: offer the values at every communication point (the step's ends
    and the driver's samples), and where a vehicle's distance, TTC, minus DRAC or headway rate turned from
    < 0 at the step's start to >= 0 at its end, or its collision course began or ended, bisect that instant
    to 1e-9 s and offer the values there too."""
    extremes = Extremes(EGO_LENGTH, EGO_WIDTH)
    points = sorted(set(np.round(np.arange(0, end + step / 2, step), 12))
                    | set(np.round(np.arange(0, end, period), 12)))
    idx = traffic.active
    previous = None
    for t in points:
        state = ego(t)
        now = {i: extremes.rates(traffic, i, state) for i in idx.tolist()}
        if previous is not None:
            for i in idx.tolist():
                for k in range(len(now[i])):
                    if previous[1][i][k] < 0 and now[i][k] >= 0:
                        def condition(probe, i=i, k=k):
                            return -1.0 if extremes.rates(traffic, i, ego(probe))[k] < 0 else 1.0
                        located = bisect_root(condition, previous[0], t)
                        extremes.observe(traffic, idx, ego(located))
                if math.isnan(previous[1][i][1]) != math.isnan(now[i][1]):  # a collision course began or ended
                    was = math.isnan(previous[1][i][1])

                    def changed(probe, i=i, was=was):
                        return 1.0 if math.isnan(extremes.rates(traffic, i, ego(probe))[1]) != was else -1.0
                    located = bisect_root(changed, previous[0], t)
                    extremes.observe(traffic, idx, ego(located - 1e-9))  # the last instant on the course
        extremes.observe(traffic, idx, state)
        previous = (t, now)
    return extremes


STEPS = (0.001, 0.01, 1.0, 10.0)


@pytest.mark.parametrize("step", STEPS)
def test_oncoming_vehicle_in_the_adjacent_lane_minimum_distance_and_its_instant_whatever_the_step(step):
    # The ego at 25 m/s on lateral 0, a car oncoming at 20 m/s on lateral -3.6 (the lane to the left; road
    # lateral + right), its centre 120 m ahead at t = 0: the footprints are 1.8 m apart over the whole
    # lengthwise overlap, first at t = (120 - 4.55) / 45 = 2.56556 s (see the test above). No collision
    # course: TTC and DRAC never apply; no headway (oncoming). In feet: 1.8 / 0.3048 = 5.9055 ft.
    traffic = traffic_of((0.0, 120.0, -LANE, 20.0, -LANE, 20.0, 0.0))
    extremes = master_like_run(traffic, cruising(25.0), step, end=4.0)
    summary = scenario_units.criticality(extremes.summary([1]), "English")
    vehicle = summary["vehicles"][0]
    assert vehicle["vehicle"] == 1
    assert vehicle["min_distance"] == pytest.approx(1.8 / FOOT, abs=1e-6)
    assert vehicle["min_distance_time_s"] == pytest.approx((120 - 4.55) / 45, abs=1e-6)
    assert vehicle["min_ttc_s"] is None and vehicle["max_drac"] is None and vehicle["min_headway_s"] is None
    assert vehicle["min_pet_s"] is None
    assert {k: v for k, v in summary.items() if k != "vehicles"} == {k: v for k, v in vehicle.items()
                                                                     if k != "vehicle"}


@pytest.mark.parametrize("step", STEPS)
def test_braking_ego_and_a_stopped_car_ahead_minimum_distance_ttc_and_drac_whatever_the_step(step):
    # The ego brakes from v0 = 20 m/s at a = 6 m/s2 (stops at 10/3 s after 100/3 m) toward a car standing in
    # its lane with a bumper gap g0 = 10 + 100/3 m (centre 4.55 further). The gap is
    # g = g0 - (v0 t - a t^2 / 2), its rate -v: the minimum distance G = g0 - v0^2 / 2a = 10 m is reached
    # when v = 0, t = 10/3 s (the root of the rate). Constant-velocity TTC = g / v; with g = G + v^2 / 2a
    # (the stopping distance still ahead), dTTC/dt = -1 + g a / v^2 = 0 at v^2 / 2a = G: v = sqrt(2 a G) =
    # sqrt(120) m/s, t = (20 - sqrt(120)) / 6 = 1.50763 s, TTC = 2 G / v = sqrt(2 G / a) = 1.82574 s.
    # DRAC = v^2 / (2 g) = v^2 / (2 G + v^2 / a) grows with v: its maximum is at t = 0, 400 / (2 g0) =
    # 4.61538 m/s2. The time headway to the stopped car (it applies to a vehicle ahead that stands still) is
    # g / v, the same quantity as TTC here (the car does not move): its minimum is TTC's, at the same instant.
    # None of these instants but t = 0 is a communication point (multiples of 0.05 s or of the step): they are
    # located.
    g0 = 10 + 400 / 12
    traffic = traffic_of((0.0, g0 + 4.55, 0.0, 0.0, 0.0, 0.0, 0.0))
    extremes = master_like_run(traffic, braking(20.0, 6.0), step, end=6.0)
    summary = scenario_units.criticality(extremes.summary([7]), "Metric")
    assert summary["min_distance"] == pytest.approx(10.0, abs=1e-6)
    assert summary["min_distance_time_s"] == pytest.approx(10 / 3, abs=1e-6)
    assert summary["min_ttc_s"] == pytest.approx(math.sqrt(20 / 6), abs=1e-6)
    assert summary["min_ttc_time_s"] == pytest.approx((20 - math.sqrt(120)) / 6, abs=1e-6)
    assert summary["max_drac"] == pytest.approx(400 / (2 * g0), rel=1e-12)
    assert summary["max_drac_time_s"] == 0.0
    assert summary["min_headway_s"] == pytest.approx(math.sqrt(20 / 6), abs=1e-6)
    assert summary["min_headway_time_s"] == pytest.approx((20 - math.sqrt(120)) / 6, abs=1e-6)
    assert summary["vehicles"][0]["vehicle"] == 7 and not summary["contact"]


@pytest.mark.parametrize("step", STEPS)
def test_time_headway_minimum_to_a_slower_car_ahead_whatever_the_step(step):
    # The ego slows from 15 m/s at 1 m/s2 behind a car at 10 m/s the same way, bumper gap g0 = 20 m:
    # v = 15 - t, g = 20 - (5 t - t^2 / 2). Headway h = g / v, h' = (g' v - g v') / v^2 = 0 where
    # g = v (v - 10): 20 - 5 t + t^2 / 2 = (15 - t)(5 - t), i.e. t^2 / 2 - 15 t + 55 = 0,
    # t = 15 - sqrt(115) = 4.27620 s, v = sqrt(115), h = g / v = v - 10 = 0.72381 s.
    traffic = traffic_of((0.0, 20.0 + 4.55, 0.0, -10.0, 0.0, -10.0, 0.0))
    extremes = master_like_run(traffic, braking(15.0, 1.0), step, end=8.0)
    summary = extremes.summary([1])
    assert summary["min_headway_s"] == pytest.approx(math.sqrt(115) - 10, abs=1e-6)
    assert summary["min_headway_time_s"] == pytest.approx(15 - math.sqrt(115), abs=1e-6)


def test_headway_rate_is_the_derivative_along_the_motion():
    # headway g / v of a car ahead along a motion with the ego braking and turning slightly; the central
    # difference with h = 1e-5 s errs by h^2 (third derivative) / 6 + eps |headway| / h, < 1e-9 here:
    # compared to 1e-7
    h = 1e-5
    for psi0, yaw_rate, brake in ((0.0, 0.0, 1.0), (0.05, 0.1, 3.0), (-0.1, -0.2, 0.5)):
        def at(t, psi0=psi0, yaw_rate=yaw_rate, brake=brake):
            return (Footprint.of(EGO_LENGTH, EGO_WIDTH, psi0 + yaw_rate * t),
                    30.0 + 12 * t - (20 * t - brake * t * t / 2), 0.3, 20 - brake * t, 12.0)
        values = [headway(*at(t), CAR_LENGTH, CAR_WIDTH) for t in (-h, h)]
        ego, dx, dy, v, lead = at(0.0)
        rate = headway_rate(ego, dx, dy, v, lead, -brake, yaw_rate, CAR_LENGTH, CAR_WIDTH)
        assert rate == pytest.approx((values[1] - values[0]) / (2 * h), abs=1e-7)


def test_post_encroachment_time_recorded_when_the_ego_reaches_the_conflict_station():
    # The crossing of test_post_encroachment_time_... above: the car leaves the ego's lane at 6.5 s standing
    # at station 135; the ego at 15 m/s reaches 132.75 with its front at t = 8.69667 s: PET 2.19667 s.
    extremes = Extremes(EGO_LENGTH, EGO_WIDTH)
    ego = cruising(15.0)
    extremes.path_left(0, 6.5, 135.0, CAR_LENGTH, ego(6.5).x + EGO_LENGTH / 2)
    assert extremes.pending_stations().tolist() == [132.75]
    reaches = (132.75 - EGO_LENGTH / 2) / 15
    extremes.reach(ego(reaches - 1e-3))
    assert extremes.pending_stations().tolist() == [132.75]
    extremes.reach(ego(reaches))
    assert len(extremes.pending_stations()) == 0
    summary = extremes.summary([3])
    assert summary["min_pet_s"] == pytest.approx(reaches - 6.5, abs=1e-12)
    # the ego already past the area's near end when the car left: they were there together, no PET
    extremes.path_left(1, 6.5, 100.0, CAR_LENGTH, ego(6.5).x + EGO_LENGTH / 2)
    assert len(extremes.pending_stations()) == 0


def test_record_of_a_few_vehicles_in_plain_floats_equals_the_array_form_bit_for_bit():
    # Extremes.observe takes up to SCALAR_VEHICLES vehicles one by one in plain floats, more at once in
    # arrays: both must record the same bits. The same 4 vehicles observed alone (floats) and among 12
    # (arrays), in every phase of a transition.
    rng = np.random.default_rng(23)
    rows = [(rng.uniform(0, 2), rng.uniform(-40, 80), rng.uniform(-5, 5), rng.uniform(-30, 30),
             rng.uniform(-5, 5), rng.uniform(-30, 30), rng.choice([0.0, 1.5, 4.0])) for _ in range(12)]
    traffic = traffic_of(*rows)
    few, many = Extremes(EGO_LENGTH, EGO_WIDTH), Extremes(EGO_LENGTH, EGO_WIDTH)
    for t in np.linspace(2, 8, 61):
        state = State(float(t), 20 * t, rng.uniform(-1, 1), rng.uniform(-0.2, 0.2), rng.uniform(5, 30),
                      rng.uniform(-1, 1), rng.uniform(-5, 5), rng.uniform(-3, 3), rng.uniform(-0.3, 0.3))
        few.observe(traffic, np.arange(4), state)
        many.observe(traffic, np.arange(12), state)
    for name in few.value:
        assert np.array_equal(few.value[name][:4], many.value[name][:4], equal_nan=True), name
        assert np.array_equal(few.time[name][:4], many.time[name][:4], equal_nan=True), name
    assert np.isfinite(many.value["min_ttc"]).sum() >= 2  # collision courses among them


def test_horizons_plain_float_forms_equal_the_array_forms_bit_for_bit():
    rng = np.random.default_rng(29)
    n = 5000
    d = mix(rng, rng.uniform(0, 100, n), rng.uniform(0, 1, n), np.zeros(n))
    frozen = mix(rng, rng.uniform(-50, 50, n), np.zeros(n), rng.uniform(-3, 0, n))
    floor = d * rng.uniform(0, 1.2, n)
    speed = np.abs(frozen) + rng.uniform(0, 10, n)
    acceleration = rng.uniform(5, 30, n)
    turn, yaw_rate_bound = 2.5, 1.1
    assert np.array_equal(distance_horizons(d, frozen, floor, turn, acceleration),
                          [distance_horizon(*row, turn, a) for row, a in zip(zip(d.tolist(), frozen.tolist(),
                                                                                  floor.tolist()), acceleration)])
    expected = approach_horizons(d, frozen, speed, turn, acceleration, yaw_rate_bound)
    assert np.array_equal(expected, [approach_horizon(x, f, v, turn, float(a), yaw_rate_bound)
                                     for x, f, v, a in zip(d.tolist(), frozen.tolist(), speed.tolist(), acceleration)])
    assert (expected > 0).sum() > 500  # approaching: a positive bound (about 700 of the 5000 cases)


def test_looks_at_horizons_skip_far_vehicles_and_never_pass_a_new_minimum():
    # An oncoming car in the next lane 400 m ahead, closing at 45 m/s: it comes within RANGE (50 m) of the
    # ego's footprint no earlier than the horizon says, and a master that looks at the vehicle only at its
    # horizons (Extremes.look; at every communication point within RANGE) records the same minimum distance
    # and instant as one that offers every communication point (Extremes.observe), with far fewer looks.
    traffic = traffic_of((0.0, 400.0, -LANE, 20.0, -LANE, 20.0, 0.0))
    ego = cruising(25.0)
    acceleration, yaw_rate_bound = 15.0, 1.0
    radius = math.hypot(EGO_LENGTH / 2, EGO_WIDTH / 2)
    extremes = Extremes(EGO_LENGTH, EGO_WIDTH)
    extremes.observe(traffic, traffic.active, ego(0.0))
    first = extremes.look(traffic, 0, ego(0.0), acceleration, yaw_rate_bound, radius)[1]
    # beyond RANGE until the lengthwise corner distance hypot(400 - 45 t - 4.55, 1.8) is 50 m: t > 7.776 s
    assert 0 < first < (400 - 4.55 - math.sqrt(50**2 - 1.8**2)) / 45
    assert distance(Footprint.of(EGO_LENGTH, EGO_WIDTH, 0.0), *oncoming(first, gap0=400.0)[:2], CAR_LENGTH,
                    CAR_WIDTH) > RANGE
    looks, next_look, previous = 0, 0.0, None
    for t in np.round(np.arange(0, 12, 0.05), 12):
        state = ego(t)
        rate = extremes.rates(traffic, 0, state)[0]
        if t >= next_look:
            looks += 1
            if previous is not None and previous[1] < 0 <= rate:
                located = bisect_root(lambda p: extremes.rates(traffic, 0, ego(p))[0], previous[0], t)
                extremes.observe(traffic, traffic.active, ego(located))
            next_look = t + extremes.look(traffic, 0, state, acceleration, yaw_rate_bound, radius)[1]
            previous = (t, rate)
    every = master_like_run(traffic, ego, 0.05, end=12.0)
    assert extremes.value["min_distance"][0] == every.value["min_distance"][0]
    assert extremes.time["min_distance"][0] == pytest.approx(every.time["min_distance"][0], abs=1e-8)
    assert extremes.time["min_distance"][0] == pytest.approx((400 - 4.55) / 45, abs=1e-8)
    assert looks < 240 / 2  # of 240 communication points


def test_a_look_offers_what_observe_offers_and_returns_the_rates():
    # Extremes.look (the master's one-pass path) against Extremes.observe and the rates from the measures'
    # own functions: the same bits, within and beyond RANGE, on and off a collision course.
    rng = np.random.default_rng(31)
    rows = [(rng.uniform(0, 2), rng.uniform(-40, 150), rng.uniform(-5, 5), rng.uniform(-30, 30),
             rng.uniform(-5, 5), rng.uniform(-30, 30), rng.choice([0.0, 1.5, 4.0])) for _ in range(40)]
    traffic = traffic_of(*rows)
    looked, observed = Extremes(EGO_LENGTH, EGO_WIDTH), Extremes(EGO_LENGTH, EGO_WIDTH)
    courses = 0
    for t in np.linspace(2, 8, 31):
        state = State(float(t), 20 * t, rng.uniform(-1, 1), rng.uniform(-0.2, 0.2), rng.uniform(5, 30),
                      rng.uniform(-1, 1), rng.uniform(-5, 5), rng.uniform(-3, 3), rng.uniform(-0.3, 0.3))
        for i in range(traffic.size):
            rates, _ = looked.look(traffic, i, state, 15.0, 1.0, 2.5)
            observed.observe(traffic, np.array([i]), state)
            ego, dx, dy, vx, vy, ax, ay, length, width = relative_motion(traffic, i, state, EGO_LENGTH, EGO_WIDTH)
            assert rates[0] == distance_rate(ego, dx, dy, vx, vy, state.yaw_rate, length, width)
            if distance(ego, dx, dy, length, width) <= RANGE and 0 < ttc(ego, dx, dy, vx, vy, length, width) < math.inf:
                assert rates[1] == ttc_rate(ego, dx, dy, vx, vy, ax, ay, state.yaw_rate, length, width)
                assert rates[2] == -drac_rate(ego, dx, dy, vx, vy, ax, ay, state.yaw_rate, length, width)
                courses += 1
            else:
                assert math.isnan(rates[1]) and math.isnan(rates[2])
    for name in looked.value:
        assert np.array_equal(looked.value[name], observed.value[name], equal_nan=True), name
        assert np.array_equal(looked.time[name], observed.time[name], equal_nan=True), name
    assert courses > 20


def test_a_course_check_sees_a_course_or_a_headway_exactly_where_a_look_does():
    # Between looks the follower only checks (Extremes.course_check) whether a collision course or a headway has
    # begun within RANGE: it must say so exactly where a look's rates do (TTC's or the headway's rate defined), and
    # elsewhere give a bound >= 0 (course_horizon's, tested above, or the time to come within RANGE).
    rng = np.random.default_rng(37)
    rows = [(rng.uniform(0, 2), rng.uniform(-40, 150), rng.choice([rng.uniform(-5, 5), 0.0]), rng.uniform(-30, 30),
             rng.uniform(-5, 5), rng.uniform(-30, 30), rng.choice([0.0, 1.5, 4.0])) for _ in range(40)]
    traffic = traffic_of(*rows)
    extremes = Extremes(EGO_LENGTH, EGO_WIDTH)
    seen = {True: 0, False: 0}
    for t in np.linspace(2, 8, 31):
        state = State(float(t), 20 * t, rng.uniform(-1, 1), rng.uniform(-0.2, 0.2), rng.uniform(5, 30),
                      rng.uniform(-1, 1), rng.uniform(-5, 5), rng.uniform(-3, 3), rng.uniform(-0.3, 0.3))
        for i in range(traffic.size):
            rates, _ = extremes.look(traffic, i, state, 15.0, 1.0, 2.5)
            followed = rates[1] == rates[1] or rates[3] == rates[3]
            bound = extremes.course_check(traffic, i, state, 15.0, 1.0, 2.5)
            assert math.isnan(bound) == followed, (t, i, rates, bound)
            assert followed or bound >= 0.0
            seen[followed] += 1
    assert seen[True] > 50 and seen[False] > 500


@pytest.mark.parametrize("step", STEPS)
def test_smallest_ttc_at_the_end_of_a_collision_course_whatever_the_step(step):
    # The ego at 20 m/s on lateral 0; a 4.5 x 1.8 car standing with its centre 30.55 m ahead (bumper gap 26 m)
    # and 2.5 m to the right, moving toward the ego's lane at 1 m/s for 0.63 s (to lateral 1.87), then
    # holding. The footprints overlap sideways while |lateral| < 1.8. Under constant velocities, from t:
    # sideways overlap after 2.5 - t - 1.8 = 0.7 - t s, lengthwise contact after (26 - 20 t) / 20 = 1.3 - t s,
    # later: a collision course with TTC = 1.3 - t. At t = 0.63 the car stops 0.07 m outside the ego's width:
    # the course ends. The smallest TTC is its value then, 0.67 s at 0.63 s (no communication point), and
    # DRAC = |v_rel| / (2 TTC) with v_rel = (-20, -1) is largest there: sqrt(401) / 1.34.
    traffic = traffic_of((0.0, 26.0 + 4.55, 2.5, 0.0, 1.87, 0.0, 0.63))
    extremes = master_like_run(traffic, cruising(20.0), step, end=2.0)
    summary = extremes.summary([1])
    assert summary["min_ttc_s"] == pytest.approx(0.67, abs=1e-6)
    assert summary["min_ttc_time_s"] == pytest.approx(0.63, abs=1e-6)
    assert summary["max_drac"] == pytest.approx(math.sqrt(401) / 1.34, rel=1e-6)
    assert summary["max_drac_time_s"] == pytest.approx(0.63, abs=1e-6)
