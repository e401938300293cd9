"""The interface data each FMU's modelDescription.xml, C variable table and CasADi symbols are generated from
(<Model>.json, units.json): data, installed as the package sdl_fmu.modelDescription (pyproject.toml) and read
through sdl_fmu/paths.py."""
