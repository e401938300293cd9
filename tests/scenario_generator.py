"""A seeded generator of random SDL scenarios (A with actions, BRK of every threshold, RSA on lanes and shoulders,
sometimes ROAD and ES), for the tests that hold the scenario FMU's rules equal to `sdl-fmu run`'s beyond the shipped
examples. The same seed gives the same text."""

from __future__ import annotations

import random


def _pick(rng: random.Random, low: float, high: float, digits: int = 1) -> str:
    return f"{rng.uniform(low, high):.{digits}f}"


def random_scenario(seed: int) -> str:
    """The text of one scenario (English units): 3 to 12 events over about 3000 ft."""
    rng = random.Random(seed)
    lines = ["English", f"// generated scenario, seed {seed}"]
    lanes_right, lanes_left, width = 1, 1, 12.0
    if rng.random() < 0.4:
        lanes_right, lanes_left = rng.randint(1, 3), rng.randint(1, 3)
        width = rng.choice([10.0, 12.0, 14.0])
        lines.append(f"0,ROAD,{width:g},{lanes_right + lanes_left},{lanes_right}")
    lanes = [*range(1, lanes_right + 1), *range(-lanes_left, 0), 101, -101]
    distances = sorted(rng.uniform(0, 3000) for _ in range(rng.randint(3, 12)))
    for distance in distances:
        kind = rng.choices(["A", "BRK", "RSA"], [0.55, 0.2, 0.25])[0]
        at = f"{distance:.0f}"
        if kind == "A":
            speed = f"*{_pick(rng, -30, 30)}" if rng.random() < 0.3 else _pick(rng, -40, 90)
            gap = _pick(rng, 150, 2500, 0) if rng.random() < 0.8 else _pick(rng, -600, -100, 0)
            lane = rng.choice(lanes[:-2] or [1])
            lateral = (f"*{_pick(rng, -3, 3)}" if rng.random() < 0.3
                       else f"{(abs(lane) - 0.5) * width * (1 if lane > 0 else -1):g}")
            model = "*1~8" if rng.random() < 0.4 else str(rng.randint(1, 9))
            actions = []
            for _ in range(rng.choices([0, 1, 2, 3], [0.3, 0.3, 0.25, 0.15])[0]):
                closure = rng.uniform(1, 15) * (1 if rng.random() < 0.75 else -1)
                where = rng.choice(["", "", "F", "B"])
                new_lateral = f"*{_pick(rng, -2, 2)}" if rng.random() < 0.4 else _pick(rng, -20, 20)
                new_speed = f"*{_pick(rng, -20, 20)}" if rng.random() < 0.3 else _pick(rng, -30, 90)
                actions.append(f"{closure:.1f}{where},{new_lateral},{new_speed},{_pick(rng, 0.5, 4)}")
            lines.append(",".join([at, "A", speed, gap, lateral, model, *actions]))
        elif kind == "BRK":
            threshold = rng.randint(0, 3)
            magnitude = [_pick(rng, 0.3, 4), _pick(rng, 30, 400, 0), _pick(rng, 5, 70, 0),
                         _pick(rng, 5, 70, 0)][threshold]
            lines.append(f"{at},BRK,{rng.choice([25, 50, 75, 100])},{threshold},{magnitude}")
        else:
            settings = rng.sample(lanes, rng.randint(1, min(3, len(lanes))))
            lines.append(",".join([at, "RSA", *[f"{lane},{rng.randint(0, 10)}" for lane in settings]]))
    if rng.random() < 0.5:
        lines.append(f"{distances[-1] + rng.uniform(100, 800):.0f},ES")
    return "\n".join(lines) + "\n"
