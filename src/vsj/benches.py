"""The test benches of report chapter 4, built from the same sub-models as the wrist.

``planetary_bench`` (section 4.1.2, fig 4.1): one planetary gear module with
its sun or its ring fixed; a motor drives the carrier through a torque sensor
(a stiff torsion spring whose torque is the measurement), or a torque is
applied to the carrier directly (for breakaway tests).

``elastic_bench`` (section 4.2.1, fig 4.9): one elastic element with the pivot
pinned at ``q``; a hand grip turns the lever through a torque sensor.

Input channels: ``drive`` (speed [rad/s] of the motor or the hand, or torque
[N m] with ``drive="torque"``).
"""

from __future__ import annotations

from .components import (Fixed, FixedPivot, Inertia, TorqueSource, Transmission,
                         VelocitySource)
from .errors import InputError
from .network import Network, Signal
from .params import Parameters
from .wrist import elastic_element, planetary

#: Torsional stiffness of the benches' torque sensor [N m/rad] (estimated: a
#: compact six-axis force/torque sensor with its adapters).
SENSOR_STIFFNESS = 200.0
#: Damping in parallel with the sensor [N m s/rad] (estimated: about 10% of
#: critical damping with the carrier's inertia, from the adapters and couplings;
#: without it the fixed-ring bench rings for seconds, its friction being so low).
SENSOR_DAMPING = 0.02


def planetary_bench(params: Parameters, *, fixed: str = "sun", drive: str = "speed",
                    sensor_stiffness: float | None = SENSOR_STIFFNESS,
                    sensor_damping: float = SENSOR_DAMPING) -> Network:
    """Fixed-sun or fixed-ring measurement of the planetary module's friction.

    ``drive="speed"``: the motor's speed follows channel ``drive``; with
    ``sensor_stiffness=None`` it drives the carrier rigidly, otherwise through
    the sensor. ``drive="torque"``: channel ``drive`` is a torque on the carrier.
    The measured torque, transmitted to the carrier, is signal
    ``spring.sensor.compliance.torque`` (sensor), ``source.motor.torque``
    (rigid drive) or ``load.motor.torque``.
    """
    if fixed not in ("sun", "ring"):
        raise InputError(f"planetary bench: fixed must be 'sun' or 'ring', got {fixed!r}")
    if drive not in ("speed", "torque"):
        raise InputError(f"planetary bench: drive must be 'speed' or 'torque', got {drive!r}")
    net = Network(f"planetary bench, {fixed} fixed")
    net.add(planetary("pg", params), Fixed("ground"))
    net.connect(f"pg.{fixed}", "ground.flange")
    if drive == "torque":
        net.add(TorqueSource("motor", "drive"))
        net.connect("motor.flange", "pg.carrier")
    elif sensor_stiffness is None:
        net.add(VelocitySource("motor", "drive"))
        net.connect("motor.flange", "pg.carrier")
    else:
        if not sensor_stiffness > 0.0:
            raise InputError(f"sensor stiffness must be > 0 N m/rad, got {sensor_stiffness!r}")
        net.add(VelocitySource("motor", "drive"),
                Transmission("sensor", ratio=1.0, compliance=1.0 / sensor_stiffness,
                             damping=sensor_damping))
        net.connect("motor.flange", "sensor.input").connect("sensor.output", "pg.carrier")
    net.signal(Signal("carrier", "pg.carrier", "carrier angle"))
    other = "ring" if fixed == "sun" else "sun"
    net.signal(Signal(other, f"pg.{other}", f"{other} angle"))
    return net


def elastic_bench(params: Parameters, *, q: float, model: str = "geometric",
                  sensor_stiffness: float = SENSOR_STIFFNESS,
                  sensor_damping: float = SENSOR_DAMPING,
                  lever_inertia: float | None = None) -> Network:
    """Torque-deflection measurement of one elastic element at pivot position ``q`` [m].

    The lever (inertia ``lever_inertia``, default the ring inertia of the
    planetary module) is driven by the hand through the torque sensor; the
    measured torque is ``spring.sensor.compliance.torque`` and the deflection
    is signal ``phi``.
    """
    if not sensor_stiffness > 0.0:
        raise InputError(f"sensor stiffness must be > 0 N m/rad, got {sensor_stiffness!r}")
    lo, hi = params.pivot.q_min, params.pivot.q_max
    if not lo <= q <= hi:
        raise InputError(f"elastic bench: q = {q * 100:g} cm is outside the pivot range "
                         f"[{lo * 100:g}, {hi * 100:g}] cm")
    inertia = params.planetary.ring_inertia if lever_inertia is None else lever_inertia
    net = Network(f"elastic bench, q = {q * 100:g} cm")
    net.add(elastic_element("vsm", params, model), FixedPivot("pivot", q),
            Inertia("lever", inertia), VelocitySource("hand", "drive"),
            Transmission("sensor", ratio=1.0, compliance=1.0 / sensor_stiffness,
                         damping=sensor_damping))
    net.connect("vsm.ring", "lever.flange")
    net.connect("hand.flange", "sensor.input").connect("sensor.output", "vsm.ring")
    net.signal(Signal("phi", "vsm.ring", "elastic deflection"))
    net.signal(Signal("hand", "hand.flange", "hand grip angle"))
    return net
