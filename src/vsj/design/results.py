"""What an optimisation leaves: the Pareto set (netCDF), its page, a design as a file.

``pareto.nc`` holds, per design of the Pareto set, the design parameters (SI), the
objectives in their natural sense and the constraint margins (>= 0: met), with the
base design's (the report's prototype with the bundled set) beside them; ``design.html``
shows the front in 2D and in parallel coordinates with the prototype marked, and says
by how much a design on the front improves each objective while no other is worse than
the prototype's. `write_params` writes one design as a parameter file that
``extends`` the base set, which every vsj command loads.
"""

from __future__ import annotations

import io
import json
import os
from pathlib import Path

import numpy as np

from .. import __version__, pages
from ..errors import InputError
from ..output import atomic_write
from ..output.trajectory import write_dataset
from ..params import DEFAULT_FILE, bundled_names, exact_text
from ..units import to_si
from .evaluate import OK, Problem, objective_matrix, prototype
from .optimise import Outcome
from .spec import DesignSpec, show

PARETO = "pareto.nc"
PAGE = "design.html"
FRONT = "front.png"
PARALLEL = "parallel.png"


def dataset(outcome: Outcome, base_row: np.ndarray, base_x: np.ndarray, base_message: str):
    """The Pareto set as an xarray Dataset (see the module docstring)."""
    import xarray as xr  # lazy: xarray is heavy; only the results need it

    problem = outcome.problem
    spec = problem.spec
    x, rows, status, generation = outcome.archive.arrays(problem)
    front = outcome.front
    cols = problem.columns
    kinds = {role: [j for j, c in enumerate(cols) if c.role == role]
             for role in ("objective", "margin", "auxiliary")}
    coords = {"design": np.arange(len(front)), "parameter": spec.names,
              "objective": [cols[j].name for j in kinds["objective"]],
              "constraint": [cols[j].name for j in kinds["margin"]],
              "auxiliary": [cols[j].name for j in kinds["auxiliary"]]}
    data = {
        "parameters": (("design", "parameter"), x[front].reshape(len(front), len(spec.variables))),
        "objectives": (("design", "objective"), rows[front][:, kinds["objective"]]),
        "margins": (("design", "constraint"), rows[front][:, kinds["margin"]]),
        "auxiliaries": (("design", "auxiliary"), rows[front][:, kinds["auxiliary"]]),
        "evaluation": (("design",), front.astype(np.int32)),
        "generation": (("design",), generation[front].astype(np.int32)),
        "parameter_unit": (("parameter",), [v.spec.unit for v in spec.variables]),
        "parameter_min": (("parameter",), [v.lo for v in spec.variables]),
        "parameter_max": (("parameter",), [v.hi for v in spec.variables]),
        "objective_unit": (("objective",), [cols[j].unit for j in kinds["objective"]]),
        "objective_sense": (("objective",), [g.sense for g in spec.objectives]),
        "constraint_unit": (("constraint",), [cols[j].unit for j in kinds["margin"]]),
        "auxiliary_unit": (("auxiliary",), [cols[j].unit for j in kinds["auxiliary"]]),
        "prototype_parameters": (("parameter",), base_x),
        "prototype_objectives": (("objective",), base_row[kinds["objective"]]),
        "prototype_margins": (("constraint",), base_row[kinds["margin"]]),
    }
    # netCDF classic reads a dimension of size 0 as the unlimited one: leave such out
    if not kinds["auxiliary"]:
        del coords["auxiliary"], data["auxiliaries"], data["auxiliary_unit"]
    if not len(front):
        for name in [k for k, (dims, _) in data.items() if "design" in dims]:
            del data[name]
        del coords["design"]
    feasible = int(np.count_nonzero(_feasible(problem, rows, status)))
    attrs = {"title": "vsj design: Pareto set", "vsj_version": __version__,
             "design_file": spec.origin, "design": spec.text, "design_sha256": spec.sha256(),
             "seed": spec.seed, "algorithm": spec.algorithm, "elastic_model": spec.elastic,
             "generations": outcome.generations, "evaluations": len(x),
             "feasible_evaluations": feasible, "failed_evaluations":
                 int(np.count_nonzero(status != OK)),
             "parameters": problem.base.origin, "parameters_hash": problem.base.hash(),
             "prototype_message": base_message or "evaluated",
             "conventions": "SI units; objectives in their natural sense (objective_sense "
                            "says which way is better); margins >= 0 where a constraint "
                            "holds"}
    return xr.Dataset(data, coords=coords, attrs=attrs)


def _feasible(problem: Problem, rows: np.ndarray, status: np.ndarray) -> np.ndarray:
    margins = [j for j, c in enumerate(problem.columns) if c.role == "margin"]
    with np.errstate(invalid="ignore"):
        return (status == OK) & np.all(rows[:, margins] >= 0.0, axis=1)


def improvements(problem: Problem, front_rows: np.ndarray, base_row: np.ndarray) -> list[str]:
    """For each objective, by how much the best design on the front that is nowhere worse
    than the prototype improves it (one sentence each)."""
    names = [g.name for g in problem.spec.objectives]
    if not np.all(np.isfinite(base_row[:len(names)])):
        return ["The prototype could not be evaluated, so nothing is compared with it."]
    F = objective_matrix(problem, front_rows)
    b = objective_matrix(problem, base_row[None, :])[0]
    out = []
    for j, goal in enumerate(problem.spec.objectives):
        others = [i for i in range(len(names)) if i != j]
        fair = np.flatnonzero(np.all(F[:, others] <= b[others], axis=1)) if others else \
            np.arange(len(F))
        unit = problem.columns[j].display
        if not len(fair) or not F[fair, j].min() < b[j]:
            out.append(f"{goal.name}: no design on the front improves it without making "
                       f"another objective worse than the prototype's "
                       f"({show(base_row[j], unit)}); the prototype is on the front there.")
            continue
        k = fair[int(np.argmin(F[fair, j]))]
        value = front_rows[k, j]
        change = (value - base_row[j]) / abs(base_row[j]) if base_row[j] else np.inf
        out.append(f"{goal.name} ({goal.sense}imise): design {k} reaches "
                   f"{show(value, unit)} against the prototype's {show(base_row[j], unit)} "
                   f"({100 * change:+.3g} %), with no other objective worse than the "
                   "prototype's.")
    return out


def figures(outcome: Outcome, base_row: np.ndarray, base_x: np.ndarray) -> dict[str, bytes]:
    """The front in 2D (each pair of objectives) and in parallel coordinates (design
    parameters and objectives, each scaled to its range), the prototype marked."""
    from .. import plots  # lazy: matplotlib is heavy; imported when a figure is drawn

    problem = outcome.problem
    spec = problem.spec
    x, rows, status, _ = outcome.archive.arrays(problem)
    feasible = _feasible(problem, rows, status)
    front = outcome.front
    n = len(spec.objectives)
    pairs = [(a, b) for a in range(n) for b in range(a + 1, n)] or [(0, 0)]
    cols = min(3, len(pairs))
    fig = plots.figure(figsize=(4.8 * cols, 3.8 * ((len(pairs) + cols - 1) // cols)),
                       layout="constrained")
    label = [f"{g.name} [{problem.columns[j].display}] ({g.sense})"
             for j, g in enumerate(spec.objectives)]
    scale = [plots_scale(problem.columns[j].display, problem.columns[j].unit)
             for j in range(n)]
    for k, (a, b) in enumerate(pairs):
        ax = fig.add_subplot((len(pairs) + cols - 1) // cols, cols, k + 1)
        ya = rows[:, b] * scale[b] if a != b else np.zeros(len(rows))
        ax.plot(rows[feasible, a] * scale[a], ya[feasible], ".", color="0.75", ms=3,
                label="feasible designs evaluated")
        ax.plot(rows[front, a] * scale[a], (ya[front]), "o", color="C0", ms=4,
                label="Pareto set")
        ax.plot([base_row[a] * scale[a]], [base_row[b] * scale[b] if a != b else 0.0], "*",
                color="C3", ms=12, label="prototype")
        ax.set_xlabel(label[a])
        if a != b:
            ax.set_ylabel(label[b])
        ax.grid(True, alpha=0.3)
        if k == 0:
            ax.legend(fontsize=7)
    fig.suptitle("Pareto front (model): each pair of objectives")
    front_png = _png(fig)

    names = spec.names + [g.name for g in spec.objectives]
    values = np.column_stack([x[front], rows[front][:, :n]]) if len(front) else \
        np.zeros((0, len(names)))
    proto = np.concatenate([base_x, base_row[:n]])
    lo = np.nanmin(np.vstack([values, proto]), axis=0)
    hi = np.nanmax(np.vstack([values, proto]), axis=0)
    span = np.where(hi > lo, hi - lo, 1.0)
    fig = plots.figure(figsize=(max(6.0, 1.6 * len(names)), 4.2))
    ax = fig.add_subplot()
    for v in values:
        ax.plot(range(len(names)), (v - lo) / span, color="C0", alpha=0.4, lw=1)
    ax.plot(range(len(names)), (proto - lo) / span, color="C3", lw=2.5, label="prototype")
    ax.set_xticks(range(len(names)))
    ax.set_xticklabels(names, rotation=20, ha="right", fontsize=8)
    ax.set_ylabel("scaled to the range shown (0: lowest, 1: highest)")
    for k in range(len(names)):
        ax.axvline(k, color="0.6", lw=0.8)
        ax.text(k, 1.02, f"{hi[k]:.3g}", ha="center", fontsize=7)
        ax.text(k, -0.06, f"{lo[k]:.3g}", ha="center", fontsize=7)
    ax.set_ylim(-0.1, 1.08)
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title("Pareto set in parallel coordinates (SI values at the axes' ends)")
    return {FRONT: front_png, PARALLEL: _png(fig)}


def _png(fig) -> bytes:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100, bbox_inches="tight")
    return buffer.getvalue()


def plots_scale(display: str, unit: str) -> float:
    """Factor from an SI value to its display unit (1 where they agree)."""
    return 1.0 / to_si(f"1 {display}", unit, where="display unit")


def page(outcome: Outcome, base_row: np.ndarray, base_x: np.ndarray, base_message: str,
         pngs: dict[str, bytes]) -> str:
    """The optimisation's page: what was asked, the front, the table, the comparison."""
    problem = outcome.problem
    spec = problem.spec
    x, rows, status, _ = outcome.archive.arrays(problem)
    front = outcome.front
    esc = pages.esc
    inside = all(v.lo <= b <= v.hi for v, b in zip(spec.variables, base_x))
    if len(front):
        headline = (f"{len(front)} designs on the Pareto front of {len(x)} evaluated "
                    f"({int(np.count_nonzero(_feasible(problem, rows, status)))} feasible) over "
                    f"{outcome.generations} generations.")
    else:
        headline = (f"No feasible design: none of the {len(x)} designs evaluated meets "
                    "every constraint.")
    facts = [("design file", spec.origin), ("base parameter set",
                                            f"{problem.base.origin} (hash "
                                            f"{problem.base.hash()[:12]})"),
             ("algorithm", f"{spec.algorithm.upper()} (pymoo), population {spec.population}, "
                           f"seed {spec.seed}"),
             ("elastic model", spec.elastic),
             ("pivot positions", f"{spec.q_points} over the pivot range (the datasheet's "
                                 "grid)"),
             ("vsj", __version__)]
    body = ["<p class=headline>" + esc(headline) + "</p>",
            "<p>" + esc("Every number is the model's (vsj's elastic laws through the engine, "
                        "and its closed-loop simulations for the tracking lag and the impact "
                        "force).") + " <span class='synthetic'>model study: no "
            "measurement</span></p>",
            "<table>" + "".join(f"<tr><th class=l>{esc(k)}</th><td class=l>{esc(v)}</td></tr>"
                                for k, v in facts) + "</table>",
            "<h2>Design parameters</h2><table><tr><th class=l>parameter</th><th>min</th>"
            "<th>max</th><th>prototype</th></tr>" + "".join(
                f"<tr><td class=l>{esc(v.name)}</td><td>{esc(show(v.lo, v.spec.display))}</td>"
                f"<td>{esc(show(v.hi, v.spec.display))}</td>"
                f"<td>{esc(show(b, v.spec.display))}</td></tr>"
                for v, b in zip(spec.variables, base_x)) + "</table>",
            "<h2>Objectives and constraints</h2><ul>" + "".join(
                f"<li>{esc(g.name)} ({g.sense}imise): {esc(g.kind.description)}</li>"
                for g in spec.objectives) + "".join(
                f"<li>constraint {esc(g.name)}: {esc(g.kind.description)} "
                f"({esc(_options(g))})</li>" for g in spec.constraints) +
            "<li>constraint parameter_relations: the relations between parameter keys of "
            "every parameter set (vsj.params.RELATIONS)</li></ul>"]
    proto_note = ("The prototype (the base parameter set) " +
                  ("lies inside the design space." if inside else
                   "lies outside the design space's bounds: it is shown for reference.") +
                  (f" It could not be evaluated: {base_message}." if base_message else ""))
    body.append("<h2>Against the prototype</h2><p>" + esc(proto_note) + "</p><ul>" + "".join(
        f"<li>{esc(s)}</li>" for s in (improvements(problem, rows[front], base_row)
                                      if len(front) else ["no feasible design to compare"]))
                + "</ul>")
    for name, caption in ((FRONT, "the front, each pair of objectives; grey: every feasible "
                                  "design evaluated; red star: the prototype"),
                          (PARALLEL, "the Pareto set in parallel coordinates; red: the "
                                     "prototype")):
        if name in pngs:
            body.append(pages.figure(pngs[name], caption))
    cols = problem.columns
    head = ("<tr><th>design</th>" + "".join(
        f"<th>{esc(v.name)} [{esc(v.spec.display)}]</th>" for v in spec.variables) + "".join(
        f"<th>{esc(c.name)} [{esc(c.display)}]</th>" for c in cols) + "</tr>")
    table = [head, "<tr><td class=l>prototype</td>" + "".join(
        f"<td>{_num(b, v.spec.display, v.spec.unit)}</td>"
        for v, b in zip(spec.variables, base_x)) + "".join(
        f"<td>{_num(r, c.display, c.unit)}</td>" for c, r in zip(cols, base_row)) + "</tr>"]
    for k, i in enumerate(front):
        table.append(f"<tr><td>{k}</td>" + "".join(
            f"<td>{_num(b, v.spec.display, v.spec.unit)}</td>"
            for v, b in zip(spec.variables, x[i])) + "".join(
            f"<td>{_num(r, c.display, c.unit)}</td>" for c, r in zip(cols, rows[i])) + "</tr>")
    body.append("<h2>The Pareto set</h2><p>" + esc(
        "Margins are >= 0 where a constraint holds. 'vsj design SPEC --out DIR "
        "--write-params N' writes design N as a parameter file.") + "</p><table>"
        + "".join(table) + "</table>")
    return pages.document(f"vsj design: {Path(spec.origin).name}", body)


def _num(value: float, display: str, unit: str) -> str:
    if not np.isfinite(value):
        return "-"
    return f"{value * plots_scale(display, unit):.5g}"


def _options(goal) -> str:
    units = goal.kind.options
    return ", ".join(f"{k} = {show(v, _display(units[k]))}" for k, v in goal.options.items())


def _display(unit: str) -> str:
    return {"N*m": "N m", "rad": "rad", "N": "N"}.get(unit, unit)


def write(outcome: Outcome, out: Path, *, plots: bool = True) -> tuple[list[str], bool]:
    """Write ``pareto.nc``, the figures and ``design.html`` into ``out``; returns the
    files written and whether a feasible design was found."""
    base_x, base_row, base_message = prototype(outcome.problem)
    ds = dataset(outcome, base_row, base_x, base_message)
    write_dataset(out / PARETO, ds)
    files = [PARETO]
    pngs = figures(outcome, base_row, base_x) if plots else {}
    for name, png in pngs.items():
        with atomic_write(out / name, "wb") as handle:
            handle.write(png)
        files.append(name)
    with atomic_write(out / PAGE) as handle:
        handle.write(page(outcome, base_row, base_x, base_message, pngs))
    files.append(PAGE)
    return files, bool(len(outcome.front))


def write_params(spec: DesignSpec, out: Path, index: int) -> Path:
    """Design ``index`` of the Pareto set in ``out/pareto.nc`` as ``out/design-INDEX.toml``:
    a parameter file that ``extends`` the design file's base set and gives the design
    parameters, each value written exactly (it reads back as the same number)."""
    import xarray as xr  # lazy: xarray is heavy; only the results need it

    path = out / PARETO
    if not path.exists():
        raise InputError(f"--write-params: {out} holds no {PARETO}: run 'vsj design "
                         f"{spec.origin} --out {out}' first")
    with xr.open_dataset(path, engine="scipy") as ds:
        if ds.attrs.get("design_sha256") != spec.sha256():
            raise InputError(f"--write-params: {path} is the result of another design file "
                             f"(its text differs from {spec.origin})")
        count = ds.sizes.get("design", 0)
        if not 0 <= index < count:
            raise InputError(f"--write-params {index}: the Pareto set in {path} has "
                             + (f"designs 0 to {count - 1}" if count else "no design"))
        names = [str(n) for n in ds["parameter"].values]
        values = [float(v) for v in ds["parameters"].values[index]]
        objectives = {str(n): float(v) for n, v in zip(ds["objective"].values,
                                                       ds["objectives"].values[index])}
    target = out / f"design-{index}.toml"
    text = params_text(spec, out, names, values, f"design {index} of its Pareto set",
                       objectives)
    with atomic_write(target) as handle:
        handle.write(text)
    return target


def params_text(spec: DesignSpec, out: Path, names, values, label: str,
                objectives: dict) -> str:
    """A parameter file, to be written into ``out``, that ``extends`` the design file's
    base set and sets ``names`` to ``values`` (SI, each written so that it reads back as
    the same number); ``label`` says which design it is."""
    if spec.params is None:
        parent = Path(DEFAULT_FILE).stem
    elif spec.params in bundled_names():
        parent = spec.params
    else:
        parent = os.path.relpath(Path(spec.params).resolve(), Path(out).resolve())
    source = f"vsj design {Path(spec.origin).name}: {label} (seed {spec.seed})"
    lines = ["# written by vsj design: one design of a Pareto set, over its base set",
             f"# objectives: {json.dumps(objectives)}",
             f"# with the {spec.elastic} elastic model: 'vsj datasheet --params FILE "
             f"--elastic {spec.elastic}' gives the same numbers",
             f"extends = {json.dumps(parent)}", "",
             "[meta]", f"name = {json.dumps(f'{label}, {Path(spec.origin).name}')}",
             f"description = {json.dumps(source)}"]
    sections: dict[str, list[str]] = {}
    for name, value in zip(names, values):
        section, key = name.split(".", 1)
        sections.setdefault(section, []).append(
            f"{key} = {{ value = {json.dumps(exact_text(name, float(value)))}, source = "
            f"{json.dumps(source)} }}")
    for section, entries in sections.items():
        lines += ["", f"[{section}]", *entries]
    return "\n".join(lines) + "\n"
