"""The `follow` driver (`--driver follow`): the lane driver (driver.py), whose speed is also limited by the lead
vehicle through Gipps' car-following law with its reaction time (docs/controllers.md, The follow driver).

Gipps, P. G. (1981). A behavioural car-following model for computer simulation. Transportation Research Part B
15(2), 105-111. Its braking term is the largest speed a driver may have a reaction time tau from now so that, if
the vehicle ahead brakes as hard as the driver believes it would (b^) and the driver brakes at b after tau, the
driver stops at least the margin behind where it stops:

    v(t + tau) = b tau + sqrt( b^2 tau^2 - b [ 2 (x_lead(t) - s_lead - x(t)) - v(t) tau - v_lead(t)^2 / b^ ] )

(b, b^ < 0; x_lead - s_lead - x is the bumper gap less the margin). Gipps' parameters, from the means of the
distributions his paper simulates with: tau = 2/3 s, b = -2 a = -3.4 m/s2 (a = 1.7 m/s2), b^ = min(-3.0,
(b - 3.0) / 2) = -3.2 m/s2; the margin at rest is 2.0 m (Gipps' effective vehicle size 6.5 m less a 4.5 m car).
Gipps' model decides once per reaction time, the speed changing linearly to the decided one: the driver decides at
the instants k x tau (the master steps to them), taking the lead-vehicle signals (cosim/signals.py) and its own
speed, and holds the acceleration (v(t + tau) - v(t)) / tau until the next decision. Gipps' free-road term is the
lane driver's speed control: the driver's acceleration demand is the smaller of the lane driver's and the law's
(`FollowDriver.pedals`), so without a vehicle ahead `follow` drives exactly as `lane`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..vehicle import STOPPED_SPEED, EgoState
from .driver import Driver
from .signals import Lead

REACTION_TIME = 2.0 / 3.0  # s, Gipps' tau: the interval between decisions and the time the decided speed takes
BRAKING = 3.4  # m/s2, -b: the hardest braking the driver wishes to use (Gipps: b = -2 a, a = 1.7 m/s2)
LEADER_BRAKING = 3.2  # m/s2, -b^: the leader's braking the driver expects (Gipps: min(-3.0, (b - 3.0) / 2))
STANDSTILL_GAP = 2.0  # m, the bumper gap the driver keeps at rest (Gipps' 6.5 m effective size less a 4.5 m car)
# at rest behind the vehicle ahead (the ego slower than STOPPED_SPEED, the law allowing less than HOLD_SPEED) the
# driver holds the brake at HOLD_BRAKE: the law's approach to rest is asymptotic, and a vehicle that would creep
# stays stopped; it drives off when the law allows HOLD_SPEED (the gap has grown ~7 cm beyond STANDSTILL_GAP, or the
# vehicle ahead moves)
HOLD_SPEED = 0.1  # m/s
HOLD_BRAKE = 0.3  # pedal


def safe_speed(v: float, gap: float, lead_speed: float) -> float:
    """Gipps' braking term (m/s, >= 0): the speed the driver may have REACTION_TIME from now, at speed v (m/s),
    `gap` (the bumper gap to the vehicle ahead, m) and `lead_speed` (its speed along the road, m/s; a vehicle coming
    toward the ego counts as stopped). 0 where the square root's argument is negative (closer than the law allows at
    any speed)."""
    tau, b, leader = REACTION_TIME, BRAKING, LEADER_BRAKING
    lead = lead_speed if lead_speed > 0.0 else 0.0
    argument = b * b * tau * tau + b * (2.0 * (gap - STANDSTILL_GAP) - v * tau + lead * lead / leader)
    if not argument > 0.0:
        return 0.0
    speed = -b * tau + math.sqrt(argument)
    return speed if speed > 0.0 else 0.0


def follow_acceleration(v: float, lead: Lead) -> float | None:
    """The acceleration (m/s2) the law asks for over the next REACTION_TIME: (safe speed - v) / tau; None without
    a vehicle ahead (no limit)."""
    if not lead.present:
        return None
    return (safe_speed(v, lead.gap, lead.speed) - v) / REACTION_TIME


@dataclass
class FollowDriver:
    """The lane driver with its speed limited by Gipps' law: `decide` at each decision instant (k x
    REACTION_TIME), `pedals`, `steer` and `update` at each driver sample, as the lane driver's."""

    lane: Driver
    acceleration: float | None = None  # m/s2, the law's, held since the last decision (None: no vehicle ahead)
    allowed: float = math.inf  # m/s, the law's safe speed at the last decision
    limiting: bool = False  # whether the law set the last pedals (then the lane driver's integral is held)

    def decide(self, state: EgoState, lead: Lead) -> bool:
        """A decision from the lead-vehicle signals at this state; whether it changes the pedals now (the law
        limited the last pedals or limits them from here): only then are they set between driver samples, so that
        while the law does not bind the driver is the lane driver, sample for sample."""
        self.acceleration = follow_acceleration(state.v, lead)
        self.allowed = safe_speed(state.v, lead.gap, lead.speed) if lead.present else math.inf
        return self.limiting or (self.acceleration is not None
                                 and self.lane.demand(state) > self.acceleration + self.lane.resistance(state.v))

    def steer(self, state: EgoState) -> float:
        return self.lane.steer(state)

    def pedals(self, state: EgoState) -> tuple[float, float]:
        """The lane driver's pedals, unless the law asks for less acceleration: then pedals for the law's
        (resistance fed forward, no coasting band), or the hold brake at rest behind the vehicle ahead."""
        lane, v = self.lane, state.v
        demand = lane.demand(state)
        acceleration = self.acceleration
        if acceleration is None or demand <= acceleration + lane.resistance(v):
            self.limiting = False
            return lane.pedals_for(demand, v)
        self.limiting = True
        if (state.stopped or v < STOPPED_SPEED) and self.allowed < HOLD_SPEED:
            return 0.0, HOLD_BRAKE
        return lane.pedals_for(acceleration + lane.resistance(v), v, deadband=False)

    def update(self, state: EgoState, h: float, throttle: float) -> None:
        """The lane driver's speed integral, not while the law limits the pedals (no wind-up while following)."""
        if not self.limiting:
            self.lane.update(state, h, throttle)

    def reset_integral(self) -> None:
        self.lane.reset_integral()
