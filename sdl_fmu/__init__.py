"""sdl-fmu: native vehicle-dynamics FMUs from CasADi, driven by STISIM-style SDL scenarios."""

__version__ = "0.1.0"
