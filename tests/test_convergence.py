"""Observed order of convergence of both solvers on a problem with a known solution.

The problem: an inertia ``J`` on a linear spring ``k`` to the ground with
viscous damping ``c``, released from rest at ``PHI0``. Its exact motion is the
damped oscillation

    phi(t) = PHI0 exp(-zeta w0 t) (cos(wd t) + zeta w0 / wd sin(wd t)),
    w0 = sqrt(k / J),  zeta = c / (2 sqrt(k J)),  wd = w0 sqrt(1 - zeta^2).

What each solver should show (the comments of ``src/vsj/engine/c``):

* ``dopri`` (Dormand-Prince 5(4), ``dopri.c``): the global error is
  proportional to the tolerance (slope 1 against rtol), and, as a fifth-order
  method, falls as the fifth power of the number of steps;
* ``rosenbrock`` (RODAS4, ``rosenbrock.c``): a fourth-order solution with a
  third-order error estimate, also propagated, so its error too is proportional
  to the tolerance, and falls as the fourth power of the number of steps;
* ``timestep`` (``timestep.c``): springs take the trapezoidal rule, and so do
  dampers flagged as such (a spring-damper's), so the oscillator converges at
  second order; a viscous bearing takes implicit Euler, first order.

Orders are the least-squares slopes of log(error) against log(step) (or
log(steps), log(rtol)); the accepted bands are named below.
"""

import math

import numpy as np
import pytest

from vsj.components import Bearing, Fixed, Inertia, SpringDamper
from vsj.network import Network
from vsj.simulate import InitialState, SimulationOptions, simulate

J, K, C = 1e-3, 0.4, 2e-3  # kg m^2, N m/rad, N m s/rad: w0 = 20 rad/s, zeta = 0.05
PHI0 = 0.1  # rad
DURATION = 0.5  # s: about 1.6 periods
W0 = math.sqrt(K / J)
ZETA = C / (2.0 * math.sqrt(K * J))
WD = W0 * math.sqrt(1.0 - ZETA ** 2)
RELEASED = InitialState(angles={"m.flange": PHI0})

#: Fixed steps [s], halving: from 1/160 to 1/1250 of the period.
STEPS = (2e-3, 1e-3, 5e-4, 2.5e-4)
#: Tolerances of dopri, a decade apart; below 1e-4 the controller is in its asymptotic regime.
RTOLS = (1e-6, 1e-7, 1e-8, 1e-9, 1e-10)
#: Accepted bands of the observed order p: half-way to the neighbouring orders, so that
#: a second-order scheme that lost a term (order 1) fails, and a first-order part that
#: became second order fails too. A fifth-order method that lost a term drops to 4;
#: above 6 the errors would no longer be the method's.
SECOND_ORDER = (1.5, 2.5)
FIRST_ORDER = (0.5, 1.5)
FIFTH_ORDER = (4.5, 6.0)
FOURTH_ORDER = (3.5, 5.0)
#: The global error against rtol: control of the error per step with local
#: extrapolation (the fifth-order solution propagated, the fourth-order one's error,
#: ~h^5, estimated) makes it proportional, exponent 1 (h ~ rtol^(1/5), global error
#: ~h^5). Without extrapolation it would be rtol^(4/5); controlling the error per unit
#: step with it (h^4 ~ rtol) rtol^(5/4): the band lies half-way to each.
TOLERANCE_PROPORTIONAL = ((4 / 5 + 1) / 2, (1 + 5 / 4) / 2)
#: The same for a fourth-order pair with a third-order estimate (the Rosenbrock
#: steps): rtol^(3/4) without extrapolation, rtol^(4/3) per unit step (h^3 ~ rtol).
TOLERANCE_PROPORTIONAL_4 = ((3 / 4 + 1) / 2, (1 + 4 / 3) / 2)


def exact(t):
    return PHI0 * np.exp(-ZETA * W0 * t) * (np.cos(WD * t) + ZETA * W0 / WD * np.sin(WD * t))


def oscillator(damping: str):
    """The damped oscillator, its damping in a spring-damper (``"damper"``) or a bearing."""
    net = Network("oscillator")
    net.add(Fixed("ground"), Inertia("m", J))
    if damping == "damper":
        net.add(SpringDamper("sd", stiffness=K, damping=C))
    else:
        net.add(SpringDamper("sd", stiffness=K), Bearing("bearing", viscous=C))
        net.connect("bearing.flange", "m.flange")
    net.connect("ground.flange", "sd.a").connect("sd.b", "m.flange")
    return net.assemble()


def max_error(result) -> float:
    assert result.success, result.message
    # the last sample, a multiple of the output step: a few roundings of the duration
    assert result.time[-1] == pytest.approx(DURATION, rel=4 * np.finfo(float).eps, abs=0.0)
    return float(np.max(np.abs(result["m.flange"] - exact(result.time))))


def slope(x, y) -> float:
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


def test_the_reference_solution_solves_the_equation():
    """J phi'' + c phi' + k phi = 0, phi(0) = PHI0, phi'(0) = 0 (finite differences)."""
    t = np.linspace(0.0, DURATION, 20001)
    h = t[1] - t[0]
    phi = exact(t)
    d1 = (phi[2:] - phi[:-2]) / (2 * h)
    d2 = (phi[2:] - 2 * phi[1:-1] + phi[:-2]) / h ** 2
    residual = J * d2 + C * d1 + K * phi[1:-1]
    # truncation: J h^2 |phi''''| / 12 + C h^2 |phi'''| / 6, with |phi^(n)| <= W0^n times
    # the mode's amplitude PHI0 / sqrt(1 - zeta^2) (|lambda| = W0); round-off of the
    # second difference: 4 eps |phi| / h^2, times J
    mode = PHI0 / math.sqrt(1.0 - ZETA ** 2)
    truncation = (J * W0 ** 4 / 12 + C * W0 ** 3 / 6) * h ** 2 * mode
    roundoff = 4 * np.finfo(float).eps * PHI0 * J / h ** 2
    assert np.max(np.abs(residual)) <= truncation + roundoff
    # phi(0) is PHI0 exp(0) (cos 0 + 0): exact; at rest, the first step moves by the
    # acceleration's h^2 / 2 (a starting speed v would add v h)
    assert phi[0] == PHI0
    assert abs(phi[1] - phi[0]) <= (W0 * h) ** 2 / 2 * mode * (1 + W0 * h)


@pytest.mark.parametrize("damping, band", [("damper", SECOND_ORDER), ("bearing", FIRST_ORDER)])
def test_time_stepper_order(damping, band):
    structure = oscillator(damping)
    errors = []
    for h in STEPS:
        options = SimulationOptions(solver="timestep", step=h, output_step=10 * STEPS[0])
        errors.append(max_error(simulate(structure, {}, DURATION, options=options,
                                         initial=RELEASED)))
    order = slope(STEPS, errors)
    assert band[0] <= order <= band[1], f"{damping}: observed order {order:.3f}, errors {errors}"


def test_dopri_error_follows_its_tolerance_at_fifth_order():
    structure = oscillator("damper")
    errors, steps = [], []
    for rtol in RTOLS:
        options = SimulationOptions(solver="dopri", rtol=rtol, atol=1e-2 * rtol * PHI0,
                                    output_step=0.01)
        result = simulate(structure, {}, DURATION, options=options, initial=RELEASED)
        errors.append(max_error(result))
        steps.append(result.solver["steps"])
        # the tolerance is met: the global error stays within rtol of the amplitude
        assert errors[-1] <= rtol * PHI0, f"rtol {rtol:g}: error {errors[-1]:.3g}"
    proportional = slope(RTOLS, errors)
    order = -slope(steps, errors)
    assert TOLERANCE_PROPORTIONAL[0] <= proportional <= TOLERANCE_PROPORTIONAL[1], \
        f"error ~ rtol^{proportional:.3f}: {errors}"
    assert FIFTH_ORDER[0] <= order <= FIFTH_ORDER[1], \
        f"observed order {order:.3f} (steps {steps}, errors {errors})"


def test_rosenbrock_error_follows_its_tolerance_at_fourth_order():
    """The oscillator is linear, so the Jacobian the Rosenbrock steps use is exact and
    the method shows its full order."""
    structure = oscillator("damper")
    errors, steps = [], []
    for rtol in RTOLS:
        options = SimulationOptions(solver="rosenbrock", rtol=rtol, atol=1e-2 * rtol * PHI0,
                                    output_step=0.01)
        result = simulate(structure, {}, DURATION, options=options, initial=RELEASED)
        assert result.solver["name"] == "rosenbrock"
        errors.append(max_error(result))
        steps.append(result.solver["steps"])
        assert errors[-1] <= rtol * PHI0, f"rtol {rtol:g}: error {errors[-1]:.3g}"
    proportional = slope(RTOLS, errors)
    order = -slope(steps, errors)
    assert TOLERANCE_PROPORTIONAL_4[0] <= proportional <= TOLERANCE_PROPORTIONAL_4[1], \
        f"error ~ rtol^{proportional:.3f}: {errors}"
    assert FOURTH_ORDER[0] <= order <= FOURTH_ORDER[1], \
        f"observed order {order:.3f} (steps {steps}, errors {errors})"
