"""The output stage: what a run produced (record.RunRecord, in SI) and what is written from it: timeseries.csv and
summary.json (files.py) and plot.png (plots.py), into a results folder that never destroys what sdl-fmu did not
write (folder.py). The samples and the event log are kept in disk-backed storage (storage.py) while the run makes
them. The run stage (cosim/) makes the record; nothing here imports it."""

from .files import summary, timeseries_table, write_results
from .record import RunRecord, SurfaceSection, VehicleTrack, VehicleTracks

__all__ = ["RunRecord", "SurfaceSection", "VehicleTrack", "VehicleTracks", "summary", "timeseries_table",
           "write_results"]
