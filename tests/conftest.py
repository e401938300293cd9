"""Shared fixtures: the real FMUs, built once per test session into a temporary folder."""

import pytest

from sdl_fmu.fmu.package import build_fmu


@pytest.fixture(scope="session")
def simple_fmu(tmp_path_factory):
    return build_fmu("simple", tmp_path_factory.mktemp("dist"))


@pytest.fixture(scope="session")
def advanced_fmu(tmp_path_factory):
    return build_fmu("advanced", tmp_path_factory.mktemp("dist"))


@pytest.fixture(scope="session")
def defaults_simple(simple_fmu):
    from fmpy import read_model_description

    return {v.name: float(v.start) for v in read_model_description(str(simple_fmu)).modelVariables
            if v.causality == "parameter"}
