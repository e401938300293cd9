"""Both FMUs as files: valid for fmpy, native (no Python, no CasADi), rebuildable from their sources."""

import subprocess
import zipfile

import pytest
from fmpy.model_description import read_build_description
from fmpy.validation import validate_fmu


@pytest.fixture(params=[("simple_fmu", "EgoVehicleSimple"), ("advanced_fmu", "EgoVehicleAdvanced")],
                ids=["simple", "advanced"])
def fmu(request):
    fixture, model = request.param
    return request.getfixturevalue(fixture), model


def test_fmu_validates(fmu):
    path, _ = fmu
    assert validate_fmu(str(path)) == []


def test_binary_links_no_python_or_casadi(fmu, tmp_path):
    path, model = fmu
    with zipfile.ZipFile(path) as archive:
        archive.extractall(tmp_path)
    linked = subprocess.run(["ldd", str(tmp_path / f"binaries/linux64/{model}.so")],
                            capture_output=True, text=True, check=True).stdout
    assert "python" not in linked.lower() and "casadi" not in linked.lower()
    configuration, = read_build_description(str(tmp_path), validate=True)  # against the FMI 3 schema
    assert configuration.modelIdentifier == model
