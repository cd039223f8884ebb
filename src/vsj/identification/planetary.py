"""The planetary module's physical friction parameters from both bench tests.

Report section 4.1.3 and fig 4.7: the fixed-sun and fixed-ring curves are two
views of one gear set. Each curve alone only gives three constants (c1..c3 or
c4..c6); the physical parameters behind them (bearing viscous and stiction
coefficients of sun, ring and carrier, the mesh stiction k_1 and its sharpness
k_b1, and the tooth ratio x = N_S/N_R) must explain both at once.

The model is the module's own (`PlanetaryGearModule.closed_form_torque`, eq
3.28-3.29 with bearing stiction): for a given tooth ratio and sharpness the
torque is linear in the seven coefficients, so the fit is a variable projection:
an outer search over (x, k_b1) and, inside it, non-negative least squares for
the seven coefficients. Two model structures are compared:

* ``mesh``: mesh friction and viscous bearings only (the report's first model);
* ``bearing-stiction``: stiction in the bearings too (the report's final model).

A structure *explains* the data when a chi-square test of its deviations does
not reject it: each point's noise is the scatter of its curve about the curve's
own free fit (eq 4.2), but never less than 0.5 % of the curve's range. When neither does, the result says so and no parameters are
offered as an answer (the report's old prototype). Parameters the data cannot
separate (for example b_C from b_R: only b_C + b_R (1 + x)^2 is measured) are
listed with the combinations that are determined.

Two warnings go with a structure that passes the test:

* *over-parameterised*: the structure has more coefficients than two curves
  determine (each curve gives three constants, eq 4.2). The viscous
  coefficients enter only as ``b_C + b_R (1+x)^2`` and ``b_C + b_S (1+1/x)^2``,
  the bearing stiction only as ``k_C + k_R (1+x)`` and ``k_C + k_S (1+1/x)``,
  so the best set is one of a family that gives the very same curves
  (`StructureFit.same_curves`: the range of each coefficient over that family,
  every coefficient >= 0). The tooth ratio is one of many too when the test
  accepts the structure over a range of x (`StructureFit.tooth_ratio_accepted`).
* *chi-square too small*: a chi-square far below its degrees of freedom (its
  lower tail below the significance) means the assumed noise is too large for
  the deviations (the model allowance dominates the curves' own scatter) or the
  model over-fits: the test then accepts without discriminating, and says so.

`parameter_overrides` writes everything the fit chose (every coefficient, the
zeros included, the sharpness, and the tooth counts that encode x) and
`bench_curves` runs the bench forward from a parameter set, so a written file
can be checked against the fitted curves.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import special
from scipy.optimize import least_squares, linprog, nnls

from ..benches import planetary_bench
from ..components.planetary import PlanetaryGearModule
from ..errors import InputError
from ..inputs import Constant
from ..params import SCHEMA
from ..simulate import SimulationOptions, simulate
from .friction import Estimate, FrictionFit

#: Linear coefficients, their ``[planetary]`` keys and units (the entries' own).
LINEAR = {symbol: (key, SCHEMA["planetary"][key].display) for symbol, key in {
    "b_C": "carrier_bearing_viscous",
    "b_R": "ring_bearing_viscous",
    "b_S": "sun_bearing_viscous",
    "k_1": "mesh_stiction",
    "k_C": "carrier_bearing_stiction",
    "k_R": "ring_bearing_stiction",
    "k_S": "sun_bearing_stiction",
}.items()}
STICTION = ("k_C", "k_R", "k_S")
#: The only coefficient whose column depends on the mesh sharpness k_b1: the mesh's
#: arctan stiction. Viscous columns are b s, and bearing stiction slides at its Coulomb
#: level whatever the sharpness.
SHARP = ("k_1",)
STRUCTURES = ("mesh", "bearing-stiction")
#: x = N_S/N_R < 1 in any planetary gear (N_R = N_S + 2 N_P); planets narrower than a
#: twentieth of the ring, or suns smaller than a tenth of it, are not built.
TOOTH_RATIO_RANGE = (0.1, 0.9)
#: Tooth ratios of the first search and of the profile that says which ratios the test
#: accepts (`StructureFit.tooth_ratio_accepted`): steps of 0.05.
TOOTH_RATIO_GRID = np.linspace(*TOOTH_RATIO_RANGE, 17)
SHARPNESS_RANGE = (0.1, 1000.0)
#: A structure explains the data when the chi-square test of its deviations, with each
#: point's noise from the free fit of its curve, does not reject it at this level.
SIGNIFICANCE = 1e-3
#: Smallest point noise assumed, as a fraction of the curve's torque range.
MODEL_ALLOWANCE = 0.005
#: A fitted x this close to an end of `TOOTH_RATIO_RANGE` is at that end (the logistic map
#: of the search reaches an end only in the limit) and is set to it exactly.
AT_END = 1e-4
#: Singular values of the unit-scaled design matrix below this fraction of the largest
#: are exact dependencies between coefficients (eq 3.28-3.29 make the b_C column a sum
#: of the b_R and b_S columns, and so for k_C: zero up to rounding, about 1e-16), not weak
#: ones (the closest independent pair, Coulomb stiction against the arctan mesh, differ
#: by percent).
DEPENDENT = 1e-9
#: The friction laws of the fit's model, as `vsj.simulate` names them: the report's
#: final module model (fig 4.7), arctan mesh friction (eq 3.17) and bearings that stick,
#: sliding at their Coulomb level k pi/2 (fig 4.8). `vsj.synth.friction` simulates the
#: bench the same way; `bench_curves` runs a parameter set forward with them.
BENCH_FRICTION = "arctan"
BENCH_OVERRIDES = {"*.bearing_*": "stiction"}


@dataclass
class StructureFit:
    """The best parameter set of one model structure and how well it explains the data.

    ``noise`` is the point noise the test assumes per curve [N m]: the curve's own
    ``scatter`` about its free fit (eq 4.2), or the model allowance when that is larger
    (``noise_source``). ``p_below`` is the probability of a chi-square as small as the one
    found; ``too_small`` says it is below the significance (the noise is over-estimated or
    the model over-fits). ``chi2_scatter``, ``p_scatter``: the same test with the scatter
    alone as the noise. ``same_curves``: each coefficient that can change without changing
    the predicted curves at all, with its range [SI] over that family (every coefficient
    >= 0). ``tooth_ratio_accepted``: the lowest and highest tooth ratio of
    `TOOTH_RATIO_GRID` at which the structure, refitted, still passes the test (None with
    the ratio given); ``profile``: those ratios and their best chi-square.
    """

    structure: str
    parameters: list[Estimate]
    misfit: dict[str, float]          # RMS deviation per experiment [N m]
    noise: dict[str, float]           # point noise per experiment [N m]
    chi2: float
    dof: int
    p_value: float
    explains: bool
    determined: list[str] = field(default_factory=list)
    undetermined: list[str] = field(default_factory=list)
    combinations: list[str] = field(default_factory=list)
    at_bound: list[str] = field(default_factory=list)
    predicted: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    scatter: dict[str, float] = field(default_factory=dict)
    noise_source: dict[str, str] = field(default_factory=dict)
    p_below: float = math.nan
    too_small: bool = False
    chi2_scatter: float = math.nan
    p_scatter: float = math.nan
    same_curves: dict[str, tuple[float, float]] = field(default_factory=dict)
    tooth_ratio_accepted: tuple[float, float] | None = None
    profile: tuple[np.ndarray, np.ndarray] | None = None

    def value(self, name: str) -> float:
        """The fitted value (SI) of the parameter ``name``."""
        return next(e.value for e in self.parameters if e.name == name)

    @property
    def over_parameterised(self) -> bool:
        """True when other parameter sets give the very same curves (`same_curves`) or
        some parameters are not determined: the set found is one of many."""
        return bool(self.same_curves or self.undetermined)

    @property
    def ratio_one_of_many(self) -> bool:
        """True when the test also accepts other tooth ratios of `TOOTH_RATIO_GRID`."""
        return (self.tooth_ratio_accepted is not None
                and self.tooth_ratio_accepted[1] > self.tooth_ratio_accepted[0])

    def to_json(self) -> dict:
        """The structure's fit (parameters, misfit, noise, chi-square test, profile) as
        plain JSON data (SI values with their units)."""
        profile = (None if self.profile is None else
                   {"x": self.profile[0].tolist(), "chi2": self.profile[1].tolist()})
        return {
            "structure": self.structure, "explains_both": self.explains,
            "parameters": {e.name: e.to_json() for e in self.parameters},
            "misfit_rms": self.misfit, "noise": self.noise, "noise_source": self.noise_source,
            "scatter": self.scatter, "chi2": self.chi2, "dof": self.dof,
            "p_value": self.p_value, "p_below": self.p_below,
            "chi2_too_small": self.too_small,
            "chi2_with_scatter": self.chi2_scatter, "p_value_with_scatter": self.p_scatter,
            "identifiability": {"determined": self.determined,
                                "not_determined": self.undetermined,
                                "determined_combinations": self.combinations,
                                "at_bound": self.at_bound,
                                "over_parameterised": self.over_parameterised,
                                "same_curves": {k: list(v) for k, v in self.same_curves.items()},
                                "tooth_ratio_accepted": (None if self.tooth_ratio_accepted is None
                                                         else list(self.tooth_ratio_accepted)),
                                "tooth_ratio_profile": profile},
            "predicted": {k: {"velocity": v.tolist(), "torque": t.tolist()}
                          for k, (v, t) in self.predicted.items()},
        }

    def caution(self) -> str | None:
        """What a chi-square that is too small means, or None when it is not."""
        if not self.too_small:
            return None
        return (f"chi2 {self.chi2:.3g} is far below its {self.dof} degrees of freedom (one this "
                f"small has probability {self.p_below:.2g}): the assumed noise is too large or "
                "the model over-fits, so passing the test says little")

    def noise_note(self) -> str | None:
        """Which curves are tested against the model allowance rather than their own
        scatter, and the test with the scatter alone; None when no curve is."""
        allowance = [k for k, s in self.noise_source.items() if s == "model allowance"]
        if not allowance:
            return None
        return ("the test assumes the model allowance of "
                f"{MODEL_ALLOWANCE * 100:g} % of the curve's range as the noise of "
                + " and ".join(f"{k} ({self.noise[k] / self.scatter[k]:.2g} times its scatter)"
                               if self.scatter[k] > 0 else k for k in allowance)
                + f"; with the scatter alone chi2 is {self.chi2_scatter:.3g} "
                f"(p = {self.p_scatter:.2g})")


@dataclass
class PlanetaryFit:
    """Both structures fitted to both experiments, and the verdict."""

    curves: dict[str, FrictionFit]
    fits: dict[str, StructureFit]
    tooth_ratio_given: float | None
    significance: float

    @property
    def chosen(self) -> StructureFit | None:
        """The simplest structure that explains both curves, or None."""
        for name in STRUCTURES:
            if self.fits[name].explains:
                return self.fits[name]
        return None

    @property
    def verdict(self) -> str:
        """Which structure explains both curves, in one sentence."""
        mesh, full = self.fits["mesh"], self.fits["bearing-stiction"]
        chosen = self.chosen
        within = (" (a chi-square too small to discriminate: see the caution)"
                  if chosen is not None and chosen.too_small else "")
        if mesh.explains:
            return "mesh friction and viscous bearings explain both curves" + within
        if full.explains:
            return ("mesh friction alone cannot explain both curves; with stiction in the "
                    "bearings one parameter set explains both" + within)
        return ("no parameter set of the planetary model explains both curves (largest "
                "deviation " + ", ".join(f"{k} {v:.3g} N m" for k, v in full.misfit.items())
                + "): some assumption of the model does not hold for this gear set")

    def to_json(self) -> dict:
        """The comparison (files, verdict, chosen structure and both fits) as plain JSON
        data (SI values with their units)."""
        chosen = self.chosen
        out = {
            "files": {k: c.source for k, c in self.curves.items()},
            "synthetic": any(c.synthetic for c in self.curves.values()),
            "verdict": self.verdict, "explained": chosen is not None,
            "structure": None if chosen is None else chosen.structure,
            "over_parameterised": None if chosen is None else chosen.over_parameterised,
            "chi2_too_small": None if chosen is None else chosen.too_small,
            "caution": None if chosen is None else chosen.caution(),
            "noise_note": None if chosen is None else chosen.noise_note(),
            "significance": self.significance,
            "tooth_ratio_given": self.tooth_ratio_given,
            "curves": {k: c.to_json() for k, c in self.curves.items()},
            "structures": {k: f.to_json() for k, f in self.fits.items()},
        }
        best = chosen or self.fits["bearing-stiction"]
        out["parameters"] = ({e.name: e.to_json() for e in best.parameters}
                             if chosen is not None else None)
        for name, (v, t) in best.predicted.items():
            out[name] = {"predicted": {"velocity": v.tolist(), "torque": t.tolist()}}
        return out

    def parameter_overrides(self, files: str, teeth: tuple[float, float]) -> dict[str, dict]:
        """Parameter-file overrides (``planetary.*``) of the chosen structure: everything
        its fit chose, so that the set reproduces the fitted curves (`bench_curves`).

        Every coefficient of `LINEAR` is written, the zeros included (a coefficient the
        structure leaves out is zero), and the mesh sharpness; values in full precision.
        ``teeth`` are the base set's ``(sun_teeth, ring_teeth)``. The model depends on the
        tooth counts only through x = N_S/N_R, which the fit treats as a real number, so
        the counts encode x: the base counts when their ratio is x already, else the
        base ring count and ``sun_teeth = x ring_teeth``, which need not be whole (a
        rounded count would change x by up to 1/(2 N_R), more than its standard error,
        and the file would no longer be the fit).
        """
        chosen = self.chosen
        if chosen is None:
            raise InputError("no parameter set explains both curves; nothing to write")
        source = f"identified from {files} ({chosen.structure} model)"
        values = {e.name: e for e in chosen.parameters}
        out = {}
        for name, (key, unit) in LINEAR.items():
            if name not in values:
                out[f"planetary.{key}"] = {
                    "value": f"0 {unit}",
                    "source": f"{source}: the structure has no stiction in the bearings"}
                continue
            note = ""
            if name in chosen.same_curves:
                lo, hi = chosen.same_curves[name]
                note = (f"; one of many: any value from {lo:.4g} to {hi:.4g} {unit} (with the "
                        "others adjusted) gives the same curves")
            elif name in chosen.at_bound:
                note = "; at its bound"
            out[f"planetary.{key}"] = {"value": f"{values[name].value!r} {unit}",
                                       "source": source + note}
        out["planetary.mesh_sharpness"] = {"value": f"{chosen.value('k_b1')!r} s/rad",
                                           "source": source}
        x = chosen.value("x")
        sun, ring = (float(v) for v in teeth)
        if sun / ring != x:
            sun = x * ring
        counts = f"N_S = {_count(sun)}, N_R = {_count(ring)}"
        if self.tooth_ratio_given is not None:
            how = f"given: tooth ratio x = N_S/N_R = {x:.10g}, held fixed in the fit of {files}"
        else:
            how = f"{source}: tooth ratio x = N_S/N_R = {x:.10g}"
            if "x" in chosen.at_bound:
                how += (f", at an end of the range {TOOTH_RATIO_RANGE[0]:g} to "
                        f"{TOOTH_RATIO_RANGE[1]:g} the fit allows")
            if chosen.ratio_one_of_many:
                lo, hi = chosen.tooth_ratio_accepted
                how += f" (one of many: the test accepts every x from {lo:.3g} to {hi:.3g})"
        how += (f"; the model depends on the ratio only: {counts}, the ring count as in the "
                "base set")
        out["planetary.sun_teeth"] = {"value": _count(sun), "source": how}
        out["planetary.ring_teeth"] = {"value": _count(ring), "source": how}
        return out


def _count(value: float) -> str:
    """A tooth count as written to a parameter file: whole, or in full precision."""
    return str(int(value)) if float(value).is_integer() else repr(float(value))


def bench_curves(params, velocities) -> dict[str, np.ndarray]:
    """The planetary bench run forward: the torque [N m] that holds the carrier at each
    speed [rad/s] with ``params`` (a `vsj.params.Parameters`).

    ``velocities`` maps ``"fixed_sun"`` and/or ``"fixed_ring"`` to carrier speeds. Each
    speed is a run of `vsj.benches.planetary_bench` (the carrier driven rigidly) under
    the fit's laws (`BENCH_FRICTION`, `BENCH_OVERRIDES`) with the time-stepper: the
    carrier takes the speed in the first step, and from then on every element slides and
    the drive holds the sum of their torques, which is read after the second step.
    """
    options = SimulationOptions(friction=BENCH_FRICTION, friction_overrides=BENCH_OVERRIDES,
                                solver="timestep")
    out = {}
    for key, speeds in velocities.items():
        fixed = key.removeprefix("fixed_")
        structure = planetary_bench(params, fixed=fixed, sensor_stiffness=None).assemble()
        torque = []
        for w in np.asarray(speeds, dtype=float):
            result = simulate(structure, {"drive": Constant(float(w))}, 2 * options.step,
                              options=replace(options, output_step=options.step), ports=False)
            if not result.success:
                raise InputError(f"the planetary bench ({fixed} fixed) at {w:g} rad/s failed: "
                                 f"{result.message}")
            torque.append(float(result["source.motor.torque"][-1]))
        out[key] = np.array(torque)
    return out


def _columns(x: float, kb: float, names, w_sun, w_ring):
    """Torque of each linear coefficient alone (value 1) in both experiments."""
    cols = []
    for name in names:
        unit = {k: 0.0 for k in LINEAR}
        unit[name] = 1.0
        gear = PlanetaryGearModule("pg", sun_teeth=x, ring_teeth=1.0, mesh_sharpness=kb,
                                   **{LINEAR[k][0]: v for k, v in unit.items()})
        # bearing stiction slides at the Coulomb level k pi/2 (fig 4.8); the mesh
        # friction is the smooth arctan law (eq 3.17) the curves' shape comes from
        law = "stiction" if name in STICTION else "arctan"
        cols.append(np.concatenate([gear.closed_form_torque("sun", w_sun, law),
                                    gear.closed_form_torque("ring", w_ring, law)]))
    return np.column_stack(cols)


def _scatter(curve: FrictionFit) -> float:
    """Standard deviation of one point about the curve's own free fit (eq 4.2) [N m]."""
    n = len(curve.torque)
    return _rms(curve.predict(curve.velocity) - curve.torque) * math.sqrt(n / max(n - 3, 1))


def _noise(curve: FrictionFit) -> float:
    """Standard deviation of one point: the free fit's scatter about its own curve, but at
    least `MODEL_ALLOWANCE` of the curve's range (no model is exact to the last digit)."""
    return max(_scatter(curve), MODEL_ALLOWANCE * float(np.ptp(curve.torque)), 1e-12)


def _same_curves(A: np.ndarray, coef: np.ndarray, names) -> dict[str, tuple[float, float]]:
    """Each coefficient that some other non-negative set with exactly the same predictions
    ``A @ coef`` can change, with its lowest and highest value over all such sets."""
    scale = np.maximum(np.linalg.norm(A, axis=0), 1e-300)
    _, sv, Vt = np.linalg.svd(A / scale, full_matrices=False)
    null = Vt[sv <= DEPENDENT * sv[0]].T  # directions (scaled) that change no prediction
    if not null.size:
        return {}
    # coefficients in units of the largest one's torque, so that the programme's
    # tolerances are relative to it
    size = max(float(np.max(np.abs(coef * scale))), 1e-300)
    c = coef * scale / size
    out = {}
    for i, name in enumerate(names):
        ends = []
        for sign in (1.0, -1.0):
            # extreme of c_i + null_i z over c + null z >= 0: a linear programme in z
            lp = linprog(sign * null[i], A_ub=-null, b_ub=c, bounds=[(None, None)] * null.shape[1],
                         method="highs")
            ends.append(c[i] + null[i] @ lp.x if lp.status == 0 else c[i])
        lo, hi = (0.0 if v < DEPENDENT else v for v in sorted(ends))  # rounding of the LP
        if hi - lo > DEPENDENT:
            out[name] = (float(lo * size / scale[i]), float(hi * size / scale[i]))
    return out


def fit_structure(sun: FrictionFit, ring: FrictionFit, structure: str, *,
                  tooth_ratio: float | None = None,
                  significance: float = SIGNIFICANCE) -> StructureFit:
    """Best parameters of one structure for both curves (weighted by their noise)."""
    if structure not in STRUCTURES:
        raise InputError(f"structure must be one of {', '.join(STRUCTURES)}")
    names = [n for n in LINEAR if structure == "bearing-stiction" or n not in STICTION]
    w_s, w_r = sun.velocity, ring.velocity
    T = np.concatenate([sun.torque, ring.torque])
    weight = np.concatenate([np.full(len(w_s), 1 / _noise(sun)),
                             np.full(len(w_r), 1 / _noise(ring))])

    by_x: dict[float, dict[str, np.ndarray]] = {}

    def columns(x, kb):
        # the columns that do not depend on k_b1 once per tooth ratio: the grid search
        # below visits 41 sharpnesses at each ratio
        fixed = by_x.get(float(x))
        if fixed is None:
            fixed = by_x[float(x)] = {n: _columns(x, kb, [n], w_s, w_r)[:, 0]
                                      for n in names if n not in SHARP}
        return np.column_stack([fixed[n] if n in fixed else
                                _columns(x, kb, [n], w_s, w_r)[:, 0] for n in names])

    def project(x, kb):
        A = columns(x, kb) * weight[:, None]
        scale = np.maximum(np.linalg.norm(A, axis=0), 1e-300)
        coef, rnorm = nnls(A / scale, T * weight)
        return coef / scale, rnorm

    free_x = tooth_ratio is None
    x_grid = TOOTH_RATIO_GRID if free_x else np.array([tooth_ratio])
    kb_grid = np.logspace(np.log10(SHARPNESS_RANGE[0]), np.log10(SHARPNESS_RANGE[1]), 41)
    grid = np.array([[project(x, kb)[1] for kb in kb_grid] for x in x_grid])
    i0, j0 = np.unravel_index(np.argmin(grid), grid.shape)
    x0, kb0 = x_grid[i0], kb_grid[j0]
    kb_bounds = [math.log(b) for b in SHARPNESS_RANGE]

    def unpack(z):
        kb = math.exp(z[-1])
        x = 1 / (1 + math.exp(-z[0])) * np.ptp(TOOTH_RATIO_RANGE) + TOOTH_RATIO_RANGE[0] \
            if free_x else tooth_ratio
        return x, kb

    def logit(x):
        u = (x - TOOTH_RATIO_RANGE[0]) / np.ptp(TOOTH_RATIO_RANGE)
        u = min(max(u, 1e-6), 1 - 1e-6)
        return math.log(u / (1 - u))

    def residual(x, kb):
        coef, _ = project(x, kb)
        return (columns(x, kb) @ coef - T) * weight

    def reduced(z):
        return residual(*unpack(z))

    def best_sharpness(x, kb):
        """The sharpness that fits best at tooth ratio ``x``, searched from ``kb``."""
        fit = least_squares(lambda z: residual(x, math.exp(z[0])), [math.log(kb)],
                            diff_step=1e-6, bounds=([kb_bounds[0]], [kb_bounds[1]]))
        return math.exp(fit.x[0])

    z0 = ([logit(x0)] if free_x else []) + [math.log(kb0)]
    outer = least_squares(reduced, z0, x_scale=1.0, diff_step=1e-6,
                          bounds=([-20.0] * free_x + [kb_bounds[0]],
                                  [20.0] * free_x + [kb_bounds[1]]))
    x, kb = unpack(outer.x)
    end = min(TOOTH_RATIO_RANGE, key=lambda b: abs(x - b))
    if free_x and abs(x - end) < AT_END:
        # at an end of the range: set x there exactly, so that the parameters written for
        # it are the ones fitted
        x = end
        kb = best_sharpness(x, kb)
    coef, _ = project(x, kb)

    # full Jacobian in all parameters (linear ones and x, k_b1) for uncertainties
    full_names = names + (["x"] if free_x else []) + ["k_b1"]
    theta = np.concatenate([coef, [x] if free_x else [], [kb]])

    def model(th):
        k = len(names)
        xx = th[k] if free_x else tooth_ratio
        return columns(xx, th[-1]) @ th[:k]

    r = (model(theta) - T) * weight
    J = np.empty((len(T), len(theta)))
    for j in range(len(theta)):
        h = 1e-6 * max(abs(theta[j]), 1e-9 if j < len(names) else 1e-3)
        up, down = theta.copy(), theta.copy()
        up[j] += h
        down[j] -= h
        J[:, j] = (model(up) - model(down)) * weight / (2 * h)
    at_bound = [names[i] for i in range(len(names)) if coef[i] <= 0.0]
    if free_x and x == end:
        at_bound.append("x")  # at an end of TOOTH_RATIO_RANGE: no symmetric interval
    free = [i for i, n in enumerate(full_names) if n not in at_bound]
    dof = max(len(T) - len(free), 1)
    chi2 = float(r @ r)
    s2 = max(1.0, chi2 / dof)
    Jf = J[:, free]
    colscale = np.maximum(np.linalg.norm(Jf, axis=0), 1e-300)
    U, sv, Vt = np.linalg.svd(Jf / colscale, full_matrices=False)
    rank = int(np.sum(sv > 1e-7 * sv[0]))
    null = Vt[rank:].T  # directions (in scaled free parameters) the data do not see
    cov_scaled = (Vt[:rank].T / sv[:rank] ** 2) @ Vt[:rank] * s2
    cov = cov_scaled / np.outer(colscale, colscale)
    err = np.full(len(theta), math.nan)  # at a bound: no symmetric interval
    undetermined: list[str] = []
    for k, i in enumerate(free):
        if null.size and np.linalg.norm(null[k]) > 1e-3:
            err[i] = math.inf
            undetermined.append(full_names[i])
        else:
            err[i] = math.sqrt(max(cov[k, k], 0.0))
    blind = [full_names[i] for k, i in enumerate(free)
             if null.size and np.linalg.norm(null[k]) > 1e-3]
    # coefficients that change along with others without changing the curves at all (at a
    # bound or not) are not determined one by one either: only their combinations are
    same_curves = _same_curves(columns(x, kb), coef, names)
    for i, name in enumerate(full_names):
        if name in same_curves:
            err[i] = math.inf
            if name not in undetermined:
                undetermined.append(name)
    combinations = _combinations(set(blind) | set(same_curves), x)
    t = special.stdtrit(dof, 0.975)  # Student's t quantile
    units = {**{n: LINEAR[n][1] for n in LINEAR}, "x": "1",
             "k_b1": SCHEMA["planetary"]["mesh_sharpness"].display}
    params = [Estimate(n, float(v), units[n], float(e),
                       (float(v - t * e), float(v + t * e))) for n, v, e in
              zip(full_names, theta, err)]
    if not free_x:
        params.append(Estimate("x", float(tooth_ratio), "1", 0.0, (tooth_ratio, tooth_ratio)))
    predicted = model(theta)
    pred_s, pred_r = predicted[:len(w_s)], predicted[len(w_s):]
    misfit = {"fixed_sun": _rms(pred_s - sun.torque), "fixed_ring": _rms(pred_r - ring.torque)}
    noise = {"fixed_sun": _noise(sun), "fixed_ring": _noise(ring)}
    scatter = {"fixed_sun": _scatter(sun), "fixed_ring": _scatter(ring)}
    source = {k: "scatter" if scatter[k] >= noise[k] else "model allowance" for k in noise}
    p_value = float(special.chdtrc(dof, chi2))  # chi-square survival function
    p_below = float(special.chdtr(dof, chi2))
    deviation = np.concatenate([(pred_s - sun.torque) / max(scatter["fixed_sun"], 1e-300),
                                (pred_r - ring.torque) / max(scatter["fixed_ring"], 1e-300)])
    chi2_scatter = float(deviation @ deviation)

    accepted = profile = None
    if free_x:
        # the best chi-square at each tooth ratio of the grid (sharpness refitted): the
        # ratios at which this structure passes the same test
        limit = float(special.chdtri(dof, significance))  # and its inverse
        best = []
        for xg, j in zip(x_grid, np.argmin(grid, axis=1)):
            r_x = residual(xg, best_sharpness(xg, kb_grid[j]))
            best.append(float(r_x @ r_x))
        profile = (x_grid.copy(), np.array(best))
        passing = [float(xg) for xg, c in zip(x_grid, best) if c <= limit]
        if p_value >= significance:
            passing.append(float(x))
        accepted = (min(passing), max(passing)) if passing else None

    return StructureFit(
        structure=structure, parameters=params, misfit=misfit, noise=noise, chi2=chi2,
        dof=dof, p_value=p_value, explains=p_value >= significance,
        determined=[full_names[i] for i in free if full_names[i] not in undetermined],
        undetermined=undetermined, combinations=combinations,
        at_bound=at_bound,
        predicted={"fixed_sun": (w_s.copy(), pred_s), "fixed_ring": (w_r.copy(), pred_r)},
        scatter=scatter, noise_source=source, p_below=p_below,
        too_small=p_below < significance, chi2_scatter=chi2_scatter,
        p_scatter=float(special.chdtrc(dof, chi2_scatter)),
        same_curves=same_curves,
        tooth_ratio_accepted=accepted, profile=profile)


def _rms(a) -> float:
    return float(np.sqrt(np.mean(np.square(a))))


def _combinations(blind: set[str], x: float) -> list[str]:
    """What the data do determine when the coefficients in ``blind`` are not determined
    one by one (eq 3.28-3.29: each curve sees the bearings only through its own sum)."""
    groups = (
        ({"b_C", "b_R", "b_S"},
         f"b_C + {(1 + x) ** 2:.4g} b_R and b_C + {(1 + 1 / x) ** 2:.4g} b_S "
         "(the viscous constants c1 and c4)"),
        ({"k_C", "k_R", "k_S"},
         f"k_C + {1 + x:.4g} k_R and k_C + {1 + 1 / x:.4g} k_S "
         "(each curve's bearing Coulomb level over pi/2)"),
    )
    out, rest = [], set(blind)
    for members, text in groups:
        if rest & members:
            out.append(text)
            rest -= members
    if rest:
        out.append("only combinations of " + ", ".join(sorted(rest)) + " are determined")
    return out


def fit_planetary(sun: FrictionFit, ring: FrictionFit, *, tooth_ratio: float | None = None,
                  significance: float = SIGNIFICANCE) -> PlanetaryFit:
    """Fit both structures to the fixed-sun and fixed-ring curves and compare them."""
    if tooth_ratio is not None and not (0 < tooth_ratio < 1):
        raise InputError(f"tooth ratio N_S/N_R must be between 0 and 1, got {tooth_ratio:g}")
    if not (0 < significance < 1):
        raise InputError(f"significance must be between 0 and 1, got {significance:g}")
    fits = {s: fit_structure(sun, ring, s, tooth_ratio=tooth_ratio, significance=significance)
            for s in STRUCTURES}
    return PlanetaryFit({"fixed_sun": sun, "fixed_ring": ring}, fits, tooth_ratio, significance)
