"""Sub-models of the wrist, one module per physical part, all on flanges (`vsj.ports`)."""

from .basic import (
    Bearing,
    Fixed,
    IdealGear,
    Inertia,
    SpringDamper,
    TorqueSource,
    VelocitySource,
)
from .clutch import Brake, Clutch
from .contact import Contact
from .differential import Differential
from .elastic_element import ElasticElement
from .motor import DCMotor
from .pivot import FixedPivot, PivotMechanism
from .planetary import IdealPlanetary, PlanetaryGearModule
from .transmission import Transmission

__all__ = [
    "Bearing", "Brake", "Clutch", "Contact", "DCMotor", "Differential", "ElasticElement", "Fixed",
    "FixedPivot", "IdealGear", "IdealPlanetary", "Inertia", "PivotMechanism",
    "PlanetaryGearModule", "SpringDamper", "TorqueSource", "Transmission", "VelocitySource",
]
