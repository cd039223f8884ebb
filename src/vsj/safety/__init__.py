"""Safety figures of a run's contacts: contact events, their verdict against ISO/TS 15066,
the largest safe impact speed, and the head injury criterion.

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
`vsj.safety.head_injury`
    `hic` of an acceleration series and its closed form for a mass-spring impact
    (`hic_half_sine`, `hic_spring_impact`).

Bad arguments raise `vsj.errors.InputError` naming the function and the argument.
"""

from .events import ContactEvent, contact_events
from .head_injury import (
    HIC15_WINDOW,
    HIC36_WINDOW,
    STANDARD_GRAVITY,
    HeadInjury,
    hic,
    hic_half_sine,
    hic_spring_impact,
)
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

__all__ = ["HIC15_WINDOW", "HIC36_WINDOW", "REGIONS", "STANDARD_GRAVITY", "BodyArea",
           "BodyRegion", "ContactEvent", "HeadInjury", "SpeedLimit", "Tip", "Verdict",
           "contact_events", "hic", "hic_half_sine", "hic_spring_impact", "reduced_mass",
           "region", "robot_effective_mass", "series_stiffness", "transfer_energy_limit",
           "transient_speed_limit", "verdict"]
