"""Imports flow one way: the output stage (the package sdl_fmu/results/: the record, the files, the plot, the results
folder, the storage) never imports the run stage (sdl_fmu/cosim/, sdl_fmu/vehicle/), the run side's vehicle
(vehicle/) never imports the build side (dynamics/, fmu/), the low modules (paths, units, names, options, tire_files,
results/storage, lazy_sequence, hold) import nothing of the package but each other (storage's EventLog is a
lazy_sequence.LazySequence), the build side never reaches the tests' hold points (hold.py: the build side's code is an
input of the FMU cache's key), and no module of the package imports itself through a circle.

Read from the source with `ast`, so every import counts: at the top, inside a function, under TYPE_CHECKING."""

import ast
from pathlib import Path

import sdl_fmu

PACKAGE = Path(sdl_fmu.__file__).parent
OUTPUT_STAGE = ("sdl_fmu.results",)
LOW = ("sdl_fmu.paths", "sdl_fmu.units", "sdl_fmu.names", "sdl_fmu.options", "sdl_fmu.tire_files",
       "sdl_fmu.results.storage", "sdl_fmu.lazy_sequence", "sdl_fmu.hold")
RUN_STAGE = ("sdl_fmu.cosim", "sdl_fmu.vehicle")
BUILD_SIDE = ("sdl_fmu.dynamics", "sdl_fmu.fmu")


def modules(package: Path) -> dict[str, Path]:
    """Every module of the package by its dotted name (a package by its __init__.py)."""
    found = {}
    for path in sorted(package.rglob("*.py")):
        parts = path.relative_to(package.parent).with_suffix("").parts
        found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return found


def import_graph(package: Path) -> dict[str, set[str]]:
    """Module -> the modules of the same package it imports directly. `from .x import y` imports x.y when y is a
    module, else x."""
    known = modules(package)
    top = package.name
    graph = {}
    for name, path in known.items():
        here = name if path.name == "__init__.py" else name.rpartition(".")[0]
        imported = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                imported |= {alias.name for alias in node.names}
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    origin = here
                    for _ in range(node.level - 1):
                        origin = origin.rpartition(".")[0]
                    base = f"{origin}.{node.module}" if node.module else origin
                imported |= {f"{base}.{alias.name}" if f"{base}.{alias.name}" in known else base
                             for alias in node.names}
        graph[name] = {module for module in imported if module.split(".")[0] == top}
    return graph


def reached(graph: dict[str, set[str]], start: str) -> set[str]:
    """Every module that importing `start` runs: its imports, theirs, and the packages (__init__) around each."""
    seen, todo = set(), [start]
    while todo:
        module = todo.pop()
        if module in seen:
            continue
        seen.add(module)
        parents = [module.rsplit(".", depth)[0] for depth in range(1, module.count(".") + 1)]
        todo += [m for m in (*graph.get(module, ()), *parents) if m not in seen]
    return seen - {start}


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (or a module importing itself): Tarjan."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(module):
        index[module] = low[module] = len(index)
        stack.append(module)
        on_stack.add(module)
        for other in sorted(graph.get(module, ())):
            if other not in graph:
                continue
            if other not in index:
                visit(other)
                low[module] = min(low[module], low[other])
            elif other in on_stack:
                low[module] = min(low[module], index[other])
        if low[module] == index[module]:
            component = []
            while not component or component[-1] != module:
                component.append(stack.pop())
                on_stack.discard(component[-1])
            if len(component) > 1 or module in graph[module]:
                found.append(sorted(component))

    for module in sorted(graph):
        if module not in index:
            visit(module)
    return found


def inside(module: str, packages: tuple[str, ...]) -> bool:
    return any(module == package or module.startswith(package + ".") for package in packages)


def test_the_output_stage_never_imports_the_run_stage():
    graph = import_graph(PACKAGE)
    output = [module for module in graph if inside(module, OUTPUT_STAGE)]
    assert {f"sdl_fmu.results.{name}" for name in ("record", "files", "plots", "folder", "storage")} <= set(output)
    for module in output:
        assert not [m for m in reached(graph, module) if inside(m, RUN_STAGE)], module


def test_the_vehicle_never_imports_the_build_side():
    # building a shipped model's FMU on first use lives above both (sdl_fmu/shipped.py)
    graph = import_graph(PACKAGE)
    vehicle = [module for module in graph if inside(module, ("sdl_fmu.vehicle",))]
    assert len(vehicle) >= 4
    for module in vehicle:
        assert not [m for m in reached(graph, module) if inside(m, BUILD_SIDE)], module


def test_the_low_modules_import_nothing_of_the_package_but_each_other():
    graph = import_graph(PACKAGE)
    for module in LOW:
        assert graph[module] <= set(LOW) - {module}, module


def test_the_build_side_never_reaches_the_test_hook():
    # a hold point there, or in a build input, would change every FMU's cache key (fmu/cache.py)
    from sdl_fmu.fmu.cache import build_inputs

    graph = import_graph(PACKAGE)
    build = [module for module in graph if inside(module, BUILD_SIDE)]
    assert len(build) >= 4
    for module in build:
        assert "sdl_fmu.hold" not in reached(graph, module), module
    for dynamics in ("simple", "advanced", "example-aeb"):
        files = [file for path in build_inputs(dynamics).values() for file in ([path] if path.is_file() else
                                                                                path.rglob("*.py"))]
        assert len(files) >= 4 and not [file for file in files if file.name == "hold.py"]


def test_no_module_imports_itself_through_a_circle():
    assert circles(import_graph(PACKAGE)) == []


def test_the_import_reader_sees_every_kind_of_import(tmp_path):
    # the checks above pass on an empty graph too, so the reader is shown to find what they look for: a circle made
    # of a TYPE_CHECKING import and an import inside a function, and a run-stage import reached through a package
    package = tmp_path / "pkg"
    (package / "cosim").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "cosim" / "__init__.py").write_text("from .master import run\n")
    (package / "cosim" / "master.py").write_text("def run(): pass\n")
    (package / "results.py").write_text("def write():\n    from . import plots\n")
    (package / "plots.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                                      "    from .results import write\n")
    (package / "helpers.py").write_text("import pkg.cosim.master as master\n")
    (package / "output.py").write_text("from .helpers import master\n")
    graph = import_graph(package)
    assert graph["pkg.results"] == {"pkg.plots"} and graph["pkg.plots"] == {"pkg.results"}
    assert circles(graph) == [["pkg.plots", "pkg.results"]]
    assert {"pkg.cosim", "pkg.cosim.master"} <= reached(graph, "pkg.output")
    # and the real package's known edges are found
    real = import_graph(PACKAGE)
    assert "sdl_fmu.results.storage" in real["sdl_fmu.results.files"]
    assert "sdl_fmu.results.record" in real["sdl_fmu.results.plots"]
    assert "sdl_fmu.cosim.master" in real["sdl_fmu.api"]
