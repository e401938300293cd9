"""The run side's vehicle: EgoModel (an FMU and its vehicle map, resolved once per run) and its instances.
Map format: docs/vehicle-maps.md."""

from .instance import STANDSTILL_SPEED, STOPPED_SPEED, EgoInstance, EgoState, FmuError
from .model import (DEFAULT_PEAK_FRICTION, VEHICLE_DEFAULTS, WHEELS, EgoModel, FrictionInput,
                    parameter_defaults, read_description, shipped_model)
from .vehicle_map import SHIPPED, Dynamics, VehicleMap, VehicleMapError, load_vehicle_map, shipped_map_path

__all__ = ["EgoModel", "EgoInstance", "EgoState", "FmuError", "VehicleMapError", "VehicleMap", "FrictionInput",
           "load_vehicle_map", "shipped_model", "shipped_map_path", "parameter_defaults", "read_description",
           "WHEELS", "SHIPPED",
           "Dynamics", "STANDSTILL_SPEED", "STOPPED_SPEED", "VEHICLE_DEFAULTS", "DEFAULT_PEAK_FRICTION"]
