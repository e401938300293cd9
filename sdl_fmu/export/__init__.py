"""The SDL scenario as a co-simulation unit: the scenario FMU (a generic native binary, the scenario as data in its
resources/), written by `scenario_fmu.write_scenario_fmu` for `sdl-fmu export`."""
