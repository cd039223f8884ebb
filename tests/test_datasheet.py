"""The VSA datasheet (vsj.datasheet), written once through the command line and checked
against hand-derived relations and the linear models."""

import argparse
import base64
import html
import json
import math
import re

import numpy as np
import pytest
from test_twin import hand_matrices

from vsj import datasheet
from vsj.cli import main
from vsj.characteristics import pretension_loss, stiffness
from vsj.datasheet.compute import END_STOP, PEAK_GEOMETRY, PEAK_SLACK, deflection_limit
from vsj.cli import control as cli_control
from vsj.errors import InputError
from vsj.wrist import elastic_element

#: Quantities computed two ways from the same model (curves vs linear model,
#: closed-form kinematics): agreement to round-off of finite differences.
SAME_MODEL_TOL = 1e-8


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    out = tmp_path_factory.mktemp("datasheet")
    parser = argparse.ArgumentParser(prog="vsj")
    cli_control.register(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["datasheet", "--out", str(out), "--points", "4"])
    assert args.func(args) == 0
    sheet = json.loads((out / "datasheet.json").read_text())
    return sheet, (out / "datasheet.html").read_text()


def test_stiffness_range_and_its_dependence_on_q(params, written):
    sheet, _ = written
    per_q = sheet["per_q"]
    qs = [r["q"] for r in per_q]
    assert qs[0] == pytest.approx(params.pivot.q_max) and qs[-1] == pytest.approx(
        params.pivot.q_min)
    k_out = np.array([r["output_stiffness"] for r in per_q])
    assert np.all(np.diff(k_out) > 0.0)  # more negative q is stiffer
    ratings = sheet["ratings"]
    assert ratings["output_stiffness_min"]["value"] == k_out[0]
    assert ratings["output_stiffness_max"]["value"] == k_out[-1]
    element = elastic_element("vsm", params, "geometric")
    pg, tr = params.planetary, params.transmission
    r_rc = pg.ring_teeth / (pg.ring_teeth + pg.sun_teeth)
    # theta_x = psi = carrier / ratio and ring = carrier / r_RC with the suns held
    c = tr.ratio / r_rc
    assert sheet["ring_per_output"] == pytest.approx([c, c], rel=1e-12)
    for r in per_q:
        k_ring = stiffness(element.law, element.parameters, r["q"])
        assert r["ring_stiffness"] == pytest.approx(k_ring, rel=1e-12)
        assert r["output_stiffness"] == pytest.approx(2 * c * c * k_ring, rel=1e-12)
        assert r["output_stiffness_linear_model"] == pytest.approx(r["output_stiffness"],
                                                                   rel=SAME_MODEL_TOL)


def test_deflection_torque_and_energy(params, written):
    sheet, _ = written
    pg, tr = params.planetary, params.transmission
    r_rc = pg.ring_teeth / (pg.ring_teeth + pg.sun_teeth)
    theta_max = params.elastic_element.end_stop * r_rc / tr.ratio
    assert sheet["ratings"]["max_deflection_max"]["value"] == pytest.approx(theta_max,
                                                                            rel=1e-12)
    by_q = {r["q"]: r for r in sheet["per_q"]}
    for curve in sheet["torque_deflection"]:
        theta = np.array(curve["deflection"])
        torque = np.array(curve["torque"])
        energy = np.array(curve["energy"])
        assert theta[-1] == pytest.approx(theta_max)
        # energy is the integral of torque (trapezoid error on 241 points)
        integral = np.concatenate([[0.0], np.cumsum(np.diff(theta) * (torque[1:] + torque[:-1])
                                                    / 2)])
        assert np.max(np.abs(integral - energy)) < 1e-3 * np.max(np.abs(energy))
        # small deflections: the tangent stiffness at zero
        row = by_q.get(curve["q"])
        if row is not None:
            assert torque[1] == pytest.approx(row["output_stiffness"] * theta[1], rel=1e-2)
            assert row["peak_torque"] == pytest.approx(np.max(torque), rel=1e-12)
    stiffest = sheet["per_q"][-1]
    assert 0.0 < stiffest["peak_torque_deflection"] < theta_max  # the torque falls again


def test_output_inertia_from_the_hand_derived_mass_matrix(params, written):
    sheet, _ = written
    c = sheet["ring_per_output"][0]
    M = hand_matrices(params)["M"]
    # theta_x moves both rings by c theta_x: kinetic energy c^2 (1,1) M (1,1)^T / 2
    expected = c * c * np.sum(M)
    assert sheet["ratings"]["output_inertia_x"]["value"] == pytest.approx(expected, rel=1e-12)


def test_dynamics_against_q(params, written):
    sheet, _ = written
    per_q = sheet["per_q"]
    natural = [r["natural_frequencies"][0] for r in per_q]
    bandwidth = [r["position_bandwidth"] for r in per_q]
    assert np.all(np.diff(natural) > 0.0) and np.all(np.diff(bandwidth) > 0.0)
    for r in per_q:
        # friction linearised damps the slow modes more than the viscous part alone does
        assert all(0.0 < m["damping"] <= 1.0 + 1e-12 for m in r["modes"])
        assert max(m["damping"] for m in r["modes_viscous"]) < min(
            m["damping"] for m in r["modes"])
    # viscous only, damping falls as the setting stiffens (zeta = b / (2 sqrt(K I)))
    viscous = [min(m["damping"] for m in r["modes_viscous"]) for r in per_q]
    assert np.all(np.diff(viscous) < 0.0)
    bode = sheet["frequency_response"]
    omega = np.array(bode["omega"])
    stiffest = bode["compliance"][-1]
    assert stiffest["q"] == pytest.approx(per_q[-1]["q"])
    # static at low frequency: 1 / K_out; inertial at high frequency: 1 / (I_x omega^2)
    assert stiffest["magnitude"][0] == pytest.approx(1 / per_q[-1]["output_stiffness"],
                                                     rel=1e-3)
    # well above the modes the output is a mass: |compliance| omega^2 tends to 1 / I_x
    # (at the grid's top the linearised friction's damping still takes a few per cent)
    inertia = sheet["ratings"]["output_inertia_x"]["value"]
    for compliance in bode["compliance"]:
        apparent = 1 / (np.array(compliance["magnitude"]) * omega ** 2)
        assert apparent[-1] == pytest.approx(inertia, rel=5e-2)
        assert abs(apparent[-1] / inertia - 1) < abs(apparent[-10] / inertia - 1)
    # motors to theta_x, statically: the sun-to-carrier ratio over the transmission's
    pg = params.planetary
    ratio = pg.sun_teeth / (pg.ring_teeth + pg.sun_teeth) / params.transmission.ratio
    assert sheet["ratings"]["motor_to_output_ratio"]["value"] == pytest.approx(ratio, rel=1e-9)
    assert bode["motor_to_output"][-1]["magnitude"][0] == pytest.approx(ratio, rel=1e-3)


def test_stiffness_change_through_the_dc_motor(params, written):
    sheet, _ = written
    mo, pv = params.motor, params.pivot
    travel = (math.asin(pv.q_max / pv.amplitude) - math.asin(pv.q_min / pv.amplitude)) \
        * pv.ratio * mo.gear_ratio
    no_load = mo.voltage_limit / mo.torque_constant  # rotor speed [rad/s]
    for key in ("stiffening", "softening"):
        change = sheet["stiffness_change"][key]
        # never faster than at the no-load speed; friction costs a little more
        assert travel / no_load < change["time"] < 1.2 * travel / no_load
        assert change["electric_energy"] > 0.0
        trajectory = change["trajectory"]
        assert trajectory["q"][0] == pytest.approx(change["from_q"], abs=1e-12)
        t_end = np.interp(change["time"], trajectory["time"], trajectory["q"])
        assert t_end == pytest.approx(change["to_q"], abs=2e-5)
    assert sheet["ratings"]["stiffening_time"]["value"] == pytest.approx(
        sheet["stiffness_change"]["stiffening"]["time"])


def test_html_is_self_contained(written):
    sheet, page = written
    images = re.findall(r"<img[^>]*src=[\"']([^\"']+)[\"']", page)
    assert len(images) == 7
    for src in images:
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1])[:8] == b"\x89PNG\r\n\x1a\n"
    assert not re.search(r"(src|href)=[\"'](https?:|//|file:)", page)
    assert "<table>" in page and sheet["title"] in page
    for key in sheet["ratings"]:
        assert key.replace("_", " ") in page


def test_bad_arguments(params, tmp_path, capsys):
    with pytest.raises(InputError, match="q_points"):
        datasheet.compute(params, q_points=1)
    # a bound on the positions (each is a few linearisations), said with the option's name
    # before the output directory is made
    with pytest.raises(InputError, match=r"q_points must be an integer in 2\.\.1001"):
        datasheet.compute(params, q_points=datasheet.MAX_Q_POINTS + 1)
    assert main(["datasheet", "--out", str(tmp_path / "ds"), "--points", "100000"]) == 2
    assert "--points must be an integer in 2..1001, got 100000" in capsys.readouterr().err
    assert not (tmp_path / "ds").exists()
    with pytest.raises(InputError, match="outside the pivot range"):
        datasheet.compute(params, q_points=2, curve_qs=[0.05])


def test_maximum_deflection_is_held_and_names_its_limit(params, written):
    """Issue 30: the maximum deflection lay past the torque peak. At each setting it is
    the end stop or the torque peak, whichever comes first, and says which."""
    sheet, page = written
    pg, tr = params.planetary, params.transmission
    r_rc = pg.ring_teeth / (pg.ring_teeth + pg.sun_teeth)
    at_stop = params.elastic_element.end_stop * r_rc / tr.ratio
    per_q = sheet["per_q"]
    for r in per_q:
        held, limit = r["max_deflection"], r["max_deflection_limit"]
        assert limit in (END_STOP, PEAK_SLACK, PEAK_GEOMETRY)
        assert held == r["peak_torque_deflection"]  # the torque rises all the way to it
        if limit == END_STOP:
            assert held == pytest.approx(at_stop, rel=1e-12)
        else:
            assert held < at_stop
        assert f"<td class=l>{html.escape(limit)}</td>" in page
    # the soft end reaches the stop; the stiff end peaks first (fig 3.5: the lever's swing)
    assert per_q[0]["max_deflection_limit"] == END_STOP
    assert per_q[-1]["max_deflection_limit"] != END_STOP
    ratings = sheet["ratings"]
    for key, pick in (("max_deflection_max", max), ("max_deflection_min", min)):
        chosen = pick(per_q, key=lambda r: r["max_deflection"])
        assert ratings[key]["value"] == chosen["max_deflection"]
        assert chosen["max_deflection_limit"].split(":")[0] in ratings[key]["note"]
    strongest = max(per_q, key=lambda r: r["peak_torque"])
    assert ratings["peak_torque"]["value"] == strongest["peak_torque"]
    assert f"{strongest['max_deflection']:.3g} rad" in ratings["peak_torque"]["note"]
    # on the drawn curves: the largest torque up to the maximum deflection is at it, and
    # past a torque peak the torque falls
    for curve in sheet["torque_deflection"]:
        theta, torque = np.array(curve["deflection"]), np.array(curve["torque"])
        k = int(np.searchsorted(theta, curve["max_deflection"]))
        assert theta[k] == curve["max_deflection"]
        assert np.argmax(torque[:k + 1]) == k
        if curve["max_deflection_limit"] != END_STOP:
            assert torque[k + 1] < torque[k]


def test_a_torque_peak_at_a_spring_going_slack_is_named_so(params):
    """The limit's cause from the springs' state at the peak: a peak where a spring goes
    slack (or taut again) is named so, one elsewhere is the lever's geometry, a torque
    still rising at the stop is the end stop. The peaks are placed by hand on the real
    geometry at q = -0.4 cm, where spring b goes slack and taut again within the stop."""
    element = elastic_element("vsm", params, "geometric")
    q = -0.004
    theta = np.linspace(0.0, params.elastic_element.end_stop, 701)
    slack = pretension_loss(element.parameters, q)
    assert 0.0 < slack < theta[-1]
    one = np.array([1.0])  # theta is the ring deflection
    for peak_at, expected in ((slack, PEAK_SLACK), (1.0, PEAK_GEOMETRY)):
        index, limit = deflection_limit(element, one, q, theta,
                                                -(theta - peak_at) ** 2)
        assert limit == expected
        assert abs(theta[index] - peak_at) <= theta[1] - theta[0]
    index, limit = deflection_limit(element, one, q, theta, theta.copy())
    assert (index, limit) == (len(theta) - 1, END_STOP)


def test_every_number_of_the_tables_has_its_unit(written):
    """datasheet.json gives the unit of each number of its tables (per_q and its modes,
    the curves, the frequency grid): the per-q frequencies are rad/s where the ratings
    give Hz, a factor 2 pi a reader could not tell from the keys."""
    sheet, _ = written
    units = sheet["units"]
    words = {"modes_viscous", "modes", "max_deflection_limit"}  # tables, or a name
    keys = set(sheet["per_q"][0]) - words
    keys |= set(sheet["per_q"][0]["modes"][0]) | {"omega"}
    keys |= set(sheet["torque_deflection"][0]) - words
    assert keys <= set(units), sorted(keys - set(units))
    assert units["natural_frequencies"] == "rad/s"
    rating = sheet["ratings"]["natural_frequency_min"]
    assert rating["unit"] == "Hz"
    lowest = min(r["natural_frequencies"][0] for r in sheet["per_q"])
    assert rating["value"] == pytest.approx(lowest / (2 * np.pi), rel=1e-12)
