"""The scenario as a co-simulation unit, in an SSP (docs/export.md): document.py writes SSP 1.0 archives in the
portable subset, system.py connects the scenario FMU and the ego FMU through the vehicle map, folder.py writes the
export folder."""
