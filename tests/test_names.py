"""The names every stage shares (sdl_fmu/names.py): the shipped models are registered there once, and every other
module takes them from there."""

import ast
import importlib
import tomllib
from pathlib import Path
from typing import get_args

import sdl_fmu
from sdl_fmu import cli
from sdl_fmu.names import (BUILT, SHIPPED, SHIPPED_CONTROLLERS, SHIPPED_MODELS, WHEELS, Dynamics, equations_module,
                           shipped_controller_map_path, shipped_map_path)

PACKAGE = Path(sdl_fmu.__file__).parent


def test_each_shipped_model_is_a_name_a_model_a_module_and_a_map():
    assert SHIPPED == get_args(Dynamics) == tuple(SHIPPED_MODELS) == ("simple", "advanced")
    for name in SHIPPED:
        assert importlib.import_module(equations_module(name)).MODEL_NAME == SHIPPED_MODELS[name]
        assert tomllib.loads(shipped_map_path(name).read_text())["name"] == name
    assert BUILT == {**SHIPPED_MODELS, **SHIPPED_CONTROLLERS}  # every FMU the cache builds
    for name, model in SHIPPED_CONTROLLERS.items():
        assert importlib.import_module(equations_module(name)).MODEL_NAME == model
        assert shipped_controller_map_path(name).is_file()
    choices = {action.dest: action.choices for action in cli.parser()._subparsers._group_actions[0].choices["run"]
               ._actions}
    assert tuple(choices["dynamics"]) == SHIPPED
    assert WHEELS == ("fl", "fr", "rl", "rr")


def test_no_other_module_spells_the_shipped_models():
    """A string literal naming a shipped model's or controller's FMU (EgoVehicleSimple, ExampleAeb), or the tuple of
    the shipped names, only in names.py: any other list of them would be a second registry."""
    model_names = set(BUILT.values())
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.name == "names.py" and path.parent == PACKAGE:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Constant) and node.value in model_names:
                found.append(f"{path.relative_to(PACKAGE)}:{node.lineno}: {node.value}")
            elif isinstance(node, (ast.Tuple, ast.List, ast.Set)) and {
                    getattr(element, "value", None) for element in node.elts} == set(SHIPPED):
                found.append(f"{path.relative_to(PACKAGE)}:{node.lineno}: a list of the shipped names")
    assert not found, "\n".join(found)
