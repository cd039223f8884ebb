"""The fig 4.15 wrist written out by hand: the benchmarks' baselines.

Velocity sources drive the suns, the pivot is fixed, the elastic elements are
the exponential model of eq 4.5, every friction element follows the arctan law.
States: the two ring angles (elastic deflections) and their speeds. The
equations are derived here from the kinematics, independently of vsj's network
elimination:

    carrier speed        w_C = r_RC w + r_SC u
    differential input   psi' = w_C / ratio
    end-effector         theta' = J psi',  J = [[1, 1], [1, -1]] / 2

Three integrators use them: `python_rhs` (a plain Python right-hand side, the
way one would write it for scipy's `solve_ivp`), `compiled_rk4` (the same
equations by hand in C, ``wrist_equations.h``, with a fixed-step Runge-Kutta loop,
``wrist_rk4.c``) and `compiled_cvodes` (SUNDIALS CVODES's BDF on the same C
equations, ``wrist_cvodes.c``, where libsundials-dev is installed).
"""

from __future__ import annotations

import ctypes
import math
import subprocess
import sysconfig
import tempfile
from pathlib import Path

import numpy as np


def constants(params, q: float, amplitude: float, frequency: float, fade: float):
    """Every number the equations need, in one array (SI)."""
    pg, tr, d, ee = params.planetary, params.transmission, params.differential, params.elastic_element
    sharp = params.friction.arctan_sharpness
    x = pg.sun_teeth / pg.ring_teeth
    r_rc = 1.0 / (1.0 + x)
    r_sc = x / (1.0 + x)
    g = r_rc / tr.ratio  # psi' per ring speed
    h = r_sc / tr.ratio  # psi' per sun speed
    J = np.array([[0.5, 0.5], [0.5, -0.5]])
    JIJ = J.T @ np.diag([d.inertia_x, d.inertia_y]) @ J
    M = (pg.ring_inertia + pg.carrier_inertia * r_rc ** 2) * np.eye(2) + g * g * JIJ
    Mu = pg.carrier_inertia * r_rc * r_sc * np.eye(2) + g * h * JIJ
    K = ee.a1 * math.exp(ee.a2 * q) + ee.a3
    return np.array([
        r_rc, r_sc, g, h, K, *np.linalg.inv(M).ravel(), *Mu.ravel(),
        pg.mesh_stiction, pg.mesh_sharpness, x,
        pg.ring_bearing_viscous, pg.ring_bearing_stiction,
        pg.carrier_bearing_viscous, pg.carrier_bearing_stiction,
        ee.lever_viscous, ee.lever_stiction, tr.viscous, tr.stiction,
        d.viscous, d.stiction, sharp, amplitude, 2 * math.pi * frequency, fade,
    ])


def _fade(t, T):
    """Quintic smoothstep and its first two derivatives."""
    if t >= T:
        return 1.0, 0.0, 0.0
    z = t / T
    return (z ** 3 * (10 - 15 * z + 6 * z * z), 30 * z * z * (1 - z) ** 2 / T,
            60 * z * (1 - z) * (1 - 2 * z) / (T * T))


def _arctan(b, k, kb, s):
    return b * s + k * math.atan(kb * s)


def _body(t, y, c, dy, _fade, _arctan):
    r_rc, r_sc, g, h, K = c[0], c[1], c[2], c[3], c[4]
    Minv = c[5:9]
    Mu = c[9:13]
    k1, kb1, x = c[13], c[14], c[15]
    bR, kR, bC, kC, bL, kL, bT, kT, bD, kD, sharp = c[16:27]
    A, om, T = c[27], c[28], c[29]
    e, de, dde = _fade(t, T)
    u = np.empty(2)
    du = np.empty(2)
    for i in range(2):
        phase = om * t + (0.25 * math.pi if i == 0 else -0.25 * math.pi)
        sn, cs = math.sin(phase), math.cos(phase)
        u[i] = A * (de * sn + e * om * cs)
        du[i] = A * (dde * sn + 2 * de * om * cs - e * om * om * sn)
    F = np.zeros(2)
    theta_y = 0.5 * (g * (y[2] - y[3]) + h * (u[0] - u[1]))
    f_diff = _arctan(bD, kD, sharp, theta_y)
    for i in range(2):
        w = y[2 + i]
        wc = r_rc * w + r_sc * u[i]
        F[i] -= K * y[i]
        F[i] += _arctan(0.0, k1, kb1, u[i] - wc) * r_rc          # mesh, sun - carrier
        F[i] -= _arctan(0.0, x * k1, kb1 / x, w - wc) * (1 - r_rc)  # mesh, ring - carrier
        F[i] -= _arctan(bR, kR, sharp, w)                       # ring bearing
        F[i] -= _arctan(bC, kC, sharp, wc) * r_rc               # carrier bearing
        F[i] -= _arctan(bL, kL, sharp, w)                       # lever and pivot
        F[i] -= _arctan(bT, kT, sharp, wc) * r_rc               # transmission
        F[i] -= f_diff * g * (0.5 if i == 0 else -0.5)          # differential
        F[i] -= Mu[2 * i] * du[0] + Mu[2 * i + 1] * du[1]
    dy[0] = y[2]
    dy[1] = y[3]
    dy[2] = Minv[0] * F[0] + Minv[1] * F[1]
    dy[3] = Minv[2] * F[0] + Minv[3] * F[1]


def python_rhs(c):
    """A plain Python right-hand side for scipy (the same equations, interpreted)."""

    def rhs(t, y):
        dy = np.empty(4)
        _body(t, y, c, dy, _fade, _arctan)
        return dy

    return rhs


_LIBRARIES: dict = {}


def _library(name: str, libraries=()):
    """benchmarks/``name``.c, compiled once per process with the flags of Python's own
    extensions and those setup.py adds for vsj's engine (-std=c99 -fno-math-errno), so
    that the baselines are built as the engine is (and linked with ``libraries``)."""
    if name not in _LIBRARIES:
        out = Path(tempfile.mkdtemp(prefix="vsj-bench-")) / f"{name}.so"
        flags = (sysconfig.get_config_var("CFLAGS") or "-O3").split() + ["-std=c99",
                                                                      "-fno-math-errno"]
        cc = (sysconfig.get_config_var("CC") or "cc").split()[0]
        subprocess.run([cc, *flags, "-shared", "-fPIC", "-o", str(out),
                        str(Path(__file__).with_name(f"{name}.c")),
                        *[f"-l{lib}" for lib in libraries], "-lm"],
                       check=True, capture_output=True)
        _LIBRARIES[name] = ctypes.CDLL(str(out))
    return _LIBRARIES[name]


_DOUBLES = ctypes.POINTER(ctypes.c_double)


def compiled_rk4(c, h, t_end, every):
    """Classical RK4 in C with fixed step ``h``; the states every ``every`` steps."""
    lib = _library("wrist_rk4")
    lib.rk4.restype = ctypes.c_long
    lib.rk4.argtypes = [_DOUBLES, ctypes.c_double, ctypes.c_double, ctypes.c_long, _DOUBLES]
    steps = int(round(t_end / h))
    out = np.empty((steps // every + 1, 4))
    c = np.ascontiguousarray(c, dtype=float)
    lib.rk4(c.ctypes.data_as(_DOUBLES), h, t_end, every, out.ctypes.data_as(_DOUBLES))
    return out


def cvodes_available() -> str | None:
    """None if SUNDIALS CVODES can be built against here, else why not."""
    try:
        _library("wrist_cvodes", ("sundials_cvodes", "sundials_nvecserial"))
    except subprocess.CalledProcessError as exc:
        lines = exc.stderr.decode(errors="replace").strip().splitlines()
        return ("CVODES not available (Debian: apt-get install libsundials-dev): "
                + (lines[0] if lines else f"the compiler exited with {exc.returncode}"))
    except OSError as exc:  # built, but the library does not load
        return f"CVODES not available: {exc}"
    return None


def compiled_cvodes(c, rtol: float, atol: float, t_out: np.ndarray):
    """SUNDIALS CVODES (BDF, dense Newton, its difference-quotient Jacobian) on the
    same equations in C: ``(states at t_out, right-hand side evaluations)``."""
    lib = _library("wrist_cvodes", ("sundials_cvodes", "sundials_nvecserial"))
    lib.cvodes_bdf.restype = ctypes.c_long
    lib.cvodes_bdf.argtypes = [_DOUBLES, ctypes.c_double, ctypes.c_double, _DOUBLES,
                               ctypes.c_long, _DOUBLES]
    c = np.ascontiguousarray(c, dtype=float)
    t_out = np.ascontiguousarray(t_out, dtype=float)
    out = np.empty((len(t_out), 4))
    evals = lib.cvodes_bdf(c.ctypes.data_as(_DOUBLES), rtol, atol, t_out.ctypes.data_as(_DOUBLES),
                           len(t_out), out.ctypes.data_as(_DOUBLES))
    if evals < 0:
        raise RuntimeError(f"CVODES failed at rtol {rtol:g}")
    return out, int(evals)


def sun_angles(t, c):
    """Sun angles of the scenario (for end-effector angles from ring angles)."""
    A, om, T = c[27], c[28], c[29]
    z = np.clip(t / T, 0.0, 1.0)
    env = z ** 3 * (10 - 15 * z + 6 * z * z)
    return np.stack([A * env * np.sin(om * t + math.pi / 4), A * env * np.sin(om * t - math.pi / 4)])


def theta_x(ring, t, c):
    """End-effector angle theta_x from ring angles (runs x 2) and time."""
    g, h = c[2], c[3]
    s = sun_angles(t, c)
    psi = g * ring + h * s.T
    return 0.5 * (psi[:, 0] + psi[:, 1])
