"""The values a sweep varies (`--vary NAME=VALUES`, docs/sweeps.md): grids and random designs, each counted from its
text before any value is made, reproducible from --sample-seed.

VALUES is `a,b,c`, a range `start:stop:step` (stop included), or n random values: `uniform(lo,hi,n)`,
`integers(lo,hi,n)`, `normal(mu,sigma,n)`, `choice(a,b,...,n)`, or a Latin hypercube `lhs(lo,hi,n)`. A scenario
parameter declared with a range (`// @param NAME = VALUE [UNIT] in LOW..HIGH`) also takes `uniform(n)` and `lhs(n)`
over it, its `normal` is truncated to it (drawn from the normal distribution restricted to the range, never clipped),
and every value given it must lie in it. The lhs() of one sweep form one design of n runs (every lhs() gives the same
n), whose columns are zipped, not combined: each dimension has exactly one value in each of its n equal strata. A
parameter that only whole fields use (a model, a lane) gets its continuous draws rounded to whole numbers."""

from __future__ import annotations

import itertools
import math
import random
import re
from statistics import NormalDist
from typing import Sequence

from .sdl import Parameter, Scenario
from .sdl.parameters import parameter_name, value_text
from .shipping import ClusterError

MAX_RUNS = 100_000  # runs of one sweep: the product of the varied values' counts (a Latin hypercube counts once)
MAX_VALUES_TEXT = 1_000_000  # characters of one --vary
FORMS = ("expected a,b,c or start:stop:step (finite numbers, step > 0, stop >= start) or uniform(lo,hi,n) / "
         "integers(lo,hi,n) (finite lo <= hi, whole n >= 1), normal(mu,sigma,n) (sigma > 0), choice(a,b,...,n), "
         "lhs(lo,hi,n); with a declared range also uniform(n), lhs(n)")
SAMPLES = ("uniform", "integers", "normal", "choice", "lhs")
_CALL = re.compile(r"([a-z]+)\((.*)\)", re.DOTALL)
_COUNT = re.compile(r"\+?[0-9]{1,20}")
RUN_OPTION_NAMES = ("speed", "seed", "until_distance", "until_time")  # api.VALUE_OPTIONS: never a scenario parameter


class SweepError(ClusterError):
    """A mistake in the sweep's arguments or output folder, or a cluster it cannot use (one line)."""


def finite_number(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError
    return value


def shown_assignment(name: str, text: str) -> str:
    assignment = f"{name}={text}"
    return assignment if len(assignment) <= 60 else f"{assignment[:45]}...{assignment[-10:]}"


def _call(text: str) -> tuple[str, list[str]] | None:
    """('uniform', ['0.2', '0.8', '4']) for a sample's text, else None."""
    match = _CALL.fullmatch(text.replace(" ", ""))
    if not match or match[1] not in SAMPLES:
        return None
    return match[1], match[2].split(",")


def _count(text: str) -> int:
    return int(text) if _COUNT.fullmatch(text) else -1


def value_count(name: str, text: str, parameter: Parameter | None = None) -> int:
    """How many values `text` gives, found without generating them (a,b,c: commas; a range: its arithmetic; samples:
    n); SweepError for a form that cannot be read, a non-finite bound, or more than MAX_RUNS."""
    shown = shown_assignment(name, text)
    if len(text) > MAX_VALUES_TEXT:
        raise SweepError(f"--vary {shown}: longer than {MAX_VALUES_TEXT} characters")
    sample = _call(text)
    try:
        if sample:
            kind, args = sample
            if kind == "choice":
                count = _count(args[-1]) if len(args) >= 2 else -1
                for value in args[:-1]:
                    finite_number(value)
            elif kind in ("uniform", "lhs") and len(args) == 1:
                count = _count(args[0])
            elif len(args) == 3:
                low, high, count = finite_number(args[0]), finite_number(args[1]), _count(args[2])
                if (kind == "normal" and not high > 0) or (kind != "normal" and high < low):
                    raise ValueError
            else:
                raise ValueError
            if count < 1:
                raise ValueError
        elif re.match(r"\s*[A-Za-z_]+\s*\(", text):  # a sample of another name
            raise ValueError
        elif ":" in text:
            start, stop, step = (finite_number(part) for part in text.split(":"))
            if step <= 0 or stop < start:
                raise ValueError
            count = math.floor((stop - start) / step + 1e-9) + 1  # finite operands: a finite float
        else:
            count = text.count(",") + 1
    except (ValueError, OverflowError):
        raise SweepError(f"--vary {shown}: {FORMS}") from None
    if count > MAX_RUNS:
        raise SweepError(f"--vary {shown}: {count:.6g} values, more than the {MAX_RUNS} runs a sweep may have")
    return int(count)


def declared(name: str, scenario: Scenario | None) -> Parameter | None:
    """The scenario's declared parameter that a --vary name sets (`NAME` or `$NAME`; a run option's name never is
    one), else None."""
    if scenario is None or name in RUN_OPTION_NAMES or name.startswith("param."):
        return None
    bare = parameter_name(name)
    return next((parameter for parameter in scenario.parameters if parameter.name == bare), None)


def _bounds(shown: str, kind: str, args: list[str], parameter: Parameter | None) -> tuple[float, float]:
    if len(args) == 3:
        return float(args[0]), float(args[1])
    if parameter is None or parameter.low is None:
        raise SweepError(f"--vary {shown}: {kind}(n) samples a declared range (// @param NAME = VALUE in LOW..HIGH); "
                         f"this name has none: give {kind}(lo,hi,n)")
    return parameter.low, parameter.high


def truncated_normal(rng: random.Random, mu: float, sigma: float, low: float, high: float) -> float:
    """One draw of the normal distribution (mu, sigma) restricted to [low, high], by inverting its distribution
    function over the range (no rejection loop; the range's far side mirrored so that small tails keep their
    precision). ValueError when the range holds no probability a double can express."""
    a, b = (low - mu) / sigma, (high - mu) / sigma
    flip = a > 0  # both ends right of the mean: draw from the mirrored range, whose Phi values are not near 1
    if flip:
        a, b = -b, -a
    unit = NormalDist()
    pa, pb = unit.cdf(a), unit.cdf(b)
    if not pb > pa:
        raise ValueError
    while True:
        u = pa + rng.random() * (pb - pa)
        if 0.0 < u < 1.0:
            break
    z = unit.inv_cdf(u)
    return min(max(mu + sigma * (-z if flip else z), low), high)


def parse_values(name: str, text: str, rng: random.Random, parameter: Parameter | None = None) -> list:
    """The values of one --vary (see the module docstring): finite values, at most MAX_RUNS (counted before any is
    made); seeds are whole numbers in 0 .. 2^63 - 1; a declared parameter's values lie in its declared range."""
    text = text.strip()
    shown = shown_assignment(name, text)
    count = value_count(name, text, parameter)
    sample = _call(text)
    continuous = False
    try:
        if sample:
            kind, args = sample
            if kind == "integers":
                low, high = float(args[0]), float(args[1])
                if low != int(low) or high != int(high):
                    raise SweepError(f"--vary {shown}: integers() takes whole bounds")
                values = [rng.randint(int(low), int(high)) for _ in range(count)]
            elif kind == "choice":
                options = [finite_number(value) for value in args[:-1]]
                values = [rng.choice(options) for _ in range(count)]
            elif kind == "normal":
                mu, sigma = float(args[0]), float(args[1])
                if parameter is not None and parameter.low is not None:
                    try:
                        values = [truncated_normal(rng, mu, sigma, parameter.low, parameter.high) for _ in range(count)]
                    except ValueError:
                        raise SweepError(f"--vary {shown}: the declared range {value_text(parameter.low)}.."
                                         f"{value_text(parameter.high)} of {parameter.name} holds no probability of "
                                         "this normal distribution") from None
                else:
                    values = [rng.gauss(mu, sigma) for _ in range(count)]
                continuous = True
            else:
                low, high = _bounds(shown, kind, args, parameter)
                if kind == "uniform":
                    values = [rng.uniform(low, high) for _ in range(count)]
                else:  # lhs: one value in each of the n equal strata, in a random order
                    strata = list(range(count))
                    rng.shuffle(strata)
                    values = [low + (stratum + rng.random()) / count * (high - low) for stratum in strata]
                    values = [min(value, high) for value in values]
                continuous = True
        elif ":" in text:
            start, stop, step = (float(part) for part in text.split(":"))
            values = [start + k * step for k in range(count)]
        else:
            values = [finite_number(part) for part in text.split(",")]
    except SweepError:
        raise
    except ValueError:
        raise SweepError(f"--vary {shown}: every value must be a finite number") from None
    if continuous and parameter is not None and parameter.whole:
        values = [float(math.floor(value + 0.5)) for value in values]
        if parameter.low is not None:
            values = [min(max(value, math.ceil(parameter.low)), math.floor(parameter.high)) for value in values]
    if not all(math.isfinite(value) for value in values):
        raise SweepError(f"--vary {shown}: every value must be a finite number")
    if parameter is not None and parameter.low is not None:
        outside = next((value for value in values if not parameter.low <= value <= parameter.high), None)
        if outside is not None:
            raise SweepError(f"--vary {shown}: {value_text(outside)} is outside the declared range "
                             f"{value_text(parameter.low)}..{value_text(parameter.high)} of {parameter.name} "
                             f"(line {parameter.line})")
    if name == "seed":
        from .options import LIMITS

        low, high = LIMITS["seed"]
        if any(v != int(v) or not low <= v <= high for v in values):
            raise SweepError(f"--vary {shown}: seeds are whole numbers from {low} to {high}")
        return [int(v) for v in values]
    return values


def lhs_names(assignments: Sequence[str]) -> list[str]:
    """The names whose VALUES are lhs(...): the columns of the one Latin hypercube, zipped (see combinations)."""
    names = []
    for assignment in assignments:
        name, _, text = assignment.partition("=")
        sample = _call(text.strip())
        if sample and sample[0] == "lhs":
            names.append(name.strip())
    return names


def run_count(varied: dict[str, list], joint: Sequence[str] = ()) -> int:
    """How many runs the values make: the product of the counts, the zipped names (`joint`) counting once."""
    counts = [len(values) for name, values in varied.items() if name not in joint]
    together = [len(varied[name]) for name in varied if name in joint]
    return math.prod(counts) * (together[0] if together else 1)


def parse_vary(assignments: list[str], sample_seed: int = 0, scenario: Scenario | None = None) -> dict[str, list]:
    """Every --vary NAME=VALUES, in order, drawn from one random.Random(sample_seed); `scenario`: the declared ranges
    and whole parameters. SweepError (one line) before any value is made for a form that cannot be read, a sweep of
    more than MAX_RUNS runs (counted before the next name's values are made), or lhs() of different n."""
    rng = random.Random(sample_seed)
    varied: dict[str, list] = {}
    joint = lhs_names(assignments)
    for assignment in assignments:
        name, separator, text = assignment.partition("=")
        name = name.strip()
        if not separator or not name or not text.strip():
            raise SweepError(f"--vary {assignment!r}: expected NAME=VALUES")
        if name in varied:
            raise SweepError(f"--vary {name} is given twice")
        if name in joint and varied.keys() & set(joint):
            first = next(other for other in varied if other in joint)
            count = value_count(name, text.strip())
            if count != len(varied[first]):
                raise SweepError(f"--vary {name}: the lhs() of one sweep are one Latin hypercube, so every lhs() "
                                 f"gives the same n ({first}: {len(varied[first])}, {name}: {count})")
        varied[name] = parse_values(name, text, rng, declared(name, scenario))
        runs = run_count(varied, joint)
        if runs > MAX_RUNS:  # checked before the next name's values are made, and before any combination
            shown = " x ".join(str(len(v)) for n, v in varied.items() if n not in joint or n == joint[0])
            raise SweepError(f"--vary: {shown} = {runs} runs, more than the {MAX_RUNS} a sweep may have")
    if not varied:
        raise SweepError("give at least one --vary NAME=VALUES")
    return varied


def combinations(varied: dict[str, list], joint: Sequence[str] = ()) -> list[dict]:
    """Every run's values, in run order: the product of the varied values (the last name fastest), the names in
    `joint` (a Latin hypercube's columns, each as long) zipped into one factor at the place of the first of them."""
    names = list(varied)
    factors = []
    for name in names:
        if name not in joint:
            factors.append([((name, value),) for value in varied[name]])
        elif name == next(n for n in names if n in joint):
            members = [n for n in names if n in joint]
            factors.append([tuple(zip(members, values)) for values in zip(*(varied[m] for m in members))])
    runs = []
    for parts in itertools.product(*factors):
        values = dict(pair for part in parts for pair in part)
        runs.append({name: values[name] for name in names})
    return runs
