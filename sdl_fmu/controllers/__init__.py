"""Controllers shipped with sdl-fmu, built like the ego FMUs (CasADi equations, the project's C runtime): the
example AEB (example_aeb.py, its reference in example_aeb.md)."""
