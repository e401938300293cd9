"""The shipped scenarios, vehicle table, tire files (tires/) and vehicle maps (vehicles/): data, installed as the
package sdl_fmu.scenarios (pyproject.toml) and read through sdl_fmu/paths.py."""
