"""The compiled engine's Python face: the C library (``c/vsj.h``) behind `_core`.

`Engine` pairs an `EngineModel` (the arrays `compile_model` makes) with the
C engine's checked copy of it and a work (its run-time state). Its methods
integrate (`dopri`, `timestep`), sample every internal signal (`observe`)
and evaluate energies and source signals. The binding checks every array it
hands to C; `Engine` adds no physics.

Solvers (C, see the sources for their derivations):

``dopri``
    adaptive Dormand-Prince 5(4) with dense output (Hairer, Norsett and
    Wanner's DOPRI5), for friction laws that are functions of speed;
``timestep``
    fixed-step, velocity-level time stepping with exact Coulomb stiction:
    the impulses of all stiction elements decided jointly at each step.

Batches (`run_batch`) spread runs over threads; the C computations release
the GIL, every run is independent of the others, so results do not depend on
the number of threads.
"""

from __future__ import annotations

import itertools
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .. import _core
from .model import SIZES, EngineModel

OK = 0
NOT_FINITE = 1
PIVOT_RANGE = 2
TOO_MANY_STEPS = 3
STEP_TOO_SMALL = 4
FRICTION_SOLVER = 5

STATUS_TEXT = {code: _core.status_text(code) for code in range(8)}

#: Friction elements whose slip is below this speed [rad/s] count as stuck (c/timestep.c).
STUCK_SPEED = 1e-10
#: The time-stepper decides each stick/slip impulse to this fraction of the largest
#: free slip of its step (c/impulses.c).
IMPULSE_REL = 1e-12


def native(model: EngineModel) -> _core.Model:
    """The C engine's checked copy of ``model`` (raises ValueError if it is inconsistent)."""
    return _core.Model(np.array([model.sizes[k] for k in SIZES], dtype=np.int64),
                       model.arrays())


class Engine:
    """One model in the C engine, with a work for one computation at a time."""

    def __init__(self, model: EngineModel):
        self.model = model
        self.c = native(model)
        self.work = _core.Work(self.c)
        d = model.dims
        self.n, self.n_sources, self.n_frictions, self.n_springs = (int(v) for v in d[:4])
        self.n_loads, self.n_motors = int(d[4]), int(d[5])
        self.n_state = 2 * self.n + self.n_motors

    def dopri(self, y: np.ndarray, t0: float, t_end: float, t_out: np.ndarray, rtol: float,
              atol: float, h_max: float, max_steps: int, n_err: int, out: np.ndarray):
        """Integrate from ``t0`` to ``t_end``; ``y`` (state, optionally accumulators)
        is overwritten with the final state (the last good one on failure); the
        leading columns of ``out`` receive the state at each time of ``t_out``.
        Returns ``(status, t, steps, rejected)``."""
        return _core.dopri(self.c, self.work, y, t0, t_end, _floats(t_out), rtol, atol, h_max,
                           max_steps, n_err, out)

    def timestep(self, y: np.ndarray, duration: float, h: float, t_out: np.ndarray,
                 max_steps: int, ledger: bool, out: np.ndarray, coulomb=None, stuck=None):
        """Fixed steps ``h`` from 0 to ``duration``; ``y`` holds the state and, with
        ``ledger``, the accumulators, and receives the final values. Samples at
        ``t_out`` (multiples of ``h``) go to ``out`` (one row each; columns as
        many as fit); ``coulomb`` and ``stuck`` (rows of friction elements, or
        None) receive each stiction element's Coulomb torque and whether it held.
        Returns ``(status, t, steps, transitions)``, the last per element: starts
        and ends of stick phases (a phase starts when an element has held for
        two consecutive steps)."""
        transitions = np.zeros(self.n_frictions, dtype=np.int64)
        status, t, steps, _ = _core.timestep(self.c, self.work, y, duration, h, _floats(t_out),
                                             max_steps, ledger, out, coulomb, stuck, transitions)
        return status, t, steps, transitions

    def start(self, solver: str, y0: np.ndarray, duration: float, options) -> Run:
        """A run from ``y0`` (state and ledger accumulators) at t = 0 to ``duration``
        with ``solver`` (``"dopri"`` or ``"timestep"``) and the numerical settings of
        ``options`` (`vsj.simulate.SimulationOptions`), sampled by `Run.advance`."""
        return Run(self, solver, y0, duration, options)

    def observe(self, t_out: np.ndarray, out: np.ndarray, coulomb=None) -> np.ndarray:
        """Every internal signal at the samples (`vsj.engine.observation_layout` names
        the columns); ``out`` holds a state row per sample, ``coulomb`` the
        stiction elements' Coulomb torques."""
        t_out = _floats(t_out)
        raw = np.empty((len(t_out), _core.observation_width(self.c)))
        _core.observe(self.c, self.work, t_out, np.ascontiguousarray(out, dtype=float),
                      None if coulomb is None else np.ascontiguousarray(coulomb, dtype=float),
                      raw)
        return raw

    def source_signals(self, t_out: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Source angles and speeds at each time, shape (samples, sources) each."""
        t_out = _floats(t_out)
        angles = np.empty((len(t_out), self.n_sources))
        speeds = np.empty((len(t_out), self.n_sources))
        _core.source_signals(self.c, self.work, t_out, angles, speeds)
        return angles, speeds

    def source_speeds(self, t: float) -> np.ndarray:
        """Speeds of the velocity sources at ``t``."""
        return self.source_signals(np.array([float(t)]))[1][0]

    def stored_energy(self, t: float, y: np.ndarray) -> tuple[tuple[float, float, float],
                                                               np.ndarray]:
        """``((kinetic, springs, inductors), each spring's energy)`` [J] at ``(t, y)``."""
        springs = np.empty(self.n_springs)
        energy = _core.stored_energy(self.c, self.work, t,
                                     np.ascontiguousarray(y[:self.n_state], dtype=float), springs)
        return energy, springs

    def derivatives(self, t: float, y: np.ndarray) -> tuple[int, np.ndarray]:
        """``(status, dy/dt)`` at ``(t, y)``."""
        y = np.ascontiguousarray(y, dtype=float)
        dy = np.empty_like(y)
        return _core.derivatives(self.c, self.work, t, y, dy), dy


class Run:
    """A run of an `Engine` sampled block by block (`Engine.start`): each `advance`
    samples the next times; the engine's steps do not depend on how the samples are
    split into blocks. ``y`` is the state (and the ledger's accumulators) where the
    run stands, ``status`` its engine status, ``t`` the time reached."""

    def __init__(self, engine: "Engine", solver: str, y0: np.ndarray, duration: float,
                 options):
        self.engine, self.solver, self.duration = engine, solver, float(duration)
        self.kind = {"dopri": 0, "timestep": 1}[solver]
        self.options = options
        self.y = np.array(y0, dtype=float)
        self.t, self.steps, self.rejected = 0.0, 0, 0
        n_state = engine.n_state
        self.n_err = n_state if n_state else len(self.y)
        self.status = _core.begin(self.kind, engine.c, engine.work, self.y, 0.0, self.duration,
                                  options.rtol, options.atol, options.max_step,
                                  options.max_steps, self.n_err)

    def advance(self, times: np.ndarray, *, finish: bool):
        """The samples at ``times`` (after those of earlier calls): ``(states, coulomb,
        stuck)``, the state rows (NaN where the run did not reach), and for the
        time-stepper each friction element's Coulomb torque and whether it held.
        With ``finish`` the run continues to its duration (the ledger's end)."""
        times = _floats(times)
        f = self.engine.n_frictions
        out = np.full((len(times), len(self.y)), np.nan)
        coulomb = np.zeros((len(times), f))
        stuck = np.zeros((len(times), f), dtype=bool)
        if self.status != OK:
            return out, coulomb, stuck
        o = self.options
        if self.kind == 0:
            end = self.duration if finish or not len(times) else float(times[-1])
            report = _core.advance(0, self.engine.c, self.engine.work, self.y, end, times, out,
                                   None, None, finish, 1.0, 1, False)
        else:
            end = self.duration if finish or not len(times) else float(times[-1])
            report = _core.advance(1, self.engine.c, self.engine.work, self.y, end, times, out,
                                   coulomb, stuck, finish, o.step,
                                   max(1, o.max_steps - self.steps), True)
        self.status, self.t = int(report[0]), float(report[1])
        if self.kind == 0:
            self.steps, self.rejected = int(report[2]), int(report[3])
        else:
            self.steps += int(report[2])
        return out, coulomb, stuck

    def transitions(self) -> np.ndarray:
        """Starts and ends of stick phases per friction element (0 for dopri)."""
        counts = np.zeros(self.engine.n_frictions, dtype=np.int64)
        if self.kind == 1:
            _core.transitions(self.engine.c, self.engine.work, counts)
        return counts


def pivot_position(model: EngineModel, x: np.ndarray, sigma: np.ndarray) -> float:
    """Pivot position q [m] at generalised angles ``x`` and source angles ``sigma``
    (the pivot is the model's last row, `vsj.engine.model`)."""
    n = int(model.dims[0])
    row, par = model.rows[-1], model.par[-1]
    angle = row[:n] @ x + row[n:] @ sigma
    moving = par[2]
    return float(moving * par[0] * np.sin(angle) + (1.0 - moving) * par[1])


def run_batch(kind: str, engine: Engine, masses, Minvs, pars, src0s, y0s, t_end: float,
              t_out, *, rtol: float = 1e-8, atol: float = 1e-10, h_max: float = np.inf,
              max_steps: int = 10 ** 8, h: float = 1e-3, threads: int | None = None,
              progress=None):
    """Many runs of one model: run ``r`` with its own mass matrix, inverse,
    parameters, source angles and initial state (row ``r`` of each array),
    states sampled at ``t_out`` (no ledger). ``kind`` is ``"dopri"`` or
    ``"timestep"`` (step ``h``). Runs go to ``threads`` threads (default: every
    core) one at a time as they free up. ``progress``, if given, is called with
    the number of runs finished after each run.

    Returns ``(outs, y_end, status, t_stop, steps, transitions)``.
    """
    runs = len(y0s)
    t_out = _floats(t_out)
    code = {"dopri": 0, "timestep": 1}[kind]
    n_state = engine.n_state
    outs = np.full((runs, len(t_out), n_state), np.nan)
    y0s = np.ascontiguousarray(y0s, dtype=float)
    y_end = np.zeros_like(y0s)
    status = np.zeros(runs, dtype=np.int64)
    t_stop = np.zeros(runs)
    steps = np.zeros(runs, dtype=np.int64)
    transitions = np.zeros(runs, dtype=np.int64)
    masses, Minvs, pars, src0s = (np.ascontiguousarray(a, dtype=float)
                                  for a in (masses, Minvs, pars, src0s))
    counter = itertools.count()
    finished = itertools.count(1)

    def worker():
        work = _core.Work(engine.c)
        while (r := next(counter)) < runs:
            _core.batch_run(code, engine.c, work, r, masses, Minvs, pars, src0s, y0s, t_end,
                            t_out, rtol, atol, h_max, max_steps, h, outs, y_end, status,
                            t_stop, steps, transitions)
            done = next(finished)
            if progress is not None:
                progress(done)

    threads = max(1, min(threads or available_cores(), runs))
    if threads == 1:
        worker()
    else:
        with ThreadPoolExecutor(max_workers=threads) as pool:
            for future in [pool.submit(worker) for _ in range(threads)]:
                future.result()
    return outs, y_end, status, t_stop, steps, transitions


def available_cores() -> int:
    """Cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _floats(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=float)
