"""Friction laws: every resistive element of the wrist uses one of these.

A friction element acts on one relative speed ``s`` [rad/s] (a bearing on an
absolute speed, a gear mesh on the speed difference of two members). It
produces a resistive torque ``f(s)`` [N m]: the element applies ``-f(s)`` to
the side whose speed is counted positive in ``s`` (see `vsj.ports`), so the
power it takes from the mechanism is ``f(s) s >= 0`` for every law below.

Each element carries four numbers: a viscous coefficient ``b`` [N m s/rad], a
stiction parameter ``k`` [N m], an arctan sharpness ``k_b`` [s/rad] and a
slope width ``w`` [rad/s] (a numerical knob, see `SimulationOptions`). ``k`` is
read as the report reads it (section 4.1.3, fig 4.8): the first parameter of
an equivalent arctan law, so every law saturates at the Coulomb level
``k * pi / 2`` and the laws can be swapped without touching the parameters.

=========  ===================================================  =============
law        resistive torque f(s)                                report
=========  ===================================================  =============
viscous    b s  (the Coulomb part is dropped)                   eq 3.19
arctan     b s + k atan(k_b s)                                  eq 3.17
sign       b s + k (pi/2) sign(s)                               eq 3.18
slope      b s + k (pi/2) clip(s / w, -1, 1)                    fig 4.8
stiction   b s, plus a Coulomb torque of at most k pi/2 that    (vsj)
           holds the element exactly at s = 0 (solved jointly
           for all elements by the time-stepping solver)
=========  ===================================================  =============

The slope law is one reading of fig 4.8 (a straight line through zero inside
``|s| < w``, the Coulomb level outside); the report gives it as a picture only.
"""

from __future__ import annotations

import numpy as np

from . import _core
from .errors import InputError

#: The friction laws by name, with their engine codes (engine/c/vsj_layout.h's table).
LAWS = {name: code for code, name in enumerate(_core.LAYOUT["friction_laws"])}
LAW_NAMES = {code: name for name, code in LAWS.items()}
VISCOUS, ARCTAN, SIGN, SLOPE, STICTION = (LAWS[n] for n in ("viscous", "arctan", "sign",
                                                             "slope", "stiction"))

#: Arctan sharpness k_b [s/rad] of an element built without one (a component used
#: outside a parameter set; the wrist takes friction.arctan_sharpness from its set).
DEFAULT_SHARPNESS = 10.0

#: Column order of a friction element's parameter row.
PARAMETERS = ("viscous", "stiction", "sharpness", "width")

#: How friction can enter a linear model (`vsj.linear`).
LINEAR_TREATMENTS = {
    "linearised": "smooth arctan law b s + k atan(k_b s) (report eq 3.17) linearised at zero "
                  "speed: viscous slope b + k k_b on every friction element",
    "viscous": "Coulomb-like part removed; the viscous part b s (report eq 3.19) kept",
    "removed": "all friction removed (undamped mechanics; only armature resistance dissipates)",
}


#: The law of the environment's contacts (`vsj.components.Contact`): an element's own,
#: not one a run chooses for its friction.
CONTACT = "contact"
#: The laws a run (or an element) may choose for its friction.
RUN_LAWS = tuple(name for name in LAWS if name != CONTACT)


def law_code(name: str) -> int:
    """The engine's code of a friction law a run or an element may choose; `InputError`
    names the choices."""
    if name != CONTACT and isinstance(name, str) and name in LAWS:
        return LAWS[name]
    choices = ", ".join(n for n in LAWS if n != CONTACT)
    raise InputError(f"unknown friction law {name!r}; choose one of {choices}"
                     + (" (contact is the environment's law: vsj.components.Contact)"
                        if name == CONTACT else ""))


def torque(law: str, speeds, *, viscous=0.0, stiction=0.0, sharpness=1.0, width=1e-3):
    """Resistive torque [N m] of one law at an array of speeds [rad/s] (the
    engine's own evaluation, ``vsj_friction_torque`` in ``engine/c/laws.c``).

    For ``stiction`` the element is sliding at every nonzero speed, so the
    Coulomb torque ``k pi/2 sign(s)`` is added to the viscous part (at ``s = 0``
    the torque is whatever holds the element and is not a function of speed).
    """
    code = law_code(law)
    shape = np.shape(np.atleast_1d(speeds))
    s = np.ascontiguousarray(np.asarray(speeds, dtype=float).ravel())
    out = np.empty_like(s)
    _core.friction_torque(code, float(viscous), float(stiction), float(sharpness), float(width),
                          s, out)
    if code == STICTION:
        out = out + stiction * 0.5 * np.pi * np.sign(s)
    return out.reshape(shape)
