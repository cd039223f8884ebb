"""A custom elastic element in the whole wrist, in one file.

The VSM elastic elements (`vsj.components.ElasticElement`) are swapped for a
torsion bar with material damping: a linear spring ``k`` in parallel with a
damper ``d`` on the ring angle (a Kelvin-Voigt law). The new law is a
component built from the engine's own elements (`vsj.springs.LINEAR` and a
viscous `Friction` marked as a damper), so it runs with every solver and
friction law, and the energy ledger accounts for it. `Network.replace` puts it
where the VSMs were; nothing of `build_wrist` is copied.

Run: python examples/custom_elastic_element.py
"""

import numpy as np

import vsj
from vsj import springs
from vsj.inputs import Sine
from vsj.network import Component, Friction, Parts, Spring


class DampedTorsionBar(Component):
    """A linear torsion spring [N m/rad] with parallel damping [N m s/rad] on ``ring``."""

    ports = ("ring",)

    def __init__(self, name: str, *, stiffness: float, damping: float):
        super().__init__(name)
        if not (stiffness > 0.0 and damping >= 0.0):
            raise ValueError(f"{name}: need stiffness > 0 and damping >= 0")
        self.stiffness, self.damping = float(stiffness), float(damping)

    def parts(self) -> Parts:
        ring = self.port("ring")
        law = (self.stiffness,) + (0.0,) * (springs.N_PARAMETERS - 1)
        return Parts(flanges=[ring],
                     springs=[Spring(self.name, {ring: 1.0}, springs.LINEAR, law)],
                     frictions=[Friction(f"{self.name}.damper", {ring: 1.0},
                                         viscous=self.damping, damper=True)])


def run(stiffness: float = 0.3, damping: float = 0.002, duration: float = 4.0):
    """The stock wrist and the wrist with torsion bars, under the same motor motion."""
    params = vsj.params.default()
    inputs = {"motor_1": Sine(3.0, 0.5, fade_in=1.0), "motor_2": Sine(-3.0, 0.5, fade_in=1.0)}
    stock = vsj.build_wrist(params)
    bars = vsj.build_wrist(params)
    for i in (1, 2):
        bars.replace(DampedTorsionBar(f"vsm_{i}", stiffness=stiffness, damping=damping))
    return {name: vsj.simulate(net.assemble(), inputs, duration)
            for name, net in (("stock VSM", stock), ("torsion bar", bars))}


if __name__ == "__main__":
    for name, result in run().items():
        lag = np.max(np.abs(result["phi_1"]))
        print(f"{name:>12}: {result.message}; peak deflection {lag:.4f} rad, ledger residual "
              f"{result.ledger['relative_residual']:.1e}")
