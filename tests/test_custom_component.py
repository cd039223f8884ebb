"""A user's own component in the wrist: the example runs, and Network.replace guards ports."""

import runpy
from pathlib import Path

import numpy as np
import pytest

import vsj
from vsj.components import VelocitySource
from vsj.errors import InputError

EXAMPLE = Path(__file__).parents[1] / "examples" / "custom_elastic_element.py"
EPS = np.finfo(float).eps
#: Round-off of the ledger per solver step (as in tests/test_regression.py).
LEDGER_ROUNDOFF_PER_STEP = 1e-15


def test_the_custom_elastic_element_example_runs_its_own_law():
    example = runpy.run_path(str(EXAMPLE))
    k, d = 0.3, 0.002
    runs = example["run"](stiffness=k, damping=d, duration=2.0)
    stock, bar = runs["stock VSM"], runs["torsion bar"]
    assert stock.success and bar.success, (stock.message, bar.message)
    for i in (1, 2):
        # the linear law k d is one product, and the damper's power (d s) s two: an ulp
        # of the value each
        deflection = bar[f"spring.vsm_{i}.deflection"]
        assert np.allclose(bar[f"spring.vsm_{i}.torque"], -k * deflection, rtol=EPS, atol=0)
        slip = bar[f"friction.vsm_{i}.damper.slip"]
        assert np.allclose(bar[f"friction.vsm_{i}.damper.power"], -d * slip ** 2,
                           rtol=2 * EPS, atol=0)
        # the stock element's lever friction is gone with it
        assert f"friction.vsm_{i}.lever.torque" not in bar.signals
    # the new law's energy is booked as any spring's: the ledger closes to the run's rtol
    # (its terms integrated by the state's steps), plus round-off per step
    assert bar.ledger["relative_residual"] <= (bar.solver["options"]["rtol"] + bar.solver["steps"]
                                               * LEDGER_ROUNDOFF_PER_STEP)
    assert np.max(np.abs(bar["phi_1"] - stock["phi_1"])) > 1e-3


def test_replace_refuses_unknown_names_and_missing_ports(params):
    net = vsj.build_wrist(params)
    with pytest.raises(InputError, match="no component 'vsm_3'"):
        net.replace(VelocitySource("vsm_3"))
    with pytest.raises(InputError, match="ring"):  # a source has a flange, not a ring
        net.replace(VelocitySource("vsm_1"))
