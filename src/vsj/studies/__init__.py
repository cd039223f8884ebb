"""Optimisation studies on the wrist (issue 34): safe and fast, and explosive motion.

* `axis`: the wrist reduced to one output axis (`axis_model`, `AxisModel`,
  `JointTable`), read from vsj's own network;
* `impact`: the reduced impact model of an elastic joint striking a body (`impact`,
  `safe_speed`, `BodyModel`, `HAND`) and the mass-spring-mass closed form;
* `collocation`: minimum-time optimal control by Hermite-Simpson collocation and SLSQP;
* `brachistochrone`: Bicchi and Tonietti's safe brachistochrone (`SafeMotion`,
  `optimise`, `verify` on the engine);
* `explosive`: the largest link speed over the motors' (`Explosive`, `optimise_wrist`
  on the engine, `reduced_explosive`);
* `study`: both as figures with rows for ``vsj reproduce`` or a ``vsj study`` command
  (`STUDIES`, `write`, `page`), drawn by `draw`.
"""

from .axis import AxisModel, JointTable, axis_model
from .brachistochrone import STRATEGIES, SafeMotion, SafeSpeed, Strategy, optimise, \
    safe_speeds, verify
from .explosive import Explosive, ExplosiveResult, ReducedExplosive, optimise_wrist, \
    reduced_explosive
from .impact import HAND, BodyModel, Impact, force_per_speed, impact, \
    mass_spring_mass_peak, reduced_mass, safe_speed
from .study import STUDIES, explosive_motion, page, safe_and_fast, write

__all__ = ["AxisModel", "BodyModel", "Explosive", "ExplosiveResult", "HAND", "Impact",
           "JointTable", "ReducedExplosive", "STRATEGIES", "STUDIES", "SafeMotion",
           "SafeSpeed", "Strategy", "axis_model", "explosive_motion", "force_per_speed",
           "impact", "mass_spring_mass_peak", "optimise", "optimise_wrist", "page",
           "reduced_explosive", "reduced_mass", "safe_and_fast", "safe_speed", "safe_speeds",
           "verify", "write"]
