"""The run side's vehicle: EgoModel (an FMU and its vehicle map, resolved once per run) and its instances.
Map format: docs/vehicle-maps.md. Nothing here imports the build side (dynamics/, fmu/): a shipped model's FMU is
built on first use above both (sdl_fmu/shipped.py)."""

from .instance import STANDSTILL_SPEED, STOPPED_SPEED, EgoInstance, EgoState, FmuError
from .model import (DEFAULT_PEAK_FRICTION, VEHICLE_DEFAULTS, EgoModel, FrictionInput, parameter_defaults,
                    read_description)
from .vehicle_map import Dynamics, VehicleMap, VehicleMapError, load_vehicle_map, shipped_map_path

__all__ = ["EgoModel", "EgoInstance", "EgoState", "FmuError", "VehicleMapError", "VehicleMap", "FrictionInput",
           "load_vehicle_map", "shipped_map_path", "parameter_defaults", "read_description",
           "Dynamics", "STANDSTILL_SPEED", "STOPPED_SPEED", "VEHICLE_DEFAULTS", "DEFAULT_PEAK_FRICTION"]
