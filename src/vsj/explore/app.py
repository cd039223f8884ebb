"""The explorer's page: a Bokeh server application over `vsj.explore.setting`.

Every control changes the `Setting`; each change runs it (`Explorer.run`: the C engine,
a few tens of milliseconds for a 2 s closed-loop run) and sends the new curves to the
page, which redraws them. The views are in tabs of two plots, each tab with its data
source(s): a run sends the data of the tab shown (one message a source) and the numbers
written over the views; a tab shown later gets the latest run's data then. Sliders run on release (Bokeh's ``value_throttled``), so a
drag does not queue runs. A typed value is parsed with its unit and checked against the
control's range before anything runs: a refused one is shown beside its field, with
the range, and changes nothing. The page's scripts and styles are BokehJS, served by
the Bokeh server from the installed package: the page needs no network.

The page marks each slider release and each redraw with the browser's performance
marks (``vsj-release``, ``vsj-drawn``) and keeps the release-to-redraw times in
``window.vsjLatencies`` [ms]: the explorer's response time as the browser sees it
(benchmarks/explore.py reads them). ``window.vsjDrawn`` is the number of the last run
drawn (the server counts them from 1), ``window.vsjShown`` ``"<run>:<tab>"`` once a tab
shown has that run's data, and a ``window.vsjOnDrawn`` function, if a test sets one, is
called after each run drawn.
"""

from __future__ import annotations

import base64
import functools
import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from bokeh.application import Application
from bokeh.application.handlers.function import FunctionHandler
from bokeh.layouts import column, row
from bokeh.models import (Button, ColumnDataSource, CustomJS, Div, FileInput,
                          Select, Slider, Span, TabPanel, Tabs,
                          TextInput, Title)
from bokeh.plotting import figure
from bokeh.server.server import Server
from bokeh.themes import Theme

from .. import params as parameter_sets
from ..errors import InputError
from ..friction import RUN_LAWS
from .setting import (CONTROLLERS, ELASTIC, ENVIRONMENTS, FRICTION_KEYS, REFERENCES, Explorer,
                      Setting, View)

#: The choices, each with its options.
CHOICES = {"reference": REFERENCES, "friction": RUN_LAWS, "controller": CONTROLLERS,
           "environment": ENVIRONMENTS, "elastic": ELASTIC}
#: The sliders' titles (a control's label, in `vsj.explore.setting`, is what its messages
#: name it).
TITLES = {"q": "stiffness setting q", "amplitude": "amplitude / radius / step",
          "frequency": "frequency (circle, sine)", "duration": "run length",
          "transmission.stiction": "transmission stiction k_T",
          "transmission.viscous": "transmission viscous b_T",
          "planetary.mesh_stiction": "sun-carrier mesh stiction k_1",
          "differential.stiction": "differential stiction k_D",
          "friction.arctan_sharpness": "arctan sharpness k_b", "k": "gain k",
          "Ti": "integral time Ti", "Td": "derivative time Td",
          "wall_angle": "wall at theta_x =", "wall_stiffness": "wall stiffness"}
CHOICE_TITLES = {"reference": "output reference", "friction": "friction law",
                 "controller": "controller (collocated, on the motors' rotors)",
                 "environment": "environment", "elastic": "elastic element model"}
#: The sources of each tab of views, in the tabs' order (`Page._views`).
TABS = (("tracking",), ("motors",), ("springs",), ("ledger", "contact"))
SOURCES = tuple(name for tab in TABS for name in tab)
#: The numbers written over the views, one line each (`Page.notes`).
NOTES = ("outputs", "stiffness", "ledger", "impact", "impact_events", "impact_iso")

#: The page's latency probe and the numbers over the views. A slider's release marks
#: ``vsj-release``; the run's last change (the ``notes`` source, changed after every view's
#: data) marks ``vsj-drawn`` once the browser has painted the frame that shows the new
#: curves: BokehJS paints the plots in the next animation frame, and a task queued from
#: that frame's callback runs after its paint. Only then are the numbers written into the
#: title lines of the plots shown (a changed title lays its plot out again, which would
#: hold back the curves' paint by a layout), and once they are painted too the page marks
#: ``vsj-numbers`` and counts the run as drawn (``window.vsjDrawn``, what tests wait for).
#: A tab shown later gets its lines at once (its curves are already there).
_RELEASE_JS = "performance.mark('vsj-release'); window.vsjPending = true;"
_DRAWN_JS = """
const set_titles = () => {
    for (const [key, title] of Object.entries(titles)) {
        if (tab_of[key] === tabs.active) title.text = notes.data[key][0];
    }
};
const after_paint = (then) => requestAnimationFrame(() => setTimeout(then, 0));
const run = notes.data.run[0];
if (run !== window.vsjSeen) {
    window.vsjSeen = run;
    after_paint(() => {
        performance.mark('vsj-drawn');
        set_titles();
        after_paint(() => {
            performance.mark('vsj-numbers');
            if (window.vsjPending) {
                const m = performance.measure('vsj-latency', 'vsj-release', 'vsj-drawn');
                const n = performance.measure('vsj-numbers-latency', 'vsj-release',
                                              'vsj-numbers');
                (window.vsjLatencies = window.vsjLatencies || []).push(m.duration);
                (window.vsjNumberLatencies = window.vsjNumberLatencies || []).push(n.duration);
                window.vsjPending = false;
            }
            window.vsjDrawn = Math.max(window.vsjDrawn || 0, run);
            if (window.vsjOnDrawn) window.vsjOnDrawn();
        });
    });
} else {
    set_titles();
}
window.vsjShown = notes.data.shown[0];
"""

#: The plots' look, chosen for a quick paint: colours written out for every text (BokehJS
#: otherwise looks each up in the page's style sheet as it paints) and no minor ticks.
THEME = Theme(json={"attrs": {
    "Axis": {"major_label_text_color": "#444444", "axis_label_text_color": "#444444",
             "axis_line_color": "#444444", "major_tick_line_color": "#444444",
             "minor_tick_line_color": None},
    "Title": {"text_color": "#222222"},
    "Legend": {"label_text_color": "#222222"}}})

_STYLE = {"font-family": "sans-serif", "font-size": "13px"}
_ERROR = {**_STYLE, "color": "#b00020"}


def _value(setting: Setting, key: str) -> float:
    return setting.coefficients.get(key, None) if "." in key else getattr(setting, key)


def _combined(handler):
    """``handler`` with the document held: the changes it makes (the run's new data, the
    field it echoes) go to the page once it returns, each changed property once (Bokeh
    sends a message per property), so the page applies them together and paints once."""
    @functools.wraps(handler)
    def held(self, *args):
        if self.holding:  # a handler the held one set off: the outer hold covers it
            return handler(self, *args)
        self.holding = True
        self.doc.hold("combine")
        try:
            return handler(self, *args)
        finally:
            self.holding = False
            self.doc.unhold()

    return held


class Page:
    """One browser session's page: its controls, views and the setting they show."""

    def __init__(self, doc, explorer: Explorer, out: Path):
        self.doc, self.explorer, self.out = doc, explorer, Path(out)
        self.setting = explorer.default()
        self.sliders, self.fields, self.errors, self.selects = {}, {}, {}, {}
        self.holding = False
        self.echoed = {}  # key -> the text the server last wrote into its field
        self.run_error = Div(text="", styles=_ERROR, name="run_error", width=310)
        self.exported = Div(text="", styles=_STYLE, name="exported", width=310)
        # a source per tab of views (and the ledger's bars), so that a run sends the page
        # the data of the views it shows, as one message each (Bokeh sends each changed
        # property as one); the other tabs get theirs when shown. The numbers written
        # over the views go in "notes", changed last: its change marks the run as drawn
        self.sources = {name: ColumnDataSource(name=name, data={}) for name in SOURCES}
        self.latest, self.sent = {}, set()
        self.notes = ColumnDataSource(name="notes", data={k: [""] for k in NOTES}
                                      | {"run": [0], "shown": [""]})
        self.spans, self.note_titles = [], {}
        controls = self._controls()
        views = self._views()
        probe = dict(titles=self.note_titles, notes=self.notes, tabs=self.tabs,
                     tab_of={"outputs": 0, "stiffness": 0, "ledger": 3, "impact": 3,
                             "impact_events": 3, "impact_iso": 3})
        self.notes.js_on_change("data", CustomJS(code=_DRAWN_JS, args=probe))
        doc.add_root(row(controls, views))
        doc.add_root(self.notes)  # read by no view: a root of its own reaches the page
        doc.title = "vsj explore"
        doc.theme = THEME
        self.refresh()
        # the first run's data arrives with the page: it counts as drawn once shown
        doc.js_on_event("document_ready", CustomJS(code=_DRAWN_JS, args=probe))

    # -- controls -------------------------------------------------------------------

    def _numeric(self, key: str):
        c = self.explorer.controls[key]
        value = self._current(key)
        slider = Slider(start=c.start, end=max(c.end, value), value=value,
                        step=(c.end - c.start) / 200.0,
                        title=f"{TITLES.get(key, c.label)} [{c.display}]", show_value=False,
                        width=180, name=f"slider:{key}")
        slider.on_change("value_throttled", lambda attr, old, new: self._slid(key, new))
        slider.js_on_change("value_throttled", CustomJS(code=_RELEASE_JS))
        field = TextInput(value=c.show(value), width=125, name=f"field:{key}",
                          styles={"margin-top": "12px"})
        field.on_change("value", lambda attr, old, new: self._typed(key, new))
        error = Div(text="", styles=_ERROR, width=310, name=f"error:{key}")
        self.sliders[key], self.fields[key], self.errors[key] = slider, field, error
        return column(row(slider, field), error)

    def _current(self, key: str) -> float:
        value = _value(self.setting, key)
        return self.explorer.params[key] if value is None else value

    def _controls(self):
        intro = Div(text="<h2 style='margin:0'>vsj explore</h2><p>The wrist of report fig "
                         "4.15 in closed loop. Move a slider, or type a value with its unit "
                         "and press Enter: each change runs the model and redraws the "
                         "views.</p>", styles=_STYLE, width=620)
        groups = [("Stiffness", ["q", "elastic"]),
                  ("References", ["reference", "amplitude", "frequency", "duration"]),
                  ("Controller", ["controller", "k", "Ti", "Td"]),
                  ("Friction", ["friction", *FRICTION_KEYS]),
                  ("Environment", ["environment", "wall_angle", "wall_stiffness"])]
        columns = [[], []]
        for k, (title, keys) in enumerate(groups):
            parts = columns[0 if k < 3 else 1]
            parts.append(Div(text=f"<b>{title}</b>", styles=_STYLE))
            for key in keys:
                if key in CHOICES:
                    select = Select(title=CHOICE_TITLES[key], value=getattr(self.setting, key),
                                    options=list(CHOICES[key]), width=200, name=f"select:{key}")
                    select.on_change("value", lambda a, o, n, key=key: self._chose(key, n))
                    self.selects[key] = select
                    parts.append(select)
                else:
                    parts.append(self._numeric(key))
        upload = FileInput(accept=".toml", name="params_file", width=300)
        # the page sends the file's content before its name: read both once the
        # message that carries them has been applied
        upload.on_change("value", lambda a, o, n: self.doc.add_next_tick_callback(
            lambda: self._loaded(upload.filename, upload.value)))
        self.params_note = Div(text=self._params_text(), styles=_STYLE, width=310,
                               name="params_note")
        self.params_error = Div(text="", styles=_ERROR, width=310, name="error:params")
        export = Button(label="Write scenario.toml and params.toml", button_type="primary",
                        name="export", width=300)
        export.on_click(self._export)
        columns[0] += [Div(text="<b>Parameter set</b>", styles=_STYLE), self.params_note,
                       upload, self.params_error]
        columns[1] += [Div(text="<b>Export</b>", styles=_STYLE), export, self.exported,
                       self.run_error]
        return column(intro, row(column(*columns[0], width=320),
                                 column(*columns[1], width=320)))

    def _params_text(self) -> str:
        p = self.explorer.params
        return (f"{p.meta.get('name', p.origin)} ({p.origin}, hash {p.hash()[:12]}); "
                "load another parameter file (TOML):")

    @_combined
    def _slid(self, key: str, value: float) -> None:
        text = self.explorer.controls[key].show(value)
        self._apply(key, float(value))
        # the field shows the new value in a message after the run's: a changed field
        # makes the page restyle, which would otherwise delay the plots' repaint
        if _value(self.setting, key) == float(value):  # it ran (a refused one is put back)
            self.doc.add_next_tick_callback(lambda: self._echo(key, text))

    def _echo(self, key: str, text: str) -> None:
        """Show ``text`` in the field of ``key`` without taking it as typed: a field's
        callback runs on the server's own changes too (once the document is released),
        and the text, rounded for display, may differ from the value set."""
        self.echoed[key] = text
        self.fields[key].value = text

    @_combined
    def _typed(self, key: str, text: str) -> None:
        if text == self.echoed.get(key):
            return
        c = self.explorer.controls[key]
        try:
            value = c.parse(text)
        except InputError as exc:
            self.errors[key].text = f"refused: {_html(str(exc))}"
            return
        slider = self.sliders[key]
        slider.start, slider.end = min(slider.start, value), max(slider.end, value)
        slider.value = value
        self._apply(key, value)

    def _apply(self, key: str, value: float) -> None:
        """Run the setting with ``key`` at ``value``; if the model refuses the run (a
        combination the controls' ranges cannot rule out alone), say why beside the
        control and put it back where it was."""
        before = self.setting
        self.errors[key].text = ""
        if "." in key:
            coefficients = {**self.setting.coefficients, key: value}
            self.setting = replace(self.setting, coefficients=coefficients)
        else:
            self.setting = replace(self.setting, **{key: value})
        why = self.refresh()
        if why is not None:
            self.setting = before
            self.errors[key].text = f"not run: {_html(why)}"
            old = self._current(key)
            self.sliders[key].value = old
            self._echo(key, self.explorer.controls[key].show(old))

    @_combined
    def _chose(self, key: str, value: str) -> None:
        if value == getattr(self.setting, key):
            return  # the choice put back after a refused run
        before = self.setting
        self.setting = replace(self.setting, **{key: value})
        why = self.refresh()
        if why is not None:
            self.setting = before
            self.selects[key].value = getattr(before, key)

    @_combined
    def _loaded(self, filename: str, content: str) -> None:
        origin = filename or "uploaded parameter file"
        try:
            text = base64.b64decode(content).decode("utf-8")
            params = parameter_sets.loads(text, origin)
        except (InputError, UnicodeDecodeError, ValueError) as exc:
            self.params_error.text = f"refused: {_html(str(exc))}"
            return
        self.params_error.text = ""
        self.explorer, self.setting = self.explorer.with_params(params, self.setting)
        for key, slider in self.sliders.items():
            c = self.explorer.controls[key]
            value = self._current(key)
            slider.update(start=c.start, end=max(c.end, value), value=value,
                          step=(c.end - c.start) / 200.0)
            self._echo(key, c.show(value))
            self.errors[key].text = ""
        self.params_note.text = self._params_text()
        self.refresh()

    @_combined
    def _export(self) -> None:
        try:
            paths = self.explorer.export(self.setting, self.out)
        except (InputError, OSError) as exc:
            self.exported.text = f"not written: {_html(str(exc))}"
            return
        self.exported.text = (f"wrote {paths[0]} and {paths[1]}; <code>vsj simulate "
                              f"{paths[0]} --params {paths[1]}</code> runs the same run")

    # -- views ----------------------------------------------------------------------

    def _views(self):
        s = self.sources
        tools = "pan,wheel_zoom,box_zoom,reset,save"

        def plot(title, y_label, x_label="time [s]", *, notes=(), **kw):
            f = figure(**{"width": 470, **kw}, height=270 + 17 * len(notes), tools=tools,
                       x_axis_label=x_label, y_axis_label=y_label)
            f.toolbar.logo = None
            # the run's numbers, in title lines the page fills in from the notes (a
            # changed text on the page would lay the whole page out again; a title
            # changes its plot only)
            for key in reversed(notes):
                line = Title(text="", text_font_style="normal", text_font_size="9pt",
                             name=f"note:{key}")
                f.add_layout(line, "above")
                self.note_titles[key] = line
            f.add_layout(Title(text=title, text_font_size="10pt"), "above")
            return f

        out = plot("Outputs and their references", "angle [rad]", notes=("outputs",))
        for name, colour, label in (("theta_x", "#1f77b4", "theta_x"),
                                    ("theta_y", "#d62728", "theta_y")):
            out.line("time", name, source=s["tracking"], color=colour, legend_label=label)
            out.line("time", f"ref_{name}", source=s["tracking"], color=colour,
                     line_dash="dashed", legend_label=f"{label} reference")
        motors = plot("Motor angles (gearhead output)", "angle [rad]")
        torques = plot("Motor torques k_t i (at the rotor)", "torque [N m]")
        deflection = plot("Elastic deflection against the end stop (dashed)",
                          "deflection [rad]")
        spring = plot("Spring torque over deflection (end stop dashed)", "torque [N m]",
                      x_label="deflection [rad]")
        for j, colour in ((1, "#1f77b4"), (2, "#d62728")):
            motors.line("time", f"motor_angle_{j}", source=s["motors"], color=colour,
                        legend_label=f"motor {j}")
            torques.line("time", f"motor_torque_{j}", source=s["motors"], color=colour,
                         legend_label=f"motor {j}")
            deflection.line("time", f"deflection_{j}", source=s["springs"], color=colour,
                            legend_label=f"element {j}")
            spring.line(f"deflection_{j}", f"spring_torque_{j}", source=s["springs"],
                        color=colour, legend_label=f"element {j}")
        for f, dimension in ((deflection, "width"), (spring, "height")):
            for sign in (1, -1):
                span = Span(location=sign * 1.4, dimension=dimension, line_dash="dashed",
                            line_color="black")
                f.add_layout(span)
                self.spans.append((span, sign))
        ellipse = plot("2D stiffness (fig 4.14): the torque of a unit displacement",
                       "tau_y [N m/rad]", x_label="tau_x [N m/rad]", notes=("stiffness",),
                       match_aspect=True)
        ellipse.line("ellipse_x", "ellipse_y", source=s["tracking"], color="#2ca02c",
                     line_width=2, legend_label="at the run's last state")
        ellipse.line("rest_x", "rest_y", source=s["tracking"], color="gray",
                     line_dash="dashed", legend_label="springs undeflected")
        ledger = plot("Energy ledger over the run", "", x_label="energy [J]",
                      notes=("ledger",), y_range=[], width=560)
        ledger.hbar(y="label", right="joules", height=0.7, source=s["ledger"],
                    color="#9467bd")
        self.ledger_plot = ledger
        contact = plot("Contact force and impact figures", "force [N]",
                       notes=("impact", "impact_events", "impact_iso"))
        contact.line("time", "contact_force", source=s["contact"], color="black")
        for f in (out, motors, torques, deflection, spring, ellipse):
            f.legend.location = "top_left"
            f.legend.label_text_font_size = "9pt"
            f.legend.background_fill_alpha = 0.6
        # the views in tabs of two: the page's update and paint take about 20 ms a plot
        # on this 2-core VM (BokehJS), whether the plot is shown or not, so a run updates
        # the tab shown (the others as they are shown)
        self.tabs = Tabs(name="views", tabs=[
            TabPanel(title="Tracking and stiffness", child=column(out, ellipse)),
            TabPanel(title="Motors", child=column(motors, torques)),
            TabPanel(title="Elastic elements", child=column(deflection, spring)),
            TabPanel(title="Energy and impact", child=column(ledger, contact))])
        self.tabs.on_change("active", lambda a, o, n: self._shown())
        return self.tabs

    def refresh(self) -> str | None:
        """Run the setting and send the views their new data (the notes last). Returns
        None, or why the model refused the run (also shown on the page)."""
        start = time.perf_counter()
        try:
            view = self.explorer.run(self.setting)
        except InputError as exc:
            self.run_error.text = f"not run: {_html(str(exc))}"
            return str(exc)
        took = time.perf_counter() - start
        self.run_error.text = ""
        self.exported.text = ""  # the files written, if any, were another setting's
        self._show(view, took)
        return None

    def _show(self, v: View, took: float) -> None:
        r = v.result
        t = r.time
        angle = np.linspace(0.0, 2.0 * math.pi, len(t))  # the ellipse at as many angles
        unit = np.vstack([np.cos(angle), np.sin(angle)])
        now, rest = v.stiffness @ unit, v.stiffness_rest @ unit
        contacts = list(v.impacts)
        labels = [label for label, _ in v.ledger.rows] + ["residual"]
        self.latest = {
            "tracking": {"time": t, "theta_x": r["theta_x"], "theta_y": r["theta_y"],
                         "ref_theta_x": r["control.theta_x"],
                         "ref_theta_y": r["control.theta_y"], "ellipse_x": now[0],
                         "ellipse_y": now[1], "rest_x": rest[0], "rest_y": rest[1]},
            "motors": {"time": t, **{f"motor_angle_{j}": r[f"motor_{j}"] for j in (1, 2)},
                       **{f"motor_torque_{j}": v.torque_constant * r[f"motor.motor_{j}.current"]
                          for j in (1, 2)}},
            "springs": {"time": t,
                        **{f"deflection_{j}": r[f"spring.{name}.deflection"]
                           for j, name in enumerate(v.springs[:2], start=1)},
                        **{f"spring_torque_{j}": r[f"spring.{name}.torque"]
                           for j, name in enumerate(v.springs[:2], start=1)}},
            "contact": {"time": t, "contact_force": r[f"contact.{contacts[0]}.force"]
                        if contacts else np.full(len(t), np.nan)},
            "ledger": {"label": labels,
                       "joules": [j for _, j in v.ledger.rows] + [v.ledger.residual]}}
        self.sent = set()
        self._send_shown()
        for span, sign in self.spans:
            span.location = sign * (v.end_stop if v.end_stop is not None else math.nan)
        lag = "n/a (the run is shorter than the fade-in and a period)" if v.lag is None \
            else f"{1e3 * v.lag:.2f} ms"
        K = v.stiffness
        run = self.notes.data["run"][0] + 1
        notes = {
            "outputs": f"tracking lag of theta_x {lag}, RMS error {1e3 * v.rms_error:.2f} "
                       f"mrad (run: {1e3 * took:.0f} ms)",
            "stiffness": f"K_xx {K[0, 0]:.4g}, K_yy {K[1, 1]:.4g}, K_xy {K[0, 1]:.3g} N m/rad "
                         "at the last state",
            "ledger": f"residual {v.ledger.residual:.2g} J, {v.ledger.relative_residual:.1e} "
                      "of the energy in play",
            **_impact_notes(v), "run": run, "shown": self._shown_note(run)}
        self.notes.data = {key: [value] for key, value in notes.items()}

    def _shown_note(self, run: int) -> str:
        """``"<run>:<tab>"``: the run whose data the tab shown has (what a test waits for)."""
        return f"{run}:{self.tabs.active}"

    def _send_shown(self) -> None:
        """Send the shown tab's sources the latest run's data, if not sent yet."""
        for name in TABS[self.tabs.active]:
            if name not in self.sent and name in self.latest:
                if name == "ledger":
                    self.ledger_plot.y_range.factors = self.latest[name]["label"][::-1]
                self.sources[name].data = self.latest[name]
                self.sent.add(name)

    @_combined
    def _shown(self) -> None:
        """Another tab is shown: send it the data of the latest run."""
        self._send_shown()
        patch = dict(self.notes.data)
        patch["shown"] = [self._shown_note(patch["run"][0])]
        self.notes.data = patch


def _impact_notes(v: View) -> dict:
    """The impact figures as the three lines over the contact plot."""
    lines = {"impact": "", "impact_events": "", "impact_iso": ""}
    if not v.impacts:
        lines["impact"] = "no contact in this environment"
        return lines
    name, events = next(iter(v.impacts.items()))
    if not events:
        lines["impact"] = f"the tip never touched the {name}"
        return lines
    first, worst = events[0], max(events, key=lambda ev: ev["peak_force"])
    lines["impact"] = (f"first impact at {first['start']:.3f} s: peak force "
                       f"{first['peak_force']:.3g} N, energy transferred "
                       f"{1e3 * first['energy_in']:.3g} mJ")
    lines["impact_events"] = (f"impulse {first['impulse']:.3g} N s; {len(events)} contact "
                              f"event(s), largest peak force {worst['peak_force']:.3g} N")
    lines["impact_iso"] = worst["iso_ts_15066"]["hand"]
    return lines


def _html(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def application(explorer: Explorer, out: Path):
    """The Bokeh application of the explorer: one `Page` per browser session."""
    return Application(FunctionHandler(lambda doc: Page(doc, explorer, out) and None))


def serve(explorer: Explorer, *, port: int, out: Path, show: bool, address: str = "localhost",
          ready=None) -> None:
    """Serve the explorer at ``http://address:port/`` until interrupted; ``show`` opens it in
    the browser; ``ready`` (if given) is called with the port once it listens. A port that
    cannot be listened on (in use, or reserved) is an `InputError` naming it."""
    try:
        server = Server({"/": application(explorer, out)}, port=port, address=address,
                        allow_websocket_origin=[f"{address}:{port}", f"127.0.0.1:{port}",
                                                f"localhost:{port}"], num_procs=1)
    except OSError as exc:  # the socket's bind: EADDRINUSE, EACCES below 1024, ...
        why = exc.strerror or str(exc)
        raise InputError(f"option --port: cannot serve on {address}:{port} ({why}); give "
                         "another port") from None
    server.start()
    if show:
        server.io_loop.add_callback(server.show, "/")
    if ready is not None:
        server.io_loop.add_callback(ready, server.port)
    server.io_loop.start()


__all__ = ["Page", "application", "serve"]
