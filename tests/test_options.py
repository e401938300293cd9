"""The run options' defaults and limits (sdl_fmu/options.py), defined once and used by the API, the command line and
the master; and the API and the command line import at their top, the heavy optional parts excepted."""

import ast
from pathlib import Path

import sdl_fmu
from sdl_fmu import api, cli, options
from sdl_fmu.cosim import master

PACKAGE = Path(sdl_fmu.__file__).parent
# (MAX_SPEED also names sdl/parser.py's bound on a scenario's speed fields, another quantity)
DEFINED_ONCE = ("MAX_TIME", "LIMITS", "DEFAULT_SPEED", "DEFAULT_STEP", "DEFAULT_DRIVER_PERIOD", "COMMAND_LINE_FLAGS")
# imported inside a function on purpose: only the commands that need them pay for them (matplotlib for a plot or the
# test packs' reports, CasADi and the compilers for a build or for an export's scenario FMU, tqdm for a bar, pandas
# for a DataFrame)
HEAVY = {"plots", "results.plots", "verify", "fmu.cache", "fmu.package", "export.scenario_fmu", "tqdm", "pandas"}


def heavy(module: str) -> bool:
    return module in HEAVY or module.startswith("verify.")


def assignments(name: str) -> list[str]:
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.Assign, ast.AnnAssign)):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                if any(isinstance(target, ast.Name) and target.id == name for target in targets):
                    found.append(str(path.relative_to(PACKAGE)))
    return found


def test_each_limit_and_default_is_defined_once_in_the_options_module():
    for name in DEFINED_ONCE:
        assert assignments(name) == ["options.py"], name
    assert master.MAX_TIME is options.MAX_TIME and api.LIMITS is options.LIMITS
    assert api.InputError is options.InputError


def local_imports(path: Path) -> list[str]:
    """The modules imported inside functions of a module (`from . import plots` is 'plots')."""
    found = []
    for function in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(function, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for node in ast.walk(function):
                if isinstance(node, ast.Import):
                    found += [alias.name for alias in node.names]
                elif isinstance(node, ast.ImportFrom):
                    found += [f"{node.module}" if node.module else alias.name for alias in node.names]
    return found


def test_the_api_and_the_command_line_import_at_their_top_but_the_heavy_parts():
    for module in (api, cli):
        assert [name for name in local_imports(Path(module.__file__)) if not heavy(name)] == [], module.__name__


def test_importing_the_api_and_the_command_line_loads_none_of_the_heavy_packages():
    # what a run with plot=False or `sdl-fmu check` needs is imported at the top; matplotlib (the plots), CasADi
    # (builds), Dask (sweeps), pandas, tqdm and pyarrow only when a command uses them (a fresh interpreter: this
    # test's own process has imported some of them already)
    import subprocess
    import sys

    heavy_packages = ["matplotlib", "casadi", "distributed", "dask", "pandas", "tqdm", "pyarrow"]
    code = ("import sys, sdl_fmu.api, sdl_fmu.cli; "
            f"print(sorted(name for name in {heavy_packages!r} if name in sys.modules))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                          cwd=Path(sdl_fmu.__file__).parents[1])
    assert done.stdout.strip() == "[]"
