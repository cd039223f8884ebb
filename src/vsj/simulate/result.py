"""What runs return: `Result` (one run, named signals with units) and
`BatchResult` (many runs of one model, their states)."""

from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np

from ..network import Structure
from .signals import rows


@dataclass
class Result:
    """Trajectory of every signal, energy ledger and solver report of one run."""

    time: np.ndarray
    signals: dict[str, np.ndarray]
    units: dict[str, str]
    ledger: dict
    success: bool
    message: str
    solver: dict
    transitions: dict[str, int] = field(default_factory=dict)
    #: Where the run left what the parameter set describes (it still succeeded).
    warnings: list[str] = field(default_factory=list)
    #: Each signal's description (the signal table's, `vsj.simulate.signals.catalogue`)
    descriptions: dict[str, str] = field(default_factory=dict)
    #: The plan the run ran (`vsj.engine.plan.Plan`; None for a result read back or made
    #: by hand): what can run it again, as `vsj.safety.run_report` does to sample its
    #: contacts finer. Copies (`copy.copy`, `copy.deepcopy`) share it, as it is
    #: immutable; a pickled result leaves it out (it holds the compiled model).
    plan: object = field(default=None, repr=False, compare=False)

    def __getstate__(self):
        return {**self.__dict__, "plan": None}

    def __copy__(self) -> "Result":
        new = object.__new__(type(self))
        new.__dict__.update(self.__dict__)
        return new

    def __deepcopy__(self, memo) -> "Result":
        if self.plan is not None:
            memo[id(self.plan)] = self.plan  # shared, not copied
        new = object.__new__(type(self))
        memo[id(self)] = new
        new.__dict__.update({k: copy.deepcopy(v, memo) for k, v in self.__dict__.items()})
        return new

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.signals[name]
        except KeyError:
            raise KeyError(f"no signal {name!r}; signals include "
                           f"{', '.join(list(self.signals)[:12])}, ...") from None

    def columns(self) -> list[str]:
        """Names of the recorded signals."""
        return list(self.signals)

    def to_xarray(self):
        """The run as an `xarray.Dataset`: one variable per signal over ``time`` [s],
        each with its unit (``units``, as CF names it) and description (``long_name``),
        as ``trajectory.nc`` gives them; the run's success, message and solver as
        attributes."""
        import xarray as xr  # lazy: xarray is heavy; import vsj needs none

        from .. import __version__  # circle: vsj imports vsj.simulate, which imports this

        data = {name: ("time", values, _attrs(self.units[name], self.descriptions.get(name)))
                for name, values in self.signals.items()}
        ds = xr.Dataset(data, coords={"time": ("time", self.time, {"units": "s"})})
        ds.attrs.update(success=int(self.success), message=self.message,
                        solver=str(self.solver.get("name", "")),
                        steps=int(self.solver.get("steps", 0)), vsj_version=__version__)
        return ds

    def summary(self) -> str:
        """Success and message, solver statistics and the energy ledger, one line each."""
        lines = [f"{'success' if self.success else 'FAILED'}: {self.message}",
                 f"solver {self.solver['name']}: {self.solver['steps']} steps in "
                 f"{self.solver['wall_time']:.3f} s"]
        led = self.ledger
        if led:
            lines.append(f"energy ledger: work in {led['total_in']:.6g} J = stored "
                         f"{led['total_stored']:.6g} J + dissipated {led['total_dissipated']:.6g} J"
                         f" + residual {led['residual']:.3g} J "
                         f"({led['relative_residual']:.2g} of the energy in play)")
        if self.transitions:
            lines.append(f"stick/slip transitions: {sum(self.transitions.values())}")
        lines += [f"warning: {text}" for text in self.warnings]
        return "\n".join(lines)


@dataclass
class BatchResult:
    """States of many runs of one model, sampled on a common grid.

    ``states[r, k]`` is the state vector (angles, speeds, currents; see
    ``state_names``) of run ``r`` at ``time[k]``; `angle` and `speed` give any
    flange of the network for all runs, and ``batch["theta_x.speed"]`` a
    signal by the name a single run's `Result` gives it (`to_xarray`: all of
    them, with units).
    """

    time: np.ndarray
    states: np.ndarray
    state_names: list[str]
    success: np.ndarray
    messages: list[str]
    stop_time: np.ndarray
    steps: np.ndarray
    transitions: np.ndarray
    wall_time: float
    solver: str
    structure: Structure = field(repr=False)
    source_angles: np.ndarray = field(repr=False)
    source_speeds: np.ndarray = field(repr=False)
    #: a controller's bus and actuators (runs, samples, signals), named by control_names
    control: np.ndarray | None = field(default=None, repr=False)
    control_names: list = field(default_factory=list, repr=False)
    #: each signal's unit and description, from the signal table a single run's result
    #: takes them from (`vsj.simulate.signals.catalogue`)
    units: dict[str, str] = field(default_factory=dict, repr=False)
    descriptions: dict[str, str] = field(default_factory=dict, repr=False)

    def angle(self, flange: str) -> np.ndarray:
        """Angle [rad] of a flange, shape (runs, samples)."""
        rx, ru = self.structure.rows(flange)
        n = self.structure.n
        return rows(self.states[:, :, :n], rx) + rows(self.source_angles, ru)

    def speed(self, flange: str) -> np.ndarray:
        """Speed [rad/s] of a flange, shape (runs, samples)."""
        rx, ru = self.structure.rows(flange)
        n = self.structure.n
        return rows(self.states[:, :, n:2 * n], rx) + rows(self.source_speeds, ru)[None, :]

    # -- the same names as a single run's `Result` ---------------------------------------
    def _flanges(self) -> dict[str, str]:
        """Signal name -> flange: the network's named signals, then unnamed free flanges
        (as `Result` names them)."""
        named = {s.name: s.flange for s in self.structure.signals}
        taken = set(named.values())
        named.update({f: f for f in self.structure.free if f not in taken})
        return named

    def columns(self) -> list[str]:
        """Every signal a batch gives: each angle [rad] and its ``.speed`` [rad/s], spelt
        as in `Result` (``theta_x``, ``theta_x.speed``)."""
        return ([name + suffix for name in self._flanges() for suffix in ("", ".speed")]
                + list(self.control_names))

    def __getitem__(self, name: str) -> np.ndarray:
        """A signal by its `Result` name, shape (runs, samples)."""
        if name in self.control_names:
            return self.control[:, :, self.control_names.index(name)]
        base, speed = (name[:-len(".speed")], True) if name.endswith(".speed") else (name, False)
        flange = self._flanges().get(base)
        if flange is None:
            raise KeyError(f"no signal {name!r} in a batch; signals: "
                           f"{', '.join(self.columns()[:12])}, ...")
        return self.speed(flange) if speed else self.angle(flange)

    def to_xarray(self):
        """The batch as an `xarray.Dataset` over ``run`` and ``time`` [s]: one variable
        per signal with its unit, and each run's success, message and stop time; the
        same layout as `Result.to_xarray` with a ``run`` dimension in front."""
        import xarray as xr  # lazy: xarray is heavy; import vsj needs none

        from .. import __version__  # circle: vsj imports vsj.simulate, which imports this

        data = {name: (("run", "time"), self[name],
                       _attrs(self.units.get(name) or ("rad/s" if name.endswith(".speed")
                                                       else "rad"),
                              self.descriptions.get(name)))
                for name in self.columns()}
        data["success"] = ("run", self.success.astype(np.int8))
        data["message"] = ("run", np.array(self.messages, dtype=str))
        data["stop_time"] = ("run", self.stop_time, {"units": "s"})
        ds = xr.Dataset(data, coords={"run": np.arange(len(self.success)),
                                      "time": ("time", self.time, {"units": "s"})})
        ds.attrs.update(solver=self.solver, vsj_version=__version__)
        return ds


def _attrs(unit: str, description: str | None) -> dict:
    """A signal variable's attributes: its unit and, if known, its description."""
    return {"units": unit, **({"long_name": description} if description else {})}
