"""Shared fixtures: the real FMUs, built once per test session into a temporary folder (FMI 2.0 and 3.0 of
each model from one code generation and one compilation of the model code)."""

import pytest

from sdl_fmu.fmu.package import FMI_VERSIONS, build_fmus


@pytest.fixture(scope="session")
def simple_fmus(tmp_path_factory):
    """{2: FMI 2.0 FMU, 3: FMI 3.0 FMU} of the Simple model."""
    return dict(zip(FMI_VERSIONS, build_fmus("simple", tmp_path_factory.mktemp("dist"), FMI_VERSIONS)))


@pytest.fixture(scope="session")
def advanced_fmus(tmp_path_factory):
    """{2: FMI 2.0 FMU, 3: FMI 3.0 FMU} of the Advanced model."""
    return dict(zip(FMI_VERSIONS, build_fmus("advanced", tmp_path_factory.mktemp("dist"), FMI_VERSIONS)))


@pytest.fixture(scope="session")
def simple_fmu(simple_fmus):
    return simple_fmus[2]


@pytest.fixture(scope="session")
def advanced_fmu(advanced_fmus):
    return advanced_fmus[2]


@pytest.fixture(scope="session")
def defaults_simple(simple_fmu):
    from fmpy import read_model_description

    return {v.name: float(v.start) for v in read_model_description(str(simple_fmu)).modelVariables
            if v.causality == "parameter"}
