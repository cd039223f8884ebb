"""One entry point to simulate a network: `simulate`.

The model (a `vsj.network.Structure`), the solver (`vsj.engine`) and this
driver are separate: `simulate` compiles the structure with the run's inputs
and options, integrates, samples every signal on a uniform output grid, and
returns a `Result` that says whether the run succeeded, how, and where energy
went (`Result.ledger`).

Three solvers:

``dopri``
    adaptive Dormand-Prince 5(4), for friction laws that are functions of
    speed (viscous, arctan, sign, slope);
``rosenbrock``
    adaptive linearly implicit Rosenbrock 4(3) (RODAS4) with the model's
    Jacobian, for the same laws: stiff parts (the friction laws' steep slopes
    near zero speed, DC motors' armature circuits) bound an explicit step, not
    this one. On fig 4.15 it is the faster at tolerances of about 1e-4 and
    looser (tighter, dopri's higher order wins); with DC motors at any;
``timestep``
    fixed-step, linearly implicit, with exact Coulomb stiction impulses solved
    jointly for every element at each step (`vsj.engine.timestep`); required
    by the ``stiction`` law and usable with every other law.

``solver="auto"`` picks ``timestep`` when any element uses ``stiction``.

The package is laid out by job: `options` (how to run), `driver` (one run),
`signals` (naming the samples), `ledger` (the energy balance), `checks`
(judging a finished run), `batch` (many runs), `result` (what they return) and
`refine` (a run's contacts sampled again, finer, for their safety figures).
"""

from .batch import simulate_batch
from .checks import DIVERGED, INTO_STOP, judge, warnings_of
from .driver import (MemorySink, check_run_size, choose_solver, prepare, rigid_stops,
                     run_plan, sample_times, simulate)
from .ledger import ledger
from .options import LEDGER_TOLERANCE, RANGES, InitialState, SimulationOptions
from .result import BatchResult, Result
from .signals import SignalSpec, catalogue, collect, port_flows, state_names

__all__ = ["MemorySink", "SignalSpec", "catalogue", "sample_times", "BatchResult", "DIVERGED", "INTO_STOP", "InitialState", "LEDGER_TOLERANCE", "RANGES",
           "Result", "SimulationOptions", "check_run_size", "choose_solver", "collect", "judge",
           "ledger", "port_flows", "prepare", "rigid_stops", "run_plan", "simulate", "simulate_batch",
           "state_names", "warnings_of"]
