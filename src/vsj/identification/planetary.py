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
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import stats
from scipy.optimize import least_squares, nnls

from ..components.planetary import PlanetaryGearModule
from ..errors import InputError
from .friction import Estimate, FrictionFit

#: Linear coefficients, their parameter-file keys and units.
LINEAR = {
    "b_C": ("carrier_bearing_viscous", "N m s/rad"),
    "b_R": ("ring_bearing_viscous", "N m s/rad"),
    "b_S": ("sun_bearing_viscous", "N m s/rad"),
    "k_1": ("mesh_stiction", "N m"),
    "k_C": ("carrier_bearing_stiction", "N m"),
    "k_R": ("ring_bearing_stiction", "N m"),
    "k_S": ("sun_bearing_stiction", "N m"),
}
STICTION = ("k_C", "k_R", "k_S")
#: The only coefficient whose column depends on the mesh sharpness k_b1: the mesh's
#: arctan stiction. Viscous columns are b s, and bearing stiction slides at its Coulomb
#: level whatever the sharpness.
SHARP = ("k_1",)
STRUCTURES = ("mesh", "bearing-stiction")
#: x = N_S/N_R < 1 in any planetary gear (N_R = N_S + 2 N_P); planets narrower than a
#: twentieth of the ring, or suns smaller than a tenth of it, are not built.
TOOTH_RATIO_RANGE = (0.1, 0.9)
SHARPNESS_RANGE = (0.1, 1000.0)
#: A structure explains the data when the chi-square test of its deviations, with each
#: point's noise from the free fit of its curve, does not reject it at this level.
SIGNIFICANCE = 1e-3
#: Smallest point noise assumed, as a fraction of the curve's torque range.
MODEL_ALLOWANCE = 0.005


@dataclass
class StructureFit:
    """The best parameter set of one model structure and how well it explains the data."""

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

    def value(self, name: str) -> float:
        return next(e.value for e in self.parameters if e.name == name)

    def to_json(self) -> dict:
        return {
            "structure": self.structure, "explains_both": self.explains,
            "parameters": {e.name: e.to_json() for e in self.parameters},
            "misfit_rms": self.misfit, "noise": self.noise, "chi2": self.chi2,
            "dof": self.dof, "p_value": self.p_value,
            "identifiability": {"determined": self.determined,
                                "not_determined": self.undetermined,
                                "determined_combinations": self.combinations,
                                "at_bound": self.at_bound},
            "predicted": {k: {"velocity": v.tolist(), "torque": t.tolist()}
                          for k, (v, t) in self.predicted.items()},
        }


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
        mesh, full = self.fits["mesh"], self.fits["bearing-stiction"]
        if mesh.explains:
            return "mesh friction and viscous bearings explain both curves"
        if full.explains:
            return ("mesh friction alone cannot explain both curves; with stiction in the "
                    "bearings one parameter set explains both")
        return ("no parameter set of the planetary model explains both curves (largest "
                "deviation " + ", ".join(f"{k} {v:.3g} N m" for k, v in full.misfit.items())
                + "): some assumption of the model does not hold for this gear set")

    def to_json(self) -> dict:
        chosen = self.chosen
        out = {
            "files": {k: c.source for k, c in self.curves.items()},
            "synthetic": any(c.synthetic for c in self.curves.values()),
            "verdict": self.verdict, "explained": chosen is not None,
            "structure": None if chosen is None else chosen.structure,
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

    def parameter_overrides(self, files: str) -> dict[str, dict]:
        """Parameter-file overrides (``planetary.*``) of the chosen structure."""
        chosen = self.chosen
        if chosen is None:
            raise InputError("no parameter set explains both curves; nothing to write")
        source = f"identified from {files} ({chosen.structure} model)"
        out = {}
        for e in chosen.parameters:
            if e.name in LINEAR:
                key, unit = LINEAR[e.name]
                out[f"planetary.{key}"] = {"value": f"{e.value:.6g} {unit}", "source": source}
        out["planetary.mesh_sharpness"] = {"value": f"{chosen.value('k_b1'):.6g} s/rad",
                                           "source": source}
        return out


def _columns(x: float, kb: float, names, w_sun, w_ring):
    """Torque of each linear coefficient alone (value 1) in both experiments."""
    cols = []
    for name in names:
        unit = {k: 0.0 for k in LINEAR}
        unit[name] = 1.0
        gear = PlanetaryGearModule.from_values(
            "pg", {"sun_teeth": x, "ring_teeth": 1.0, "mesh_sharpness": kb,
                   **{LINEAR[k][0]: v for k, v in unit.items()}})
        # bearing stiction slides at the Coulomb level k pi/2 (fig 4.8); the mesh
        # friction is the smooth arctan law (eq 3.17) the curves' shape comes from
        law = "stiction" if name in STICTION else "arctan"
        cols.append(np.concatenate([gear.closed_form_torque("sun", w_sun, law),
                                    gear.closed_form_torque("ring", w_ring, law)]))
    return np.column_stack(cols)


def _noise(curve: FrictionFit) -> float:
    """Standard deviation of one point: the free fit's scatter about its own curve, but at
    least `MODEL_ALLOWANCE` of the curve's range (no model is exact to the last digit)."""
    n = len(curve.torque)
    scatter = _rms(curve.predict(curve.velocity) - curve.torque) * math.sqrt(n / max(n - 3, 1))
    return max(scatter, MODEL_ALLOWANCE * float(np.ptp(curve.torque)), 1e-12)


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

    x_grid = ([tooth_ratio] if tooth_ratio is not None
              else np.linspace(*TOOTH_RATIO_RANGE, 17))
    kb_grid = np.logspace(np.log10(SHARPNESS_RANGE[0]), np.log10(SHARPNESS_RANGE[1]), 41)
    best = min(((project(x, kb)[1], x, kb) for x in x_grid for kb in kb_grid))
    _, x0, kb0 = best
    free_x = tooth_ratio is None

    def unpack(z):
        kb = math.exp(z[-1])
        x = 1 / (1 + math.exp(-z[0])) * np.ptp(TOOTH_RATIO_RANGE) + TOOTH_RATIO_RANGE[0] \
            if free_x else tooth_ratio
        return x, kb

    def logit(x):
        u = (x - TOOTH_RATIO_RANGE[0]) / np.ptp(TOOTH_RATIO_RANGE)
        u = min(max(u, 1e-6), 1 - 1e-6)
        return math.log(u / (1 - u))

    z0 = ([logit(x0)] if free_x else []) + [math.log(kb0)]

    def reduced(z):
        x, kb = unpack(z)
        coef, _ = project(x, kb)
        return (columns(x, kb) @ coef - T) * weight

    kb_bounds = [math.log(b) for b in SHARPNESS_RANGE]
    outer = least_squares(reduced, z0, x_scale=1.0, diff_step=1e-6,
                          bounds=([-20.0] * free_x + [kb_bounds[0]],
                                  [20.0] * free_x + [kb_bounds[1]]))
    x, kb = unpack(outer.x)
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
    if free_x and min(abs(x - b) for b in TOOTH_RATIO_RANGE) < 1e-4:
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
    combinations = [_combination(null, [full_names[i] for i in free], x)] if null.size else []
    t = stats.t.ppf(0.975, dof)
    units = {**{n: LINEAR[n][1] for n in LINEAR}, "x": "1", "k_b1": "s/rad"}
    params = [Estimate(n, float(v), units[n], float(e),
                       (float(v - t * e), float(v + t * e))) for n, v, e in
              zip(full_names, theta, err)]
    if not free_x:
        params.append(Estimate("x", float(tooth_ratio), "1", 0.0, (tooth_ratio, tooth_ratio)))
    predicted = model(theta)
    pred_s, pred_r = predicted[:len(w_s)], predicted[len(w_s):]
    misfit = {"fixed_sun": _rms(pred_s - sun.torque), "fixed_ring": _rms(pred_r - ring.torque)}
    noise = {"fixed_sun": _noise(sun), "fixed_ring": _noise(ring)}
    p_value = float(stats.chi2.sf(chi2, dof))
    return StructureFit(
        structure=structure, parameters=params, misfit=misfit, noise=noise, chi2=chi2,
        dof=dof, p_value=p_value, explains=p_value >= significance,
        determined=[full_names[i] for i in free if full_names[i] not in undetermined],
        undetermined=undetermined, combinations=[c for c in combinations if c],
        at_bound=at_bound,
        predicted={"fixed_sun": (w_s.copy(), pred_s), "fixed_ring": (w_r.copy(), pred_r)})


def _rms(a) -> float:
    return float(np.sqrt(np.mean(np.square(a))))


def _combination(null: np.ndarray, names: list[str], x: float) -> str:
    """Describe what the data do see when some directions are invisible."""
    blind = [n for k, n in enumerate(names) if np.linalg.norm(null[k]) > 1e-3]
    known = {
        frozenset({"b_C", "b_R", "b_S"}):
            f"b_C + {(1 + x) ** 2:.4g} b_R and b_C + {(1 + 1 / x) ** 2:.4g} b_S "
            "(the viscous constants c1 and c4)",
    }
    key = frozenset(blind)
    if key in known:
        return known[key]
    return "only combinations of " + ", ".join(blind) + " are determined"


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
