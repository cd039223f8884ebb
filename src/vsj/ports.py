"""The port convention every component of vsj follows (stated once, here).

A *flange* is a rotational port: an angle ``phi`` [rad] and a speed
``omega = d phi / dt`` [rad/s], both positive in the flange's reference
direction. A torque ``tau`` [N m] that a component applies *to* a flange is
positive in that same direction, so ``tau * omega`` [W] is the power the
component delivers into the flange (negative: power it takes out).

Flanges are named ``"<component>.<port>"``. Connecting two flanges makes them
one rigid body in the kinematic sense: a common speed, a bond-graph 1-junction
(report section 3.1). The connection itself transmits a torque; the network
reports it as the torque applied to the first flange of the pair and the power
flowing through it into that flange.

Linear relations between flange speeds (an ideal gear, the planetary set, the
differential, a connection) are *kinematic maps*: each is a constant matrix,
and the torques such an element exerts on its flanges are the transpose of the
map applied to its constraint forces. Power balance of ideal elements therefore
holds by construction (``tests/test_ideal_elements.py`` checks it).

Relative quantities (a mesh slip speed, a spring deflection) are linear
combinations of flange speeds or angles, written as ``{flange: coefficient}``.
An element acting on ``s = sum(c_i omega_i)`` with torque ``f`` applies
``c_i f`` to flange ``i``.

The one exception, kept because friction is read as a resistance: a friction
element's recorded ``friction.<name>.torque`` is its *resistive* torque ``r``,
positive when it opposes a positive slip ``s``; the torque it applies in the
sense above is ``f = -r`` (``-c_i r`` on flange ``i``). Its
``friction.<name>.power`` follows the convention: ``f s = -r s <= 0``, the
power it delivers, never positive.

Angles are measured from the reference configuration in which every spring of
the model is at its nominal zero (elastic elements undeflected, parasitic
compliances unloaded); all kinematic maps hold for angles as well as speeds.
"""

#: Separator between a component's name and its port's name.
SEPARATOR = "."


def flange(component: str, port: str) -> str:
    """Full name of a component's port."""
    return f"{component}{SEPARATOR}{port}"
