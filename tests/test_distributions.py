"""The values a sweep varies (sdl_fmu/distributions.py, docs/sweeps.md): grids, uniform, integers, normal, choice and
Latin hypercubes, reproducible from --sample-seed, inside a declared parameter's range, counted before any is made."""

import math
from statistics import NormalDist

import pytest

from sdl_fmu import distributions
from sdl_fmu.distributions import SweepError, combinations, lhs_names, parse_vary, run_count
from sdl_fmu.sdl import parse_text

SCENARIO = parse_text("English\n// @param gap = 1000 ft in 500..3000\n// @param lateral = -6 ft in -9..-3\n"
                      "// @param model = 2 in 1..8\n// @param free = 50\n"
                      "100,A,$free,$gap,$lateral,$model\n", "p.sdl")

FORMS = ["gap=uniform(600,900,5)", "gap=uniform(5)", "gap=normal(1000,300,5)", "gap=choice(600,700,800,5)",
         "gap=lhs(5)", "gap=lhs(600,900,5)", "seed=integers(1,1000,5)", "free=normal(40,10,5)"]


@pytest.mark.parametrize("form", FORMS)
def test_each_distribution_is_reproducible_from_the_sample_seed_and_differs_with_another(form):
    first = parse_vary([form], sample_seed=7, scenario=SCENARIO)
    assert first == parse_vary([form], sample_seed=7, scenario=SCENARIO)
    assert first != parse_vary([form], sample_seed=8, scenario=SCENARIO)
    name = form.split("=")[0]
    assert len(first[name]) == 5 == distributions.value_count(name, form.split("=", 1)[1])
    if name == "gap":
        assert all(500 <= value <= 3000 for value in first[name])
    if form.startswith("gap=choice"):
        assert set(first[name]) <= {600.0, 700.0, 800.0}


def test_lhs_is_one_design_stratified_in_every_dimension():
    n = 16
    varied = parse_vary([f"gap=lhs({n})", f"lateral=lhs({n})", "speed=70,80"], sample_seed=3, scenario=SCENARIO)
    joint = lhs_names([f"gap=lhs({n})", f"lateral=lhs({n})", "speed=70,80"])
    assert joint == ["gap", "lateral"]
    for name, (low, high) in (("gap", (500, 3000)), ("lateral", (-9, -3))):
        strata = sorted(math.floor((value - low) / (high - low) * n) for value in varied[name])
        assert strata == list(range(n))  # exactly one sample in each of the n equal strata of each dimension
    # the hypercube's columns are zipped (one design of n points), then combined with the other values
    runs = combinations(varied, joint)
    assert len(runs) == run_count(varied, joint) == 2 * n
    assert [(run["gap"], run["lateral"]) for run in runs[::2]] == list(zip(varied["gap"], varied["lateral"]))
    assert [run["speed"] for run in runs[:2]] == [70.0, 80.0]
    with pytest.raises(SweepError, match="every lhs\\(\\) gives the same n \\(gap: 16, lateral: 8\\)"):
        parse_vary(["gap=lhs(16)", "lateral=lhs(8)"], scenario=SCENARIO)


def _truncated_moments(mu, sigma, low, high):
    """Mean and variance of the normal (mu, sigma) restricted to [low, high] (the closed forms: with alpha, beta the
    standardised ends and Z = Phi(beta) - Phi(alpha), mean = mu + sigma (phi(alpha) - phi(beta)) / Z and variance =
    sigma^2 [1 + (alpha phi(alpha) - beta phi(beta)) / Z - ((phi(alpha) - phi(beta)) / Z)^2])."""
    unit = NormalDist()
    alpha, beta = (low - mu) / sigma, (high - mu) / sigma
    z = unit.cdf(beta) - unit.cdf(alpha)
    ratio = (unit.pdf(alpha) - unit.pdf(beta)) / z
    return mu + sigma * ratio, sigma**2 * (1 + (alpha * unit.pdf(alpha) - beta * unit.pdf(beta)) / z - ratio**2)


@pytest.mark.parametrize("mu, sigma, declaration", [
    (600.0, 400.0, "500..3000"),  # 40 % of the untruncated draws fall below the range: clipping would pile them at 500
    (0.0, 1.0, "5..6"),  # the whole range in the far right tail (the mirrored branch)
])
def test_normal_is_truncated_to_the_declared_range_not_clipped(mu, sigma, declaration):
    low, high = map(float, declaration.split(".."))
    scenario = parse_text(f"// @param x = {low} in {declaration}\n100,A,50,1000,-6,1,$x,-6,50,1\n", "n.sdl")
    n = 4000
    values = parse_vary([f"x=normal({mu},{sigma},{n})"], sample_seed=11, scenario=scenario)["x"]
    assert all(low <= value <= high for value in values)
    assert not any(value in (low, high) for value in values)  # no mass at the ends: truncated, not clipped
    mean, variance = _truncated_moments(mu, sigma, low, high)
    # the sample mean of n independent draws has standard error sqrt(variance / n); 4 of them hold with probability
    # 1 - 6e-5 (and the draws are fixed by the sample seed, so the test cannot flake)
    assert abs(sum(values) / n - mean) < 4 * math.sqrt(variance / n)


def test_a_range_holding_no_probability_and_values_outside_the_range_are_refused():
    with pytest.raises(SweepError, match="the declared range 500..3000 of gap holds no probability"):
        parse_vary(["gap=normal(1e6,1,3)"], scenario=SCENARIO)
    with pytest.raises(SweepError, match=r"--vary gap=400,800: 400 is outside the declared range 500..3000 of gap"):
        parse_vary(["gap=400,800"], scenario=SCENARIO)
    with pytest.raises(SweepError, match="is outside the declared range 500..3000 of gap"):
        parse_vary(["gap=uniform(0,600,50)"], scenario=SCENARIO)
    with pytest.raises(SweepError, match=r"lhs\(n\) samples a declared range .* this name has none: give "
                                         r"lhs\(lo,hi,n\)"):
        parse_vary(["free=lhs(4)"], scenario=SCENARIO)
    # without a declared range, normal is the plain normal distribution
    plain = parse_vary(["free=normal(40,10,400)"], sample_seed=1, scenario=SCENARIO)["free"]
    assert min(plain) < 40 - 10 and max(plain) > 40 + 10


def test_a_parameter_that_only_whole_fields_use_draws_whole_numbers():
    assert [p.whole for p in SCENARIO.parameters] == [False, False, True, False]
    for form in ("model=uniform(20)", "model=lhs(8)", "model=normal(4,3,20)"):
        values = parse_vary([form], sample_seed=2, scenario=SCENARIO)["model"]
        assert all(value == int(value) and 1 <= value <= 8 for value in values), (form, values)


@pytest.mark.parametrize("text", ["gap=normal(1,0,3)", "gap=choice(4)", "gap=foo(1,2,3)", "gap=lhs(0)",
                                  "gap=uniform(1,2)", "gap=normal(1,inf,3)"])
def test_a_form_that_cannot_be_read_is_one_line(text):
    with pytest.raises(SweepError) as caught:
        parse_vary([text], scenario=SCENARIO)
    assert str(caught.value).startswith(f"--vary {text}: expected a,b,c or start:stop:step")
    assert "\n" not in str(caught.value)
