"""The compiled engine's Python face: the C library (``c/vsj.h``) behind `_core`.

`Engine` pairs an `EngineModel` (the arrays `compile_model` makes) with the
C engine's checked copy of it and a work (its run-time state). Its methods
evaluate: every internal signal (`observe`), energies, source signals and
derivatives. Runs go through `vsj.engine.plan` (one entry point,
``vsj._core.run``). The binding checks every array it hands to C; `Engine`
adds no physics.

Solvers (C, see the sources for their derivations):

``dopri``
    adaptive Dormand-Prince 5(4) with dense output (Hairer, Norsett and
    Wanner's DOPRI5), for friction laws that are functions of speed;
``rosenbrock``
    adaptive linearly implicit Rosenbrock 4(3) (Hairer and Wanner's RODAS4) with
    the model's analytic Jacobian, for the same laws where their steep slopes
    bound an explicit step (loose tolerances);
``timestep``
    fixed-step, velocity-level time stepping with exact Coulomb stiction:
    the impulses of all stiction elements decided jointly at each step.
"""

from __future__ import annotations

import ctypes
import os
import signal

import numpy as np

from .. import _core
from .model import SIZES, EngineModel, Layout

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

    def __init__(self, model: EngineModel, checked: _core.Model | None = None):
        self.model = model
        self.c = native(model) if checked is None else checked
        self.work = _core.Work(self.c)
        d = model.dims
        self.n, self.n_sources, self.n_frictions, self.n_springs = (int(v) for v in d[:4])
        self.n_loads, self.n_motors = int(d[4]), int(d[5])
        self.n_state = 2 * self.n + self.n_motors
        self.n_acc = Layout(self.n, self.n_sources, self.n_frictions, self.n_springs,
                            self.n_loads, self.n_motors).n_acc

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

    def jacobian(self, t: float, y: np.ndarray, *, ledger: bool = False
                 ) -> tuple[int, np.ndarray, np.ndarray]:
        """``(status, J, ft)``: the Jacobian of the derivatives at ``(t, y)`` in the state
        (``J[i, j] = d(dy_i/dt)/dy_j`` over the state's components j) and their partial
        derivative in time, as the ``rosenbrock`` scheme linearises. With ``ledger``,
        ``y`` carries the energy accumulators after the state and ``J`` and ``ft`` their
        rates' rows too. Raises `ValueError` for a ``y`` of another length."""
        ny = self.n_state + (self.n_acc if ledger else 0)
        if len(y) != ny:
            what = "the state and the energy accumulators" if ledger else "the state"
            raise ValueError(f"jacobian: y has {len(y)} values; expected {ny} ({what})")
        y = np.ascontiguousarray(y, dtype=float)
        jac = np.empty((ny, self.n_state))
        ft = np.empty(ny)
        return _core.jacobian(self.c, self.work, t, y, jac, ft), jac, ft


def pivot_position(model: EngineModel, x: np.ndarray, sigma: np.ndarray) -> float:
    """Pivot position q [m] at generalised angles ``x`` and source angles ``sigma``
    (the pivot is the model's last row, `vsj.engine.model`)."""
    n = int(model.dims[0])
    row, par = model.rows[-1], model.par[-1]
    angle = row[:n] @ x + row[n:] @ sigma
    moving = par[2]
    return float(moving * par[0] * np.sin(angle) + (1.0 - moving) * par[1])


def available_cores() -> int:
    """Cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


#: Linux's prctl option that signals a process when the thread that made it ends.
_PR_SET_PDEATHSIG = 1


def die_with_parent() -> None:
    """Have this process killed when the one that started it ends (Linux's parent-death
    signal; elsewhere nothing): a worker process whose run was killed outright does not
    stay behind. Only for a process started by a thread that lives as long as it should
    (the main thread of the process that made it, or a single-threaded one)."""
    try:
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
    except (OSError, AttributeError):  # not Linux: no such signal to ask for
        pass


def _floats(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=float)
