"""Python side of the EhsvActuator FMU: what the examples in cosim-examples and the tests
in tests/python share, one module for each concern.

* ``paths``: where the built archives are,
* ``contract``: the FMU's interface, read from its modelDescription.xml,
* ``fmu``: one instance through fmpy, values by name, the FMU's log captured,
* ``scenarios``: steps of the inputs run through the FMU, the paper's driver table and
  flow-loop comparison,
* ``measures``: settling time, time on a rail, PWM-period means, volume balance,
* ``bands``: the paper's figures and the bands the FMU must land in,
* ``reference``: numpy reference models (exact linear valve, cylinder through solve_ivp),
* ``report``: the tables printed by the examples, ``plotting``: figures to files,
  ``paper_plots``: the paper's figures redrawn from FMU runs,
* ``frequency``: frequency responses through the FMU and the analytic ones (eq. 3/eq. 4),
* ``valves``: the valve catalog (valves.toml: datasheet figures as start values) and the
  datasheet's figures measured back through the FMU,
* ``study``: parameter-study designs, scenarios and metrics; ``cluster``: many runs on
  dask.distributed (LocalCluster or a cluster by address) or in this process,
* ``bad_input``: the bad-input cases run in a child process.
* ``calibrate``: parameters, sensor offsets and delays fitted to a recording
  (``python -m ehsv.calibrate``, docs/calibration.md).
* ``cli``: what the example commands share (--fmi3, the archive check, out/, figure lines).

The names below are the package's public surface for the common runs (``import ehsv;
ehsv.run_step(...)``); the studies' modules are imported by name (``from ehsv import
frequency, study, cluster``).
Nothing here builds anything: the archives are made by ``cargo run --release -p
build-fmu`` (scripts/test.sh and scripts/demo.sh do it first).
"""

from .bad_input import BAD_INPUT_CASES, bad_input_case
from .bands import (
    FLOW_RATIO_MIN,
    FLOW_STEP,
    PAPER_DRIVERS,
    PAPER_FLOW,
    PAPER_FLOW_RATIO,
    PAPER_STEP,
    PAPER_T_TORQUE,
    PAPER_TOLERANCE,
    ROWS,
    PaperDriver,
    PaperFlowRun,
)
from .contract import (
    CONTROL_MODES,
    DRIVERS,
    ENUMERATIONS,
    INPUTS,
    NOMINAL,
    OUTPUTS,
    PWM_DRIVERS,
    SOLVER_METHODS,
    enumeration_value,
    flow_gain,
    interface,
    method_params,
    parameters,
)
from .fmu import Ehsv, LogRecord
from .measures import period_average, pwm_period, settling_time, time_at_rail, volume_balance
from .paths import FMU_DIR, REPO, VERSIONS, fmu_path, missing_fmu_message, require_fmu
from .plotting import pyplot, save_figure
from .reference import (
    Cylinder,
    augmented_linear_model,
    cylinder_derivatives,
    cylinder_reference,
    cylinder_solve,
    expm,
    impact_estimate,
    linear_model,
    linear_step_response,
    linear_step_response_dense,
)
from .report import driver_table, flow_table
from .scenarios import (
    COMPARE_H,
    COMPARE_T_STOP,
    DEFAULT_OUTPUTS,
    FLOW_H,
    FLOW_T_STOP,
    HYDRAULIC_OUTPUTS,
    DriverResult,
    FlowStepResult,
    compare_drivers,
    compare_flow_supplies,
    driver_step,
    flow_step,
    run_scenario,
    run_step,
)

__all__ = [name for name in dir() if not name.startswith("_")]
