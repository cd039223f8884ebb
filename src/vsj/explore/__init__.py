"""``vsj explore``: the joint in the browser, its response redrawn as its controls move.

`vsj.explore.setting` is the model side (no web library): a `Setting` of the controls,
written as a scenario and a parameter set that ``vsj simulate`` runs to the same result,
and the numbers the views show. `vsj.explore.app` is the page (a Bokeh server
application), imported only by ``vsj explore``.
"""

from .setting import (CONTROLLERS, ELASTIC, ENVIRONMENTS, FRICTION_KEYS, REFERENCES, Control,
                      Explorer, Ledger, Setting, View)

__all__ = ["CONTROLLERS", "Control", "ELASTIC", "ENVIRONMENTS", "Explorer", "FRICTION_KEYS",
           "Ledger", "REFERENCES", "Setting", "View"]
