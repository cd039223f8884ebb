"""Minimum-time optimal control by direct collocation (Hermite-Simpson, SLSQP).

The trajectory is cut into ``N`` intervals of equal share of the free final time ``T``;
the states ``x`` and controls ``u`` at the ``N + 1`` nodes and ``T`` are the unknowns.
Between nodes the controls are linear and the states cubic (Hermite-Simpson in its
compressed form: the midpoint state is the cubic's, ``x_c = (x_k + x_k+1)/2 +
h T (f_k - f_k+1)/8``, and each interval must satisfy Simpson's rule, ``x_k+1 - x_k =
h T (f_k + 4 f_c + f_k+1)/6``), whose error is fourth order in the step (Betts,
*Practical Methods for Optimal Control*, 2010, section 4.6). Path constraints hold at
the nodes and at the intervals' midpoints; the boundary conditions are bounds on the
first and last nodes.

`solve` takes the dynamics as a function that returns ``f`` and its Jacobians, so the
constraints' Jacobian is exact and SLSQP (scipy.optimize, sequential quadratic
programming) gets it without finite differences. Every value is scaled by a typical
size before the optimiser sees it; the result is unscaled.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from collections.abc import Callable

import numpy as np
from scipy.optimize import minimize


@dataclass(frozen=True)
class Problem:
    """A minimum-time problem.

    ``dynamics(x, u)`` (arrays n x nx, n x nu) returns ``(f, A, B)``: n x nx, n x nx x nx,
    n x nx x nu (``A = df/dx``, ``B = df/du``). ``path(x, u)`` returns ``(c, Cx, Cu)``
    with ``c >= 0`` required at every node (n x nc, n x nc x nx, n x nc x nu), or None.
    ``x_bounds``, ``u_bounds``: (lo, hi) arrays per component over the whole motion;
    ``first``, ``last``: the boundary states (NaN leaves a component free); ``x_scale``,
    ``u_scale``: typical sizes; ``T_bounds`` [s] the final time's range."""

    dynamics: Callable
    nx: int
    nu: int
    x_bounds: tuple
    u_bounds: tuple
    first: np.ndarray
    last: np.ndarray
    x_scale: np.ndarray
    u_scale: np.ndarray
    T_bounds: tuple[float, float]
    path: Callable | None = None


@dataclass
class Solution:
    """A solved (or failed) problem: ``time`` [s] (N + 1 nodes), ``states`` and
    ``controls`` at the nodes, ``T`` [s], ``success`` and ``message`` (SLSQP's),
    ``iterations``, ``history`` (T after each iteration [s]) and ``constraint_violation``
    (the largest defect or path violation, scaled: 0 for a feasible trajectory)."""

    time: np.ndarray
    states: np.ndarray
    controls: np.ndarray
    T: float
    success: bool
    message: str
    iterations: int
    history: list = field(default_factory=list)
    constraint_violation: float = 0.0


class _Transcription:
    def __init__(self, problem: Problem, nodes: int, time_scale: float):
        self.p = problem
        self.N = int(nodes)
        self.nx, self.nu = problem.nx, problem.nu
        self.h = 1.0 / self.N
        self.sx = np.asarray(problem.x_scale, dtype=float)
        self.su = np.asarray(problem.u_scale, dtype=float)
        self.sT = float(time_scale)
        n1 = self.N + 1
        self.size = n1 * self.nx + n1 * self.nu + 1
        self.scale = np.concatenate([np.tile(self.sx, n1), np.tile(self.su, n1), [self.sT]])

    def unpack(self, y):
        z = y * self.scale
        n1 = self.N + 1
        X = z[:n1 * self.nx].reshape(n1, self.nx)
        U = z[n1 * self.nx:n1 * (self.nx + self.nu)].reshape(n1, self.nu)
        return X, U, z[-1]

    def pack(self, X, U, T):
        return np.concatenate([np.ravel(X), np.ravel(U), [T]]) / self.scale

    def columns(self):
        """Column index helpers: states of node k, controls of node k, T."""
        n1 = self.N + 1
        xs = np.arange(n1 * self.nx).reshape(n1, self.nx)
        us = n1 * self.nx + np.arange(n1 * self.nu).reshape(n1, self.nu)
        return xs, us, self.size - 1

    def defects(self, y):
        """Simpson defects (N x nx, scaled by the states' sizes) and their Jacobian."""
        X, U, T = self.unpack(y)
        f, A, B = self.p.dynamics(X, U)
        hT = self.h * T
        xc = (X[:-1] + X[1:]) / 2 + hT * (f[:-1] - f[1:]) / 8
        uc = (U[:-1] + U[1:]) / 2
        fc, Ac, Bc = self.p.dynamics(xc, uc)
        d = X[1:] - X[:-1] - hT * (f[:-1] + 4 * fc + f[1:]) / 6
        N, nx, nu = self.N, self.nx, self.nu
        eye = np.eye(nx)
        dxc_dxk = eye / 2 + hT / 8 * A[:-1]
        dxc_dxk1 = eye / 2 - hT / 8 * A[1:]
        dxc_duk = hT / 8 * B[:-1]
        dxc_duk1 = -hT / 8 * B[1:]
        dxc_dT = self.h * (f[:-1] - f[1:]) / 8
        AcX = lambda m: np.einsum("kij,kjl->kil", Ac, m)  # noqa: E731
        d_xk = -eye - hT / 6 * (A[:-1] + 4 * AcX(dxc_dxk))
        d_xk1 = eye - hT / 6 * (4 * AcX(dxc_dxk1) + A[1:])
        d_uk = -hT / 6 * (B[:-1] + 4 * (AcX(dxc_duk) + Bc / 2))
        d_uk1 = -hT / 6 * (B[1:] + 4 * (AcX(dxc_duk1) + Bc / 2))
        d_T = -self.h / 6 * (f[:-1] + 4 * fc + f[1:]) \
            - hT / 6 * 4 * np.einsum("kij,kj->ki", Ac, dxc_dT)
        J = np.zeros((N * nx, self.size))
        xs, us, tcol = self.columns()
        rows = np.arange(N * nx).reshape(N, nx)
        for k in range(N):
            r = rows[k]
            J[np.ix_(r, xs[k])] = d_xk[k]
            J[np.ix_(r, xs[k + 1])] = d_xk1[k]
            J[np.ix_(r, us[k])] = d_uk[k]
            J[np.ix_(r, us[k + 1])] = d_uk1[k]
            J[r, tcol] = d_T[k]
        J *= self.scale[None, :]
        return (d / self.sx).ravel(), J / np.tile(self.sx, N)[:, None]

    def path(self, y):
        """Path constraints at the nodes and at the intervals' midpoints (the cubic's
        state and the controls' mean there), with their Jacobian: on a bound held over an
        arc (a speed at its limit), midpoints leave the controls no room to ring between
        the nodes."""
        X, U, T = self.unpack(y)
        c, Cx, Cu = self.p.path(X, U)
        n1, nc = c.shape
        N, nx = self.N, self.nx
        f, A, B = self.p.dynamics(X, U)
        hT = self.h * T
        xc = (X[:-1] + X[1:]) / 2 + hT * (f[:-1] - f[1:]) / 8
        uc = (U[:-1] + U[1:]) / 2
        cm, Cxm, Cum = self.p.path(xc, uc)
        eye = np.eye(nx)
        # the midpoint state's dependence on both nodes and T (as in `defects`)
        blocks = {"xk": eye / 2 + hT / 8 * A[:-1], "xk1": eye / 2 - hT / 8 * A[1:],
                  "uk": hT / 8 * B[:-1], "uk1": -hT / 8 * B[1:]}
        dxc_dT = self.h * (f[:-1] - f[1:]) / 8
        J = np.zeros(((n1 + N) * nc, self.size))
        xs, us, tcol = self.columns()
        rows = np.arange(n1 * nc).reshape(n1, nc)
        for k in range(n1):
            J[np.ix_(rows[k], xs[k])] = Cx[k]
            J[np.ix_(rows[k], us[k])] = Cu[k]
        mid = n1 * nc + np.arange(N * nc).reshape(N, nc)
        for k in range(N):
            r = mid[k]
            J[np.ix_(r, xs[k])] = Cxm[k] @ blocks["xk"][k]
            J[np.ix_(r, xs[k + 1])] = Cxm[k] @ blocks["xk1"][k]
            J[np.ix_(r, us[k])] = Cxm[k] @ blocks["uk"][k] + Cum[k] / 2
            J[np.ix_(r, us[k + 1])] = Cxm[k] @ blocks["uk1"][k] + Cum[k] / 2
            J[r, tcol] = Cxm[k] @ dxc_dT[k]
        J *= self.scale[None, :]
        return np.concatenate([c.ravel(), cm.ravel()]), J

    def bounds(self):
        n1 = self.N + 1
        xlo = np.tile(np.asarray(self.p.x_bounds[0], float), (n1, 1))
        xhi = np.tile(np.asarray(self.p.x_bounds[1], float), (n1, 1))
        for k, fixed in ((0, self.p.first), (-1, self.p.last)):
            fixed = np.asarray(fixed, dtype=float)
            given = np.isfinite(fixed)
            xlo[k, given] = fixed[given]
            xhi[k, given] = fixed[given]
        ulo = np.tile(np.asarray(self.p.u_bounds[0], float), (n1, 1))
        uhi = np.tile(np.asarray(self.p.u_bounds[1], float), (n1, 1))
        lo = np.concatenate([xlo.ravel(), ulo.ravel(), [self.p.T_bounds[0]]]) / self.scale
        hi = np.concatenate([xhi.ravel(), uhi.ravel(), [self.p.T_bounds[1]]]) / self.scale
        return list(zip(lo, hi))


#: Weight of the controls' smoothing term (see `solve`): small enough to move the final
#: time by a fraction of a per mille, large enough to settle the chattering that a
#: minimum-time problem's singular arcs (a speed held at its bound) otherwise leave
#: between the nodes, which stalls SLSQP.
SMOOTHING = 1e-4
#: How often SLSQP is started again from where it stalled.
RESTARTS = 3
#: SLSQP's exit codes of a stall (scipy.optimize's _slsqp_py): 4 incompatible
#: inequality constraints, 5 and 6 singular matrices in the least-squares subproblem,
#: 8 no descent in the line search, 9 the iteration limit.
STALLED = (4, 5, 6, 8, 9)


def solve(problem: Problem, nodes: int, guess_states, guess_controls, guess_T: float, *,
          maxiter: int = 500, tolerance: float = 1e-8, smoothing: float = SMOOTHING
          ) -> Solution:
    """Solve ``problem`` on ``nodes`` intervals from the guess (states and controls at the
    ``nodes + 1`` nodes, the final time [s]) with SLSQP.

    The objective is the scaled final time plus ``smoothing`` times the mean square of
    the scaled controls' steps from node to node (a regularisation: the time reported is
    the trajectory's own). ``tolerance`` is SLSQP's ``ftol`` on that objective. The
    returned `Solution` says whether SLSQP converged and how far the result is from
    feasible; it is never marked a success when it is not."""
    tr = _Transcription(problem, nodes, guess_T)
    history: list = []
    y0 = tr.pack(guess_states, guess_controls, guess_T)
    bounds = tr.bounds()
    lo = np.array([b[0] for b in bounds])
    hi = np.array([b[1] for b in bounds])
    y0 = np.clip(y0, lo, hi)
    cons = [{"type": "eq", "fun": lambda y: tr.defects(y)[0], "jac": lambda y: tr.defects(y)[1]}]
    if problem.path is not None:
        cons.append({"type": "ineq", "fun": lambda y: tr.path(y)[0],
                     "jac": lambda y: tr.path(y)[1]})
    xs, us, tcol = tr.columns()

    def objective(y):
        grad = np.zeros(tr.size)
        grad[tcol] = 1.0
        steps = np.diff(y[us], axis=0)
        grad[us[:-1]] -= 2.0 * smoothing * steps / nodes
        grad[us[1:]] += 2.0 * smoothing * steps / nodes
        return y[tcol] + smoothing * float(np.sum(steps ** 2)) / nodes, grad

    def record(y):
        history.append(float(y[-1] * tr.sT))

    # SLSQP can stall on a minimum-time problem's nearly singular arcs (its line search
    # finds no descent, or its quadratic subproblem's linearised constraints conflict);
    # started again from where it stopped, with a fresh quasi-Newton matrix, it usually
    # goes on. A run only counts when SLSQP itself reports convergence.
    iterations = 0
    for _ in range(RESTARTS + 1):
        res = minimize(objective, y0, jac=True, method="SLSQP", bounds=bounds,
                       constraints=cons, callback=record,
                       options={"maxiter": maxiter, "ftol": tolerance})
        iterations += int(res.nit)
        if res.success or res.status not in STALLED:
            break
        y0 = np.clip(res.x, lo, hi)
    X, U, T = tr.unpack(res.x)
    violation = float(np.max(np.abs(tr.defects(res.x)[0]))) if nodes else 0.0
    if problem.path is not None:
        violation = max(violation, float(max(0.0, -np.min(tr.path(res.x)[0]))))
    return Solution(time=np.linspace(0.0, T, nodes + 1), states=X, controls=U, T=float(T),
                    success=bool(res.success), message=str(res.message),
                    iterations=iterations, history=history,
                    constraint_violation=violation)


__all__ = ["Problem", "Solution", "solve"]
