"""The vehicle data sheet both test packs put in verify.json and report.html: the FMU's identity, mass and geometry,
drive and brakes, tires, as this run used them (the map's values and --param overrides), SI with units in the keys;
and what made the report (tool, version, date)."""

from __future__ import annotations

import datetime
import hashlib
from pathlib import Path

from .. import __version__

# FMU parameters shown under tires when the FMU has them (a linear-tire model's cornering stiffnesses)
TIRE_PARAMETERS = {"cornering_stiffness_front": "cornering_stiffness_front_N", "cornering_stiffness_rear":
                   "cornering_stiffness_rear_N"}
# Magic Formula coefficients shown per tire slot: the nominal load, and the peak friction at it, longitudinal
# |PDX1 LMUX| and lateral |PDY1 LMUY| (a coefficient times its scaling factor)
PEAK_FRICTION = {"peak_friction_longitudinal": ("PDX1", "LMUX"), "peak_friction_lateral": ("PDY1", "LMUY")}


def file_digest(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def fmu_identity(fmu_path: Path, description, map_path: Path | None, name: str) -> dict:
    """An FMU's identity: file, SHA-256, model name, GUID, FMI version, the tool that generated it, its map."""
    return {"name": name, "fmu": Path(fmu_path).name, "fmu_sha256": file_digest(Path(fmu_path)),
            "model_name": description.modelName, "guid": description.guid, "fmi_version": description.fmiVersion,
            "generation_tool": description.generationTool, "map": None if map_path is None else Path(map_path).name}


def datasheet(model, params: dict[str, float] | None = None) -> dict:
    """The data sheet of an EgoModel run with FMU start values `params` (SI)."""
    model = model.with_parameters(params) if params else model
    sheet = {"identity": fmu_identity(model.fmu_path, model.description, model.map_path, model.name),
             "mass_and_geometry": {"mass_kg": model.mass, "length_m": model.length, "width_m": model.width,
                                   "wheelbase_m": model.wheelbase, "cg_to_front_axle_m": model.cg_to_front,
                                   "cg_to_rear_axle_m": model.cg_to_rear, "track_front_m": model.track_front,
                                   "track_rear_m": model.track_rear},
             "drive_and_brakes": {"drive_accel_max_mps2": model.drive_accel_max,
                                  "drive_power_max_W": model.drive_power_max,
                                  "brake_decel_max_mps2": model.brake_decel_max,
                                  "rolling_resistance": model.rolling_resistance, "drag_area_m2": model.drag_area,
                                  "air_density_kgpm3": model.air_density},
             "tires": _tires(model), "parameters_set": dict(params or {})}
    if "yaw_inertia" in model.parameters:
        sheet["mass_and_geometry"]["yaw_inertia_kgm2"] = model.parameters["yaw_inertia"]
    return sheet


def _tires(model) -> dict:
    friction = model.friction
    tires: dict = {"friction_input": None if friction is None else friction.meaning}
    if friction is not None and friction.meaning == "mu":
        tires["friction_coefficient"] = model.wheel_values((model.default_surface,))[0]  # on the test surface
    for name, key in TIRE_PARAMETERS.items():
        if name in model.parameters:
            tires[key] = model.parameters[name]
    slots = model.tire_slot_numbers()
    if slots:
        from ..tire_files import default_attribute_file, read_attribute_file

        files = {entry.attribute: entry.tire_file.name for entry in read_attribute_file(default_attribute_file())}
        prefix = friction.tire_slots
        value = model.parameters.get
        tires["slots"] = [{"attribute": k, "file": files[k],
                           "nominal_load_N": value(prefix.format(slot=k) + "FNOMIN"),
                           **{key: abs(value(prefix.format(slot=k) + coefficient, 0.0)
                                       * value(prefix.format(slot=k) + scale, 1.0))
                              for key, (coefficient, scale) in PEAK_FRICTION.items()}}
                          for k in slots if k in files]
    return tires


def provenance() -> dict:
    """What made a report and when: the tool, its version, the date (UTC, to the second)."""
    now = datetime.datetime.now(datetime.timezone.utc).replace(microsecond=0)
    return {"tool": "sdl-fmu", "version": __version__, "date": now.isoformat()}
