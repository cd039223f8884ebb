"""The whole wrist, assembled from its sub-models as in report fig 3.1.

Per output DOF ``i = 1, 2``::

    motor_i --- pg_i.sun          pg_i.ring --- vsm_i.ring          (elastic element)
                pg_i.carrier --- tr_i.input   tr_i.output --- diff.input_i
    diff.theta_x --- ee_x         diff.theta_y --- ee_y              (loads or drives)
    motor_s --- pivot.input       pivot -> q for vsm_1 and vsm_2    (non-backdrivable)

Every connection is rigid (a common speed). Any sub-model can be swapped for
another with the same ports through `WristOptions` without touching the rest:
the elastic model, DC motors or velocity sources at each motor port, external
torques or prescribed angles at the end-effector, and (per run) the friction
law.

Input channels: ``motor_1``, ``motor_2``, ``motor_s`` (speed [rad/s] of the
sun or of the pivot input, with velocity sources) or ``voltage_1``,
``voltage_2``, ``voltage_s`` [V] (DC motors); ``tau_x``, ``tau_y`` [N m]
(external torques) or ``theta_x``, ``theta_y`` (end-effector speeds, when
``end_effector="driven"``).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

from .components import (
    DCMotor,
    Differential,
    ElasticElement,
    FixedPivot,
    PivotMechanism,
    PlanetaryGearModule,
    TorqueSource,
    Transmission,
    VelocitySource,
)
from .components.planetary import MESH_RELATIONS
from .errors import InputError
from .network import Network, Signal
from .params import DEFAULT_ORIGIN, Parameters, default
from .springs import EXPONENTIAL_FIELDS, GEOMETRY_FIELDS

ELASTIC_MODELS = ("geometric", "geometric-report", "exponential", "linear")
DRIVES = ("velocity", "dc")


@dataclass(frozen=True)
class WristOptions:
    """Which sub-model sits at each swappable place.

    ``elastic``: ``geometric`` (potential form of eq 3.1-3.7), ``geometric-report``
    (eq 3.8), ``exponential`` (eq 4.5) or ``linear`` (needs ``linear_stiffness``
    [N m/rad]). ``motors`` and ``pivot_drive``: ``velocity`` or ``dc``;
    ``pivot_drive`` may also be ``fixed`` (pivot pinned at ``fixed_q`` [m]).
    ``end_effector``: ``loaded`` (external torques) or ``driven`` (prescribed
    end-effector speeds, as in fig 4.14). ``mesh_relation``: eq 3.27 as
    ``printed`` (table 4.1's k_1 was derived with it) or ``equal-force`` (see
    `vsj.components.planetary`).
    """

    elastic: str = "geometric"
    motors: str = "velocity"
    pivot_drive: str = "velocity"
    end_effector: str = "loaded"
    linear_stiffness: float | None = None
    fixed_q: float = 0.0
    mesh_relation: str = "printed"

    def validate(self) -> None:
        """`InputError` naming the option and what is allowed if an option is unknown or
        incomplete (a linear elastic model needs a stiffness > 0)."""
        if self.elastic not in ELASTIC_MODELS:
            raise InputError(f"elastic model must be one of {', '.join(ELASTIC_MODELS)}, "
                             f"got {self.elastic!r}")
        if self.elastic == "linear" and not (self.linear_stiffness and self.linear_stiffness > 0):
            raise InputError("the linear elastic model needs linear_stiffness > 0 N m/rad")
        if self.motors not in DRIVES:
            raise InputError(f"motors must be one of {', '.join(DRIVES)}, got {self.motors!r}")
        if self.pivot_drive not in DRIVES + ("fixed",):
            raise InputError(f"pivot_drive must be velocity, dc or fixed, got "
                             f"{self.pivot_drive!r}")
        if self.mesh_relation not in MESH_RELATIONS:
            raise InputError(f"mesh_relation must be one of {', '.join(MESH_RELATIONS)}, got "
                             f"{self.mesh_relation!r}")
        if self.end_effector not in ("loaded", "driven"):
            raise InputError(f"end_effector must be 'loaded' or 'driven', got "
                             f"{self.end_effector!r}")


def geometry(params: Parameters) -> tuple[float, ...]:
    """Parameter row of the geometric elastic models (SI)."""
    return tuple(params[f"elastic_element.{name}"] for name in GEOMETRY_FIELDS)


def exponential(params: Parameters) -> tuple[float, ...]:
    """Parameter row of the simplified elastic model, eq 4.5 (SI)."""
    return tuple(params[f"elastic_element.{name}"] for name in EXPONENTIAL_FIELDS)


def elastic_element(name: str, params: Parameters, model: str,
                    linear_stiffness: float | None = None) -> ElasticElement:
    """The elastic element of a parameter set (``[elastic_element]`` and the friction
    law's sharpness and peak) with elastic ``model``."""
    return ElasticElement.from_parameters(name, params, model=model, stiffness=linear_stiffness)


def planetary(name: str, params: Parameters, *,
              mesh_relation: str = "printed") -> PlanetaryGearModule:
    """The planetary module of a parameter set (``[planetary]``; bearings take the set's
    arctan sharpness, every element its breakaway peak)."""
    return PlanetaryGearModule.from_parameters(name, params, mesh_relation=mesh_relation)


def motor(name: str, params: Parameters, drive: str, channel: str):
    """A motor port: velocity source or DC motor with gearhead (``[motor]``)."""
    if drive == "velocity":
        return VelocitySource(name, channel=f"motor_{channel}")
    return DCMotor.from_parameters(name, params, channel=f"voltage_{channel}")


def build_wrist(params: Parameters, options: WristOptions | None = None) -> Network:
    """The wrist network for a parameter set.

    Each part reads its own section (`SchemaComponent.from_parameters`); the
    only mapping here is the one the wrist adds: DOF ``i``'s transmission takes
    ``transmission.series_compliance_<i>``."""
    options = options or WristOptions()
    options.validate()
    net = Network("wrist")
    net.add(Differential.from_parameters("diff", params))
    for i in (1, 2):
        net.add(motor(f"motor_{i}", params, options.motors, str(i)),
                planetary(f"pg_{i}", params, mesh_relation=options.mesh_relation),
                elastic_element(f"vsm_{i}", params, options.elastic, options.linear_stiffness),
                Transmission.from_parameters(
                    f"tr_{i}", params, keys={"compliance": f"transmission.series_compliance_{i}"}))
        net.connect(f"motor_{i}.flange", f"pg_{i}.sun")
        net.connect(f"pg_{i}.ring", f"vsm_{i}.ring")
        net.connect(f"pg_{i}.carrier", f"tr_{i}.input")
        net.connect(f"tr_{i}.output", f"diff.input_{i}")
    if options.end_effector == "loaded":
        net.add(TorqueSource("ee_x", "tau_x"), TorqueSource("ee_y", "tau_y"))
    else:
        net.add(VelocitySource("ee_x", "theta_x"), VelocitySource("ee_y", "theta_y"))
    net.connect("diff.theta_x", "ee_x.flange").connect("diff.theta_y", "ee_y.flange")
    if options.pivot_drive == "fixed":
        net.add(FixedPivot("pivot", options.fixed_q))
    else:
        net.add(motor("motor_s", params, options.pivot_drive, "s"),
                PivotMechanism.from_parameters("pivot", params))
        net.connect("motor_s.flange", "pivot.input")
    for name, flange, text in [
        ("theta_x", "diff.theta_x", "end-effector angle about x"),
        ("theta_y", "diff.theta_y", "end-effector angle about y"),
        ("phi_1", "vsm_1.ring", "elastic deflection 1 (ring angle)"),
        ("phi_2", "vsm_2.ring", "elastic deflection 2 (ring angle)"),
        ("psi_1", "diff.input_1", "differential input 1"),
        ("psi_2", "diff.input_2", "differential input 2"),
        ("carrier_1", "pg_1.carrier", "planetary carrier 1"),
        ("carrier_2", "pg_2.carrier", "planetary carrier 2"),
        ("motor_1", "pg_1.sun", "motor 1 output (sun 1)"),
        ("motor_2", "pg_2.sun", "motor 2 output (sun 2)"),
    ]:
        net.signal(Signal(name, flange, text))
    if options.pivot_drive != "fixed":
        net.signal(Signal("motor_s", "pivot.input", "stiffness motor output"))
    return net


@functools.cache
def _bundled_values() -> dict[str, float]:
    """The bundled set's values, read once (compared with, never handed out)."""
    return dict(default().values)


def elastic_models(net: Network) -> str:
    """The elastic models of ``net``'s elastic elements and the ``[elastic_element]`` keys
    each reads, in words ("the 'exponential' elastic model (it reads a1, ...)")."""
    models = {c.model: c.reads for c in net.components if isinstance(c, ElasticElement)}
    return " and ".join(f"the {model!r} elastic model (it reads "
                        f"{', '.join(reads) if reads else 'none of them'})"
                        for model, reads in models.items())


def unread_keys(net: Network) -> list[str]:
    """The ``[elastic_element]`` keys of the elastic models' rows (`GEOMETRY_FIELDS`,
    `EXPONENTIAL_FIELDS`) that no elastic element of ``net`` reads, as "section.key"; none
    for a network without elastic elements."""
    reads = [c.reads for c in net.components if isinstance(c, ElasticElement)]
    if not reads:
        return []
    read = set().union(*reads)
    return [f"elastic_element.{k}" for k in dict.fromkeys(GEOMETRY_FIELDS + EXPONENTIAL_FIELDS)
            if k not in read]


def unread_changes(net: Network, params: Parameters, *,
                   choose: str = "a scenario's [model] elastic") -> list[str]:
    """A sentence naming the ``[elastic_element]`` values of ``params`` that differ from the
    bundled set's but that no elastic element of ``net`` reads (a geometric design run with
    the exponential model of eq 4.5, say, which gives the bundled set's results), or none
    when ``net`` reads every value the set changes. ``choose`` names what chooses the
    model where the sentence is read."""
    if params.origin == DEFAULT_ORIGIN:
        return []
    bundled = _bundled_values()
    unread = [k for k in unread_keys(net) if params[k] != bundled[k]]
    if not unread:
        return []
    return [f"the parameter set ({params.origin}) sets {', '.join(unread)} away from the "
            f"bundled set, but {elastic_models(net)} does not read "
            f"{'it' if len(unread) == 1 else 'them'}, so the results are the same as "
            f"without; {choose} chooses the model"]
