"""How a run is set up: numerical options (`SimulationOptions`) and the
initial state (`InitialState`)."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from collections.abc import Mapping

from .. import friction as friction_laws
from ..engine.plan import ATOL, RTOL
from ..errors import InputError, is_number

#: Sane ranges of the numerical settings (SI): outside them a run cannot be trusted
#: (a relative tolerance of 0.5 gives no accuracy at all) and is refused up front.
RANGES = {"rtol": (1e-14, 1e-2), "atol": (1e-20, 1e-2), "step": (1e-7, 0.05),
          "output_step": (1e-7, math.inf), "slope_width": (1e-12, 1e3),
          "max_step": (1e-9, math.inf), "ledger_tolerance": (1e-15, 1.0)}
#: A run fails when its energy ledger's residual exceeds this fraction of the energy
#: in play (the work done, the energy dissipated, or the energy the mechanism holds;
#: a sound run closes it to 1e-15 with the time-stepper, and to about rtol or better
#: with dopri).
LEDGER_TOLERANCE = 1e-3
#: the solvers a run may ask for ("auto": the time-stepper where stiction or a rigid
#: end stop needs it, else dopri)
SOLVERS = ("auto", "dopri", "rosenbrock", "timestep")


@dataclass(frozen=True)
class SimulationOptions:
    """How to simulate: friction law, solver and numerical knobs (SI units).

    ``slope_width`` is the report's ``w`` of fig 4.8 (a numerical knob, not a
    property of the prototype). ``rtol``/``atol`` steer ``dopri`` and ``rosenbrock``;
    ``step`` is
    the fixed step of ``timestep``. ``output_step`` sets the sample grid. A run
    whose energy ledger leaves a residual above ``ledger_tolerance`` (a fraction
    of the energy in play) is reported as failed. `RANGES` bounds every number.
    """

    friction: str = "arctan"
    friction_overrides: Mapping[str, str] = field(default_factory=dict)
    slope_width: float = 0.01
    solver: str = "auto"
    rtol: float = RTOL
    atol: float = ATOL
    max_step: float = math.inf
    step: float = 1e-3
    output_step: float = 1e-3
    max_steps: int = 20_000_000
    ledger_tolerance: float = LEDGER_TOLERANCE

    def __post_init__(self):
        # NumPy's scalars (np.float32(0.01), np.int64(1000)) are the numbers they hold
        for name in (*RANGES, "max_steps"):
            value = getattr(self, name)
            if is_number(value):
                whole = name == "max_steps" and isinstance(value, numbers.Integral)
                object.__setattr__(self, name, int(value) if whole else float(value))

    def validate(self) -> None:
        """`InputError` naming the option, the value and what is allowed if any option is
        out of range."""
        friction_laws.law_code(self.friction)
        if self.solver not in SOLVERS:
            raise InputError(f"solver must be one of {', '.join(map(repr, SOLVERS))}, got "
                             f"{self.solver!r}")
        for name, (lo, hi) in RANGES.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not lo <= value <= hi:
                raise InputError(f"option {name} must be a number in [{lo:g}, {hi:g}], got "
                                 f"{value!r}")
        if isinstance(self.max_steps, bool) or not isinstance(self.max_steps, int) \
                or not 1 <= self.max_steps <= 10 ** 10:
            raise InputError(f"option max_steps must be a whole number in [1, 1e10], got "
                             f"{self.max_steps!r}")


@dataclass(frozen=True)
class InitialState:
    """Initial angles and speeds of named flanges, pivot position and currents.

    Flanges not named start at rest in the reference configuration (or as
    close to it as the named ones allow). ``q`` [m] sets the pivot mechanism.
    """

    angles: Mapping[str, float] = field(default_factory=dict)
    speeds: Mapping[str, float] = field(default_factory=dict)
    q: float | None = None
    currents: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self):
        """`InputError` naming the field and the entry unless the angles, speeds and
        currents map names to finite numbers and ``q`` is one (or None); the mappings are
        kept as copies with float values, so a caller's later change does not reach them."""
        for name in ("angles", "speeds", "currents"):
            given = getattr(self, name)
            if not isinstance(given, Mapping):
                raise InputError(f"InitialState.{name} must be a mapping of names to numbers "
                                 f"(a dict), got {type(given).__name__}")
            checked = {}
            for key, value in given.items():
                if not isinstance(key, str):
                    raise InputError(f"InitialState.{name}: names are strings, got {key!r}")
                checked[key] = _finite(value, f"InitialState.{name}[{key!r}]")
            object.__setattr__(self, name, checked)
        if self.q is not None:
            object.__setattr__(self, "q", _finite(self.q, "InitialState.q (the pivot "
                                                          "position in metres)"))


def _finite(value, where: str) -> float:
    """``value`` as a float if it is a finite real number, else `InputError` naming
    ``where``."""
    if not is_number(value) or not math.isfinite(value):
        raise InputError(f"{where} must be a finite number (SI units), got {value!r}")
    return float(value)
