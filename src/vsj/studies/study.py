"""The two trade-off studies as figures with their numbers (issue 34).

Each study is a function ``study(ctx) -> vsj.reproduce.base.Figure`` with the signature
of the report's figures, so that ``vsj reproduce`` (or a ``vsj study`` command) can run
it beside them: it computes, returns its data (plain arrays in SI units), its rows (with
the reproduction's categories) and its caption, and draws only when asked
(`vsj.studies.draw`). Nothing here is in the report, so no row has a report value to
compare with: each says, in its source, which published finding it tests.

``study-safe-and-fast``
    Bicchi and Tonietti's safe brachistochrone on the wrist's ``theta_x``
    (`vsj.studies.brachistochrone`): the rigid reference, the stiffest setting, the best
    fixed setting and the optimised stiffness schedule, then the optimal commands run
    through the engine with strikes on a hand surrogate.
``study-explosive-motion``
    the largest ``theta_x`` speed over the motors' speed limit
    (`vsj.studies.explosive`): the voltage profile and the stiffness setting optimised
    with every candidate run by the engine, the optimiser's convergence, what limits
    the result, and the ratio over the stiffness setting.

`write` puts a study's PNG, SVG and JSON (rows and data) in a directory.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..output import atomic_write
from ..params import Parameters
from ..plots import save
from ..reproduce.base import INPUT, LIMIT, NOT_STATED, Context, Figure, Row
from . import draw
from .axis import AxisModel, axis_model
from .brachistochrone import (SafeMotion, integrated_error, optimise, safe_speeds, verify,
                              with_tip)
from .collocation import SMOOTHING
from .explosive import Explosive, optimise_wrist, reduced_explosive

#: The statement each study's rows belong to (one entry each in the page's headline).
SAFE_STATEMENT = "safe brachistochrone (Bicchi and Tonietti 2004)"
EXPLOSIVE_STATEMENT = ("explosive motion (Haddadin et al. 2011; Garabini et al. 2011; "
                       "Braun et al. 2012)")
#: The pivot moves this share of its range above both ends of the motion for a schedule
#: to count as going soft in the middle: 5 % of 4.2 cm is 2 mm, about the pivot's travel
#: in 0.1 s at its drive's no-load speed.
SOFTENING = 0.05
#: A relative difference of minimum times counts from here: the controls' smoothing term
#: moves an optimum's T by at most SMOOTHING times the largest squared step of a scaled
#: control (4), and every strategy is solved on the same grid, so what the grid itself
#: misses is common to them.
RESOLUTION = 4 * SMOOTHING


def _context(ctx) -> Context:
    if not isinstance(ctx, Context):
        raise InputError(f"a study needs a vsj.reproduce.base.Context, got "
                         f"{type(ctx).__name__}")
    if not isinstance(ctx.params, Parameters):
        raise InputError(f"a study's context needs a vsj.params.Parameters set, got "
                         f"{type(ctx.params).__name__}")
    return ctx


def _not_stated(published: str) -> str:
    return f"{NOT_STATED} (new study; published: {published})"


def safe_setup(reduced: bool) -> SafeMotion:
    """The safe-and-fast problem the study solves (smaller when ``reduced``)."""
    if reduced:
        return SafeMotion(nodes=20, safety_points=6, fixed_candidates=4)
    return SafeMotion(nodes=30, safety_points=15, fixed_candidates=7)


def _stiff_soft_stiff(q: np.ndarray, span: float) -> bool:
    """Whether a schedule (``q`` at evenly spaced nodes, higher is softer) goes stiff,
    soft, stiff: its softest over the middle three fifths of the motion is `SOFTENING` of
    the range above its softest over the first fifth and over the last fifth."""
    n = len(q)
    first, last = q[:max(1, n // 5)], q[n - max(1, n // 5):]
    middle = q[n // 5:n - n // 5]
    top = np.max(middle)
    return bool(top - np.max(first) >= SOFTENING * span
                and top - np.max(last) >= SOFTENING * span)


def safe_and_fast(ctx: Context, setup: SafeMotion | None = None,
                  model: AxisModel | None = None) -> Figure:
    """The safe brachistochrone study (see the module's notes) as a `Figure`.

    Data: ``distance`` [rad], ``link`` [m], ``body`` (name, mass [kg], stiffness [N/m],
    force_limit [N], source), ``no_load_speed`` [rad/s]; ``safe``: ``q`` [m],
    ``stiffness`` [N m/rad], ``speed`` and ``first_contact_speed`` [rad/s] (every
    contact, the first alone), ``rigid_speed`` [rad/s]; ``strategies``: per strategy its
    ``name``, ``T`` [s], and over ``time`` [s] the ``link_speed`` [rad/s], ``q`` [m],
    ``voltage`` [V] and ``deflection`` [rad] (NaN where a rigid joint has none);
    ``candidates``: the fixed settings tried, ``q`` [m] and ``T`` [s]; ``verification``:
    per verified strategy the engine's ``time`` [s], ``speed`` [rad/s], ``q`` [m], and
    the strikes' ``instants`` [s], ``first_peak``, ``peak``, ``predicted_first`` and
    ``predicted`` [N], ``final_error`` and ``residual`` [rad]."""
    ctx = _context(ctx)
    setup = setup or safe_setup(ctx.reduced)
    setup.check()
    model = model or axis_model(ctx.params)
    safe = safe_speeds(model, setup)
    found = optimise(model, setup)
    data = {"distance": setup.distance, "link": setup.link, "tip_mass": setup.tip_mass,
            "body": {"name": setup.body.name, "mass": setup.body.mass,
                     "stiffness": setup.body.stiffness,
                     "force_limit": setup.body.force_limit, "source": setup.body.source},
            "no_load_speed": model.no_load_speed, "q_range": (model.q_min, model.q_max),
            "safe": {"q": safe.q, "stiffness": safe.stiffness, "speed": safe.speed,
                     "first_contact_speed": setup.body.force_limit
                     / (safe.first_contact * setup.link),
                     "rigid_speed": safe.rigid_speed},
            "strategies": [], "candidates": {"q": np.array([]), "T": np.array([])},
            "verification": []}
    for name, s in found.items():
        data["strategies"].append({
            "name": name, "T": s.T, "time": s.solution.time, "link_speed": s.link_speed,
            "q": s.q, "voltage": s.solution.controls[:, 0], "deflection": s.deflection,
            "iterations": s.solution.iterations})
        if s.candidates:
            data["candidates"] = {"q": np.array(list(s.candidates)),
                                  "T": np.array(list(s.candidates.values()))}
    verified = []
    for name in ("stiffest", "best fixed", "schedule"):
        if name not in found:
            continue
        if name == "best fixed" and found[name].q[0] == found["stiffest"].q[0]:
            continue  # the same setting: the stiffest's run shows it
        v = verify(ctx.params, found[name], setup, model=model)
        verified.append(v)
        every = max(1, len(v.time) // 2000)
        data["verification"].append({
            "strategy": name, "time": v.time[::every], "speed": v.speed[::every],
            "q": v.q[::every], "instants": v.instants, "first_peak": v.first_peak,
            "peak": v.peak, "predicted_first": v.predicted_first,
            "predicted": v.predicted, "final_error": v.final_error, "residual": v.residual,
            "touch_speed": v.touch_speed})
    rows = _safe_rows(model, setup, safe, found, verified)
    for name, s in found.items():
        error = integrated_error(with_tip(model, setup), s)
        if math.isfinite(error):
            rows.append(Row(f"reduced model: {name}'s commands integrated, theta_x's miss at "
                            "the end", NOT_STATED, error, "rad", "vsj.studies.collocation",
                            f"the collocation's own error ({setup.nodes} Hermite-Simpson "
                            "intervals), against DOP853 on the same model",
                            statement=SAFE_STATEMENT))
    T = {n: s.T for n, s in found.items()}
    caption = (f"Safe and fast (new; tests Bicchi and Tonietti 2004): the minimum time to "
               f"turn theta_x by {setup.distance:g} rad from rest to rest while an impact "
               f"of a {setup.link * 100:g} cm link on the {setup.body.name} stays within "
               f"{setup.body.force_limit:g} N. Rigid joint {T.get('rigid', math.nan) * 1e3:.1f}"
               f" ms, stiffest setting {T.get('stiffest', math.nan) * 1e3:.1f} ms, best fixed "
               f"{T.get('best fixed', math.nan) * 1e3:.1f} ms, schedule "
               f"{T.get('schedule', math.nan) * 1e3:.1f} ms (instant stiffness changes "
               f"{T.get('instant schedule', math.nan) * 1e3:.1f} ms). Reduced model "
               "optimised by collocation, then run on the whole wrist by the engine with "
               "strikes on a hand surrogate. No report value: a new study.")
    return Figure("study-safe-and-fast", data, caption, rows, draw=draw.safe_and_fast)


def _safe_rows(model, setup, safe, found, verified) -> list[Row]:
    src = "Bicchi and Tonietti 2004"
    rows = [
        Row("motion", NOT_STATED, setup.distance, "rad", "study set-up",
            "theta_x from rest to rest, theta_y held", category=INPUT,
            statement=SAFE_STATEMENT),
        Row("link length to the point of impact", NOT_STATED, setup.link, "m",
            "study set-up", "an assumed end-effector link (the wrist's own has none)",
            category=INPUT, statement=SAFE_STATEMENT),
        Row(f"{setup.body.name}: effective mass", NOT_STATED, setup.body.mass, "kg",
            setup.body.source, "used as given", category=INPUT, statement=SAFE_STATEMENT),
        Row(f"{setup.body.name}: contact stiffness", NOT_STATED, setup.body.stiffness, "N/m",
            setup.body.source, "used as given", category=INPUT, statement=SAFE_STATEMENT),
        Row(f"{setup.body.name}: transient force limit", NOT_STATED,
            setup.body.force_limit, "N", setup.body.source, "used as given",
            category=INPUT, statement=SAFE_STATEMENT),
        Row("motors' speed limit at theta_x", NOT_STATED, model.no_load_speed, "rad/s",
            "parameter set [motor]", "no-load speed at the voltage limit through the rigid "
            "kinematics", category=INPUT, statement=SAFE_STATEMENT),
        Row("safe link speed, rigid joint", _not_stated("the rigid joint is the slowest"),
            safe.rigid_speed, "rad/s", src, "the rotors and link as one mass on the body "
            "(the mass-spring-mass closed form)", statement=SAFE_STATEMENT),
        Row("safe link speed, stiffest setting", NOT_STATED, float(safe.speed[0]), "rad/s",
            src, "reduced impact model, every contact of the collision",
            statement=SAFE_STATEMENT),
        Row("safe link speed, softest setting", NOT_STATED, float(safe.speed[-1]), "rad/s",
            src, "reduced impact model, every contact of the collision",
            statement=SAFE_STATEMENT),
        Row("the stiffest joint seen at the tip, over the body's contact stiffness",
            NOT_STATED, float(np.max(safe.stiffness)) / (setup.body.stiffness
                                                         * setup.link ** 2), "-", src,
            "far below 1: an impact meets the link alone at every setting, the rotors "
            "behind the spring only later; above 1 the rotors would strike with the link",
            statement=SAFE_STATEMENT),
    ]
    span = model.q_max - model.q_min
    for name, s in found.items():
        note = f"{s.solution.iterations} SLSQP iterations, converged"
        if name == "best fixed":
            note += f"; at q = {s.q[0] * 100:.2f} cm"
        rows.append(Row(f"minimum time, {name}", NOT_STATED, s.T, "s", src, note,
                        statement=SAFE_STATEMENT))
    elastic = [n for n in ("stiffest", "best fixed", "schedule") if n in found]
    if "rigid" in found and elastic:
        best = min(found[n].T for n in elastic)
        rows.append(Row("the elastic joint is faster than a rigid one at the same bound",
                        _not_stated("yes"), "yes" if best < found["rigid"].T else "no", "",
                        src, f"best of {', '.join(elastic)}: {best * 1e3:.2f} ms against the "
                        f"rigid joint's {found['rigid'].T * 1e3:.2f} ms",
                        statement=SAFE_STATEMENT))
    for base in ("stiffest", "best fixed"):
        if base in found and "schedule" in found:
            gain = 1.0 - found["schedule"].T / found[base].T
            rows.append(Row(f"a stiffness schedule beats the {base} setting",
                            _not_stated("yes"), "yes" if gain > RESOLUTION else "no", "", src,
                            f"the schedule takes {gain * 100:.2f} % less time (counted from "
                            f"{RESOLUTION * 100:g} %, what the collocation's smoothing can "
                            "move)", statement=SAFE_STATEMENT))
    for name in ("schedule", "instant schedule"):
        if name in found:
            q = found[name].q
            rows.append(Row(f"{name}: stiff, then soft, then stiff", _not_stated("yes"),
                            "yes" if _stiff_soft_stiff(q, span) else "no", "", src,
                            f"q from {q[0] * 100:.2f} cm, softest {np.max(q) * 100:.2f} cm at "
                            f"{np.argmax(q) / (len(q) - 1):.0%} of the motion, to "
                            f"{q[-1] * 100:.2f} cm (counted when the middle three fifths "
                            f"reach {SOFTENING:.0%} of the range softer than the first and "
                            "the last fifth)", statement=SAFE_STATEMENT))
    for v in verified:
        worst = float(np.max(v.peak)) / setup.body.force_limit
        first = float(np.max(v.first_peak)) / setup.body.force_limit
        rows.append(Row(f"engine: strikes on the {setup.body.name}, {v.strategy}, largest "
                        "peak over the bound", NOT_STATED, worst, "-", "vsj engine",
                        f"first contacts at most {first:.2f} of the bound; reduced model "
                        f"predicted first contacts {np.max(v.predicted_first):.1f} N against "
                        f"the engine's {np.max(v.first_peak):.1f} N", statement=SAFE_STATEMENT))
        rows.append(Row(f"engine: theta_x error at the end, {v.strategy}", NOT_STATED,
                        v.final_error, "rad", "vsj engine",
                        f"largest after T: {v.residual:.3g} rad (Coulomb friction and the "
                        "neglects of the reduced model, run open loop)",
                        statement=SAFE_STATEMENT))
    return rows


def explosive_setup(reduced: bool) -> tuple[Explosive, tuple[float, ...], int]:
    """The explosive problem the study solves, the pivot positions of its sweep [m] and
    the sweep's iterations (smaller when ``reduced``)."""
    if reduced:
        return Explosive(window=0.1, knots=8, max_iterations=4), (-0.022, -0.01), 2
    return Explosive(window=0.2, knots=20, max_iterations=60), \
        (-0.022, -0.016, -0.01, -0.004, 0.002), 15


def explosive_motion(ctx: Context, setup: Explosive | None = None,
                     sweep: tuple[float, ...] | None = None, sweep_iterations: int | None = None,
                     model: AxisModel | None = None) -> Figure:
    """The explosive-motion study (see the module's notes) as a `Figure`.

    First the voltage profile is optimised at each fixed setting of ``sweep`` [m]
    (``sweep_iterations`` SLSQP iterations each, from the reduced model's optimum), then
    profile and setting together from the best of them (``setup``, whose ``q`` must be
    None). Data: ``history`` (the ratio after each iteration of that last optimisation),
    ``history_fixed`` (the same for the fixed setting it started from, at ``fixed_q``
    [m]), ``times`` [s] and ``voltages`` [V] of the optimal profile, the run's ``time`` [s],
    ``speed`` and ``motor_speed`` [rad/s], ``deflection`` (the larger ring angle [rad])
    and ``voltage`` [V]; ``no_load_speed`` [rad/s], ``ratio``, ``q`` [m], ``end_stop``
    [rad], ``holdable`` (the ring angle at the joint's torque peak at q [rad]),
    ``limits`` (`limits_of`); ``sweep``: ``q`` [m] and ``ratio`` at the fixed settings;
    ``reduced``: the linear, friction-free model's ratio at q, elastic and rigid."""
    ctx = _context(ctx)
    default, default_sweep, default_iterations = explosive_setup(ctx.reduced)
    setup = setup or default
    setup.check()
    if setup.q is not None:
        raise InputError("explosive motion study: setup.q must be None (the study optimises "
                         "the setting; give fixed settings as its sweep)")
    sweep = default_sweep if sweep is None else tuple(sweep)
    sweep_iterations = default_iterations if sweep_iterations is None else sweep_iterations
    if not sweep:
        raise InputError("explosive motion study: the sweep needs at least one pivot "
                         "position")
    model = model or axis_model(ctx.params)
    for q in sweep:
        if not (isinstance(q, (int, float)) and model.q_min <= q <= model.q_max):
            raise InputError(f"explosive motion: sweep position {q!r} m is outside the "
                             f"pivot's range [{model.q_min:g}, {model.q_max:g}] m")
    swept = [optimise_wrist(ctx.params, replace(setup, q=float(q),
                                                max_iterations=sweep_iterations), model=model)
             for q in sweep]
    start = max(swept, key=lambda r: r.ratio)
    best = optimise_wrist(ctx.params, setup, model=model, start=(start.voltages, start.q))
    lin = reduced_explosive(model, best.q, window=setup.window, knots=setup.knots,
                            tail=setup.tail)
    rig = reduced_explosive(model, best.q, window=setup.window, knots=setup.knots,
                            tail=setup.tail, rigid=True)
    end_stop = float(ctx.params["elastic_element.end_stop"])
    ring_per_output = end_stop / float(np.max(model.joint.deflection))
    every = max(1, len(best.time) // 4000)
    data = {"history": np.array(best.history), "history_fixed": np.array(start.history),
            "fixed_q": start.q, "times": best.times,
            "voltages": best.voltages, "time": best.time[::every],
            "speed": best.speed[::every], "motor_speed": best.motor_speed[::every],
            "deflection": best.deflection[::every], "voltage": best.voltage[::every],
            "no_load_speed": best.no_load_speed, "ratio": best.ratio, "q": best.q,
            "end_stop": end_stop,
            "holdable": float(model.joint.holdable_deflection(best.q)[0]) * ring_per_output,
            "limits": best.limits, "success": best.success, "message": best.message,
            "evaluations": best.evaluations + sum(r.evaluations for r in swept),
            "sweep": {"q": np.array(sweep, dtype=float),
                      "ratio": np.array([r.ratio for r in swept])},
            "reduced": {"elastic": lin.ratio, "rigid": rig.ratio},
            "window": setup.window}
    rows = _explosive_rows(best, lin, rig, sweep, swept, end_stop, setup.window)
    caption = (f"Explosive motion (new; tests Haddadin et al. 2011, Garabini et al. 2011, "
               f"Braun et al. 2012): the voltage profile over {setup.window * 1e3:g} ms "
               f"({setup.knots} knots) and the stiffness setting optimised for the largest "
               f"theta_x speed, every candidate run by the engine: {best.peak_speed:.1f} rad/s"
               f", {best.ratio:.2f} times the motors' speed limit at theta_x "
               f"({best.no_load_speed:.1f} rad/s), at q = {best.q * 100:.2f} cm. A rigid "
               "joint cannot pass 1. No report value: a new study.")
    return Figure("study-explosive-motion", data, caption, rows, draw=draw.explosive_motion)


def _still_growing(best) -> bool:
    """Whether the swing still grows at the window's end: the ring's largest deflection
    in the window's last quarter above that of the quarter before."""
    t, d, w = best.time, best.deflection, best.times[-1]
    last = d[(t > 0.75 * w) & (t <= w)]
    before = d[(t > 0.5 * w) & (t <= 0.75 * w)]
    return bool(len(last) and len(before) and np.max(last) > np.max(before))


def _explosive_rows(best, lin, rig, sweep, swept, end_stop, window) -> list[Row]:
    src = "Haddadin et al. 2011; Garabini et al. 2011; Braun et al. 2012"
    lim = best.limits
    tail = best.history[-11:]
    converged = "converged" if best.success else (
        f"did not converge ({best.message}: the ratio is the best it had run, up by "
        f"{tail[-1] - tail[0]:.2g} over its last {len(tail) - 1} iterations)")
    rows = [
        Row("peak theta_x speed over the motors' speed limit", _not_stated(
            "about 2 on hardware VSAs"), best.ratio, "-", src,
            f"engine runs of the whole wrist; SLSQP {converged} after "
            f"{len(best.history) - 1} iterations, {best.evaluations} runs; from "
            f"{best.start_ratio:.2f} at the best fixed setting's optimum",
            statement=EXPLOSIVE_STATEMENT),
        Row("the same, reduced model (linear joint, no Coulomb friction)", NOT_STATED,
            lin.ratio, "-", src, "the axis linearised at the optimum's q",
            statement=EXPLOSIVE_STATEMENT),
        Row("the same, rigid joint (reduced model)", _not_stated("1"), rig.ratio, "-", src,
            "a rigid joint never passes its motors' no-load speed; below 1 by the "
            "viscous friction and the motors' time constant", statement=EXPLOSIVE_STATEMENT),
        Row("optimal stiffness setting", NOT_STATED, best.q, "m", src, "optimised with the "
            "profile", statement=EXPLOSIVE_STATEMENT),
        Row("voltage profile at the limit", NOT_STATED, lim["voltage"], "-", "parameter set "
            "[motor] voltage_limit", "share of the knots at +-V_max: a bang-bang profile "
            "means the motors' voltage limits the result", category=LIMIT,
            statement=EXPLOSIVE_STATEMENT),
        Row("largest ring deflection over the end stop", NOT_STATED, lim["end_stop"], "-",
            f"end stop {end_stop:g} rad", "1: the end stop limits the swing", category=LIMIT,
            statement=EXPLOSIVE_STATEMENT),
        Row("largest joint deflection over its torque peak", NOT_STATED, lim["holdable"], "-",
            "elastic element's law", "above 1 the link swings past the joint's torque peak "
            "(the springs' lever arm shrinks)", category=LIMIT, statement=EXPLOSIVE_STATEMENT),
        Row("share of the run with a spring slack", NOT_STATED, lim["slack"], "-",
            "elastic element's law", "a slack spring stores nothing", category=LIMIT,
            statement=EXPLOSIVE_STATEMENT),
        Row("motor side's largest speed over its no-load speed", NOT_STATED,
            lim["motor_speed"], "-", "parameter set [motor]", "above 1 the spring drives "
            "the motors back", category=LIMIT, statement=EXPLOSIVE_STATEMENT),
        Row("the motors' time to swing it up", NOT_STATED, window, "s", "study set-up",
            "the swing still grows at the window's end: a longer window pumps more"
            if _still_growing(best) else "the swing had stopped growing before the end",
            category=LIMIT, statement=EXPLOSIVE_STATEMENT),
        Row("largest motor current", NOT_STATED, lim["peak_current"], "A",
            "parameter set [motor]", "the parameter set gives no current limit",
            category=LIMIT, statement=EXPLOSIVE_STATEMENT),
    ]
    for q, r in zip(sweep, swept):
        how = "converged" if r.success else f"stopped: {r.message}"
        rows.append(Row(f"ratio at fixed q = {q * 100:.1f} cm", NOT_STATED, r.ratio, "-", src,
                        f"optimised voltage profile at this setting ({len(r.history) - 1} "
                        f"iterations, {how})", statement=EXPLOSIVE_STATEMENT))
    return rows


#: The studies by name, as `vsj.reproduce` names its figures.
STUDIES = {"study-safe-and-fast": safe_and_fast, "study-explosive-motion": explosive_motion}


def _plain(value):
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, (np.integer, np.bool_)):
        return value.item()
    return value


#: What each study tests, for its page: the published finding, and what is new.
FINDINGS = {
    "study-safe-and-fast": (
        "Bicchi and Tonietti (2004) found that a joint whose stiffness can change during a "
        "motion reaches a target sooner than a stiff one under the same collision force "
        "bound, with a schedule that is stiff at the start and the end and soft in the "
        "middle. The study solves that problem with the wrist's own parameters and reports "
        "what they give, whether or not it matches the finding."),
    "study-explosive-motion": (
        "Haddadin et al. (2011), Garabini et al. (2011) and Braun et al. (2012) found that an "
        "elastic joint, driven with an optimised motor and stiffness profile, can throw its "
        "link at about twice the speed the motor alone allows, where a stiff joint reaches "
        "once that speed. The study computes the wrist's ratio and says what limits it."),
}


def page(figure: Figure, png: bytes) -> str:
    """A study's HTML page: its caption, the figure (``png``, the PNG `write` made), what
    it tests and what is new, and its rows by category, as the reproduction shows them."""
    # lazy: the reproduction's row tables load every figure module; pages only need them
    from ..reproduce import rows_by_category
    from .. import pages  # lazy: as above

    if not isinstance(figure, Figure) or figure.name not in FINDINGS:
        raise InputError(f"page: one of the studies {', '.join(FINDINGS)}, got "
                         f"{getattr(figure, 'name', type(figure).__name__)!r}")
    body = ["<p class=headline>" + pages.esc(figure.caption) + " <span class='synthetic'>"
            "model study: no measurement</span></p>",
            pages.figure(png, f"{figure.name}.png (and .svg beside it); its numbers are "
                              f"in {figure.name}.json"),
            "<p>" + pages.esc("What it tests: " + FINDINGS[figure.name]) + "</p>",
            "<p>" + pages.esc("What is new: the report has no such study, so no row has a "
                              "report value to compare with; each row's category says what "
                              "kind of number it is, as in the reproduction.") + "</p>",
            rows_by_category([(figure.name, r) for r in figure.rows])]
    return pages.document(f"vsj study: {figure.name.removeprefix('study-')}", body)


def write(figure: Figure, directory: str | Path) -> list[Path]:
    """Write a study's ``<name>.png``, ``<name>.svg``, ``<name>.json`` (caption, rows
    with their categories and verdicts, and the data) and ``<name>.html`` (`page`) into
    ``directory``, each file atomically; returns the paths. A command that writes a result set wraps this in
    `vsj.output.ResultSet`."""
    if not isinstance(figure, Figure):
        raise InputError(f"write: a study's Figure, got {type(figure).__name__}")
    directory = Path(directory)
    if not directory.is_dir():
        raise InputError(f"write: {directory} is not a directory")
    png = directory / f"{figure.name}.png"
    save(figure.figure, png, svg=True)
    record = {"name": figure.name, "caption": figure.caption,
              "rows": [{"quantity": r.quantity, "category": r.category,
                        "statement": r.statement, "report": r.report, "vsj": r.vsj,
                        "unit": r.unit, "source": r.source, "note": r.note,
                        "verdict": r.verdict()} for r in figure.rows],
              "data": figure.data}
    path = directory / f"{figure.name}.json"
    with atomic_write(path) as handle:
        handle.write(json.dumps(_plain(record), indent=1))
    html = directory / f"{figure.name}.html"
    with atomic_write(html) as handle:
        handle.write(page(figure, png.read_bytes()))
    return [png, png.with_suffix(".svg"), path, html]


__all__ = ["EXPLOSIVE_STATEMENT", "FINDINGS", "SAFE_STATEMENT", "STUDIES", "explosive_motion",
           "explosive_setup", "page", "safe_and_fast", "safe_setup", "write"]
