"""Each FMI version's allowed states sit in one table of MASK_fmi2<Function> / MASK_fmi3<Function> lines
(sdl_fmu/fmu/runtime/fmi2Functions.c, fmi3Functions.c), and every FMI function that checks its state uses its
own line. The tables are compared here with the standard's state tables, written out below.

States of this runtime: I Instantiated, N Initialization Mode, E Event Mode, C Continuous-Time Mode (model
exchange), S Step Mode (co-simulation: FMI 2.0 "stepComplete"), T Terminated, X Error. States the runtime never
enters are left out of the expected sets: FMI 2.0 stepInProgress, stepFailed, stepCanceled (fmi2DoStep always
completes or fails into Error), FMI 3.0 Configuration, Reconfiguration, Step Discarded, Clock Activation and
Intermediate Update Mode (no structural parameters, no clocks, hasEventMode="false", no early return).
One mask serves both interface types: a function's model-exchange states (I N E C T X) and co-simulation states
(I N S T X) are united; functions of one interface type refuse the other type before the table is consulted."""

import pytest

from fmi_state_tables import FMI2, FMI2_DEVIATIONS, FMI3, FMI3_DEVIATIONS, mask_table


@pytest.mark.parametrize("version, expected, deviations", [(2, FMI2, FMI2_DEVIATIONS), (3, FMI3, FMI3_DEVIATIONS)],
                         ids=["fmi2", "fmi3"])
def test_state_table_is_the_standards(version, expected, deviations):
    table = mask_table(version)
    for function, states in {**expected, **deviations}.items():
        assert function in table, f"no MASK_fmi{version}{function} line"
        assert set(table[function]) == set(states), (function, table[function], states)
    if version == 2:  # FMI 2.0: every line is compared
        assert set(table) == set(expected) | set(deviations)
