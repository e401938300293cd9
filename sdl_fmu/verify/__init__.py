"""`sdl-fmu verify`: the vehicle test pack (docs/verification.md) and the Simple FMU's closed-form braking cases.

One module per job: drive (the sampled control loop), driver (path following), one module per manoeuvre
(braking, circular, step_steer, sine_with_dwell, split_mu, lane_change), pack (runs them, failures contained),
report (verify.json, CSVs, report.html, the table), closed_forms (the closed-form braking distances), quantities
(numbers rounded to their meaning with units), datasheet (the vehicle data sheet); the AEB car-to-car pack in aeb/.
"""

from .drive import ManoeuvreFailed
from .outcome import Outcome
from .pack import MANOEUVRES, run_manoeuvre, run_pack
from .report import passed, table, write

__all__ = ["MANOEUVRES", "ManoeuvreFailed", "Outcome", "passed", "run_manoeuvre", "run_pack", "table", "write"]
