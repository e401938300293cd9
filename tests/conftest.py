"""Shared fixtures: the real FMUs, built once per test session into a temporary per-user FMU cache."""

import os
import tempfile

import pytest

# Every test (and every sdl-fmu subprocess it starts) uses a private FMU cache, never the user's.
os.environ["SDL_FMU_CACHE"] = tempfile.mkdtemp(prefix="sdl-fmu-test-cache-")

from sdl_fmu.fmu.cache import cached_fmu  # noqa: E402


@pytest.fixture(scope="session")
def simple_fmu():
    return cached_fmu("simple")


@pytest.fixture(scope="session")
def advanced_fmu():
    return cached_fmu("advanced")


@pytest.fixture(scope="session")
def defaults_simple(simple_fmu):
    from fmpy import read_model_description

    return {v.name: float(v.start) for v in read_model_description(str(simple_fmu)).modelVariables
            if v.causality == "parameter"}


def pytest_unconfigure(config):
    import shutil

    shutil.rmtree(os.environ["SDL_FMU_CACHE"], ignore_errors=True)
