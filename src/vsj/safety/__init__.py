"""Safety figures of a run's contacts: contact events, their verdict against ISO/TS 15066
and the largest safe impact speed.

The functions work on sampled signals and plain numbers, whatever computed them (the
engine's contact element, a measurement), and use NumPy only.

`vsj.safety.iso_ts_15066`
    The ISO/TS 15066:2016 body model for the hand and the lower arm (`REGIONS`, each
    value with its table, row and source), `verdict`, `transient_speed_limit`,
    `transfer_energy_limit`, the reduced mass and the robot's effective mass, and the
    contact `Tip` that turns a force into a pressure.
`vsj.safety.events`
    `contact_events`: the contact events of a run's signals, each a `ContactEvent` with
    its peak force, impulse, duration, energy transferred to the body, peak deflection
    and spring torque of the joint and margin to its end stop.

Bad arguments raise `vsj.errors.InputError` naming the function and the argument.
"""

from .events import ContactEvent, contact_events
from .iso_ts_15066 import (
    REGIONS,
    BodyArea,
    BodyRegion,
    SpeedLimit,
    Tip,
    Verdict,
    reduced_mass,
    region,
    robot_effective_mass,
    series_stiffness,
    transfer_energy_limit,
    transient_speed_limit,
    verdict,
)

__all__ = ["REGIONS", "BodyArea", "BodyRegion", "ContactEvent", "SpeedLimit", "Tip",
           "Verdict", "contact_events", "reduced_mass", "region", "robot_effective_mass",
           "series_stiffness", "transfer_energy_limit", "transient_speed_limit", "verdict"]
