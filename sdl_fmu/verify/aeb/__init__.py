"""`sdl-fmu verify --pack aeb-ccr`: the Euro NCAP AEB car-to-car rear tests (CCRs, CCRm, CCRb) with a controller in
the loop (docs/verification.md, The AEB car-to-car pack).

One module per job: protocol (the grid, the target, the scoring, with their sources), scenario (a test as a
generated scenario), outcome (a run's results and points), pack (runs the grid, on Dask or in this process, and says
how far it is), kept (the finished tests kept as they finish: an interrupted pack resumes), report (verify.json,
tests.csv, report.html, the printed table)."""

from .outcome import TestOutcome
from .pack import Progress, run_grid, run_test, totals
from .protocol import GROUPS, PROTOCOL, Test, grid
from .report import passed, table, write

__all__ = ["GROUPS", "PROTOCOL", "Progress", "Test", "TestOutcome", "grid", "passed", "run_grid", "run_test", "table",
           "totals", "write"]
