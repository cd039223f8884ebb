"""Clutch and brake: friction whose normal force an input signal sets.

As Modelica's ``Rotational.Components.Clutch`` and ``Brake`` (MSL): the
kinetic friction torque is ``mu(|w|) cgeo fn``, with ``fn = fn_max f`` and
``f`` a normalised normal force in [0, 1] from an input channel (any
`vsj.inputs` signal: engaged, released or modulated over time; values
outside [0, 1] are clipped). ``mu`` is a constant or a table against slip
speed (MSL's ``mu_pos``: rows of slip speed [rad/s] >= 0 and coefficient,
linear between rows, constant beyond). A stuck clutch holds up to ``peak``
times the kinetic torque at zero speed (``peak >= 1``: the breakaway torque,
the Stribeck-like effect the report suspects at low speeds, section 4.1.3).

Both are friction elements of the network (`vsj.network.Friction`); the
run's friction law applies to them as to every other element. True stiction
(``friction = "stiction"``) gives the stuck phases, the breakaway at the peak
and sliding at the kinetic level; a smooth law scales its level by ``f`` and
``mu`` and has no peak.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from ..friction import DEFAULT_SHARPNESS
from ..network import Component, Friction, Parts
from ..params import FORCE, SHARPNESS, Spec
from ._values import _check, _peak

#: MSL's geometry constant cgeo: the friction torque per newton of normal force and
#: unit friction coefficient [m].
GEOMETRY_CONSTANT = Spec("m", "m", "geometry constant cgeo", 0.0, strict=True)


def _mu_table(name: str, mu) -> tuple[tuple[float, float], ...]:
    """Rows (slip speed, coefficient) from a constant or a table."""
    if isinstance(mu, (int, float)):
        rows = ((0.0, float(mu)),)
    else:
        try:
            rows = tuple((float(w), float(c)) for w, c in mu)
        except (TypeError, ValueError):
            raise ValueError(f"{name}: mu must be a number or rows of (slip speed [rad/s], "
                             f"coefficient), got {mu!r}") from None
    if not rows:
        raise ValueError(f"{name}: mu needs at least one row")
    for k, (w, c) in enumerate(rows):
        if not (math.isfinite(w) and math.isfinite(c) and w >= 0.0 and c >= 0.0):
            raise ValueError(f"{name}: mu row {k} ({w!r}, {c!r}): slip speed and coefficient "
                             f"must be finite and >= 0")
        if k and not w > rows[k - 1][0]:
            raise ValueError(f"{name}: mu's slip speeds must increase (row {k})")
    return rows


class _NormalForceFriction(Component):
    """The friction element shared by `Clutch` and `Brake`."""

    def __init__(self, name: str, *, fn_max: float, mu: float | Sequence = 0.5,
                 peak: float = 1.0, cgeo: float = 1.0, channel: str | None = None,
                 sharpness: float = DEFAULT_SHARPNESS):
        super().__init__(name)
        self.fn_max = _check(f"fn_max of {name}", FORCE, fn_max)
        self.cgeo = _check(f"cgeo of {name}", GEOMETRY_CONSTANT, cgeo)
        self.mu = _mu_table(name, mu)
        self.peak = _peak(name, peak)
        self.sharpness = _check(f"arctan sharpness of {name}", SHARPNESS, sharpness)
        self.channel = channel or f"{name}_force"

    def _friction(self, speed: dict[str, float]) -> Friction:
        # level k pi/2 f mu(|w|) = cgeo fn_max f mu(|w|)
        return Friction(self.name, speed, 0.0, 2.0 / math.pi * self.cgeo * self.fn_max,
                        self.sharpness, peak=self.peak, normal=self.channel, table=self.mu)


class Clutch(_NormalForceFriction):
    """Friction between flanges ``a`` and ``b`` on their relative speed ``w_b - w_a``
    (MSL's ``w_rel``); ``channel`` (default ``<name>_force``) is the normalised
    normal force. Parameters: ``fn_max`` [N], ``mu`` (constant or table),
    ``peak``, ``cgeo`` [m] (torque per unit friction force)."""

    ports = ("a", "b")

    def parts(self) -> Parts:
        """Friction on the slip speed ``omega_b - omega_a`` [rad/s], its level set by the
        normal-force channel."""
        a, b = self.port("a"), self.port("b")
        return Parts(flanges=[a, b], frictions=[self._friction({b: 1.0, a: -1.0})])


class Brake(_NormalForceFriction):
    """Friction between ``flange`` and the ground, on the flange's speed; the
    parameters are those of `Clutch`."""

    ports = ("flange",)

    def parts(self) -> Parts:
        """Friction on the flange's absolute speed [rad/s], its level set by the
        normal-force channel."""
        f = self.port("flange")
        return Parts(flanges=[f], frictions=[self._friction({f: 1.0})])
