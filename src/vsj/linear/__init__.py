"""Linear models of the wrist around an operating point, for control design.

`linearize` returns a python-control `StateSpace` (a `LinearModel`, which
also carries its operating point and how friction was treated) with named
states, inputs and outputs. It linearises the engine's own right-hand side
(`vsj.stepper.Stepper.rate`, central differences with Richardson
extrapolation), so it works for every sub-model choice of
`vsj.wrist.WristOptions` and for any other network (`linearize_structure`).

The package is laid out by job: `build` (operating point and Jacobians),
`analysis` (modes, responses, gains), `files` (JSON and .npz), `data` (the
plain model, `LinearData`, which needs no python-control) and `statespace`
(`LinearModel`). python-control is imported only when a `LinearModel` is
made: the command line works on `LinearData` and starts faster.

Coordinates (the same as `vsj.stepper`)::

    state   x  generalised angles: the free flanges (for the wrist the ring
               angles vsm_i.ring, which are the elastic deflections) [rad]
            p  generalised momenta p = M v + M_su u [N m s]
            i  DC motor currents [A]
            sigma  angles of the velocity sources (motor positions) [rad]
    input   the network's input channels: velocity-source speeds [rad/s],
            load torques [N m], motor voltages [V]; and q [m], the pivot
            position (a fixed pivot's position as an input)
    output  angle [rad] and speed [rad/s] of every named signal of the
            network (theta_x, phi_1, ...; speeds as "<name>_speed"), and the
            torque [N m] that every spring applies ("vsm_1_torque")

Output names are those of `vsj.simulate.Result` with underscores for dots
(``theta_x.speed`` is ``theta_x_speed``): python-control reserves the dot
for ``system.signal`` in interconnections. State names keep vsj's dots.

Momenta rather than speeds because the velocity sources' speeds are inputs:
the kinetic coupling ``M_su du/dt`` would otherwise put the input's
derivative into the model. With momenta the model is proper, and a speed is
an output with a direct feedthrough from the source speeds. Bond graphs
(the report's 20-sim models) use the same states for their inertias.

The pivot is held: the elastic elements do not back-drive it (report section
3.1), so the pivot mechanism and its drive are a separate, one-way chain and
are left out; ``q`` is a parameter of the model and, as input ``q``, the
sensitivity of the ring torques to a small pivot displacement.

Friction (`FRICTION_TREATMENTS`): the wrist rests at the operating point,
where every friction element sits at zero speed. The report's smooth law,
arctan (eq 3.17: ``b s + k atan(k_b s)``), has the slope ``b + k k_b`` there
(for the fitted constants of eq 4.2, ``c1 + c2 c3``): ``linearised`` uses it.
That slope is the small-signal damping, valid while ``k_b |s| << 1`` (speeds
well below 0.1 rad/s with the bundled sharpness of 10 s/rad); for larger
motions friction acts more like a constant torque and damps less. The
Coulomb-like laws (sign, slope, stiction) have no derivative at zero speed
(a jump, a slope set by a numerical width, a set-valued force), so they are
not linearised: ``viscous`` keeps only the viscous part ``b s`` (eq 3.19)
and ``removed`` drops friction altogether.
"""

from .analysis import (
    bandwidth,
    dynamic_states,
    modes,
    natural_frequencies,
    output_stiffness,
    static_gain,
    transfer,
)
from .build import EQUILIBRIUM_ITERATIONS, EQUILIBRIUM_TOL, linearize, linearize_structure, sweep
from .data import FRICTION_TREATMENTS, PIVOT_INPUT, LinearData, signal_name
from .files import FORMAT, FORMAT_VERSION, from_dict, load, save, to_dict


def __getattr__(name):
    if name == "LinearModel":  # imports python-control, which is slow to import
        from .statespace import LinearModel  # lazy: python-control is heavy

        return LinearModel
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["EQUILIBRIUM_ITERATIONS", "EQUILIBRIUM_TOL", "FORMAT", "FORMAT_VERSION",
           "FRICTION_TREATMENTS", "LinearData", "LinearModel", "PIVOT_INPUT", "bandwidth",
           "dynamic_states", "from_dict", "linearize", "linearize_structure", "load", "modes",
           "natural_frequencies", "output_stiffness", "save", "signal_name", "static_gain",
           "sweep", "to_dict", "transfer"]
