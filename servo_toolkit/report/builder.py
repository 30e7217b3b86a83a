"""Assemble the report: run each section builder, isolate failures, write HTML and PDF."""

from __future__ import annotations

import dataclasses
import datetime as _dt
import sys
import hashlib
from dataclasses import dataclass, field
from pathlib import Path

from ..core.progress import progress_bar

from ..errors import SceneError
from . import sections_drivetrain as drv
from . import sections_export as export_section
from . import sections_loop as loop
from . import sections_measured as measured
from . import sections_montecarlo as montecarlo
from . import sections_closed as closed
from . import sections_command as command
from . import sections_disturbance as disturbance
from . import sections_poles as poles
from . import sections_requirements as requirements_section
from . import sections_limits as limits
from . import sections_robust as robust
from . import sections_sizing as sizing
from . import sections_stroke as stroke
from . import sections_studies as studies
from . import sections_time as timing
from . import sections_tolerances as tolerances
from .context import Context
from .figures import finish
from .references import reader_words
from .section import FigureSpec, NotApplicable, NotAvailable, Section
from .sections_kinds import kind_sections
from .time_limit import time_limit as _time_limit

#: default wall-time limit per section (s) with light settings; None with full settings
LIGHT_SECTION_TIME_LIMIT = 60.0

#: Section builders in report order (the requirements table, REQUIREMENTS, is built and shown first).
#: The study kinds' sections (:mod:`.sections_kinds`) come before :data:`KIND_SECTIONS_BEFORE`.
SECTIONS = (
    ("scene", "Scene summary", drv.scene_summary),
    ("stiffness", "Stiffness chain and compliance shares", drv.stiffness_chain),
    ("inertia", "Reflected inertia and ratio along the stroke", drv.ratio_and_inertia),
    ("plant", "Plant Bode with the drivetrain resonance", loop.plant_bode),
    ("controller", "Designed controller", loop.controller),
    ("export", "Exported controller coefficients", export_section.exported_coefficients),
    ("loop", "Loop Bode and Nyquist with margins", loop.loop_margins),
    ("stroke", "Margins along the stroke", stroke.margins_along_stroke),
    ("closed_loop", "Closed loop: sensitivity, Nichols, disturbance rejection, step", closed.closed_loop),
    ("poles", "Closed-loop poles and the sampled loops", poles.poles_and_sampling),
    ("disturbance", "Disturbance step and dynamic stiffness along the stroke", disturbance.disturbance),
    ("robustness", "Robustness over the parameter variants", robust.robustness),
    ("montecarlo", "Nonlinear Monte Carlo over the parameter variants", montecarlo.montecarlo_section),
    ("tolerances", "Tolerances: yield and sensitivity", tolerances.tolerances_section),
    ("time", "Step response and sine tracking", timing.time_responses),
    ("command", "Control that uses the model: feedforward, gain schedule, command shaping", command.command_section),
    *kind_sections(),  # each study kind's own section (the sweep, Kv), from its descriptor
    ("sizing", "Sizing along the duty cycle", sizing.sizing),
    ("reduce", "What the model leaves out", limits.leaves_out),
    ("accuracy", "Solver accuracy", studies.accuracy),
)
#: the section the study kinds' sections come before
KIND_SECTIONS_BEFORE = "sizing"
REQUIREMENTS = ("requirements", "Requirements", requirements_section.requirements)
#: the section of a measured plant response, after :data:`measured.AFTER`, in a report given one
MEASURED = ("measured", "The loop on the measured plant", measured.measured_plant)


def sections_of(plant_frf, scene=None) -> list:
    """The section builders of a report, in order: :data:`SECTIONS`, the sections of the
    study kinds registered since (a plugin's) and the generic section of each kind without
    one of its own that ``scene`` has studies of (before :data:`KIND_SECTIONS_BEFORE`), and
    :data:`MEASURED` when a measured plant response is given."""
    steps = list(SECTIONS)
    known = {s[0] for s in steps}
    at = next((i for i, s in enumerate(steps) if s[0] == KIND_SECTIONS_BEFORE), len(steps))
    steps[at:at] = [s for s in kind_sections(scene) if s[0] not in known]
    if plant_frf is not None:
        at = next(i for i, s in enumerate(steps) if s[0] == measured.AFTER) + 1
        steps.insert(at, MEASURED)
    return steps


@dataclass(frozen=True, repr=False)
class Report:
    """A built report.

    Attributes
    ----------
    scene_name, subtitle : str
    sections : tuple of Section
        Requirements first, then :data:`SECTIONS` in order.
    requirements : tuple of RequirementRow
        The rows of ``servo-toolkit check`` (:mod:`servo_toolkit.studies.gate`).
    meta : dict
        The document's identity: ``source`` (scene file), ``sha256`` (of its bytes),
        ``version`` (of the toolkit), ``date``, ``settings``.
    """

    scene_name: str
    subtitle: str
    sections: tuple
    requirements: tuple
    meta: dict = field(default_factory=dict)

    @property
    def passed(self) -> bool:
        """Every requirement row met (True when there is none)."""
        return all(r.passed for r in self.requirements)

    def section(self, key: str) -> Section:
        """The section with ``key``."""
        return next(s for s in self.sections if s.key == key)

    def to_dict(self) -> dict:
        """JSON-ready summary: section statuses and the requirements table."""
        return {"scene": self.scene_name, **self.meta,
                "sections": [s.to_dict() for s in self.sections],
                "requirements": [r.to_dict() for r in self.requirements]}

    def __repr__(self) -> str:
        counts = {}
        for sec in self.sections:
            counts[sec.status] = counts.get(sec.status, 0) + 1
        failed = sum(1 for r in self.requirements if not r.passed)
        return (f"<Report {self.scene_name}: {len(self.sections)} sections ("
                + ", ".join(f"{n} {k}" for k, n in sorted(counts.items())) + f"), {failed} requirement(s) not met>")

    def _repr_html_(self) -> str:
        from ..display.cards import card, table
        rows = [(s.title, s.status, s.reason) for s in self.sections]
        reqs = [r.cells() for r in self.requirements]
        return card(f"Report of {self.scene_name}", parts=[
            table(("ID", "requirement", "required", "achieved", "shortfall", "status"), reqs),
            table(("section", "status", "why"), rows)], notes=[self.subtitle])

    def close(self) -> None:
        """Release the figures' memory."""
        for s in self.sections:
            for f in s.figures:
                f.figure.clear()


def run_section(key: str, title: str, builder, ctx: Context, time_limit: float | None = None) -> Section:
    """Build one section; a missing capability, an error or running past ``time_limit``
    seconds becomes a visible box."""
    try:
        with _time_limit(time_limit, f"the section {title!r}"):
            section = builder(ctx)
    except NotApplicable as exc:
        return Section(title, status="n/a", reason=str(exc), key=key)
    except NotAvailable as exc:
        return Section(title, status="unavailable", reason=str(exc), key=key)
    except (ImportError, AttributeError) as exc:
        return Section(title, status="unavailable", reason=f"{type(exc).__name__}: {exc}", key=key)
    except SceneError as exc:
        return Section(title, status="unavailable", reason=f"the scene does not support it: {exc}", key=key)
    except Exception as exc:  # noqa: BLE001 - a failing section must not kill the report
        return Section(title, status="unavailable", reason=f"{type(exc).__name__}: {exc}", key=key)
    layout = []
    for k, spec in enumerate(section.figures, 1):  # one legend outside the axes, titles wrapped, checked
        try:
            layout += [f"figure {k}: {problem}" for problem in finish(spec.figure)]
        except Exception as exc:  # noqa: BLE001 - a figure that cannot be checked is said so, not lost
            layout.append(f"figure {k}: its layout could not be checked ({type(exc).__name__}: {exc})")
    figs = tuple(FigureSpec(spec.figure, reader_words(spec.caption)) for spec in section.figures)
    return dataclasses.replace(section, key=section.key or key, layout=tuple(layout), figures=figs,
                               html=reader_words(section.html), reason=reader_words(section.reason))


def build_report(scene, light: bool = True, executor=None, progress: bool = True,
                 section_time_limit="auto", design=None, plant_frf=None,
                 plant_frf_signal: str = "motor_angle_rad") -> Report:
    """Build every section of the report of ``scene``.

    Parameters
    ----------
    scene : Scene
    light : bool
        Light settings for expensive studies (the report then takes well under a minute).
    executor : concurrent.futures.Executor, optional
        Passed on to studies that run cases in parallel.
    progress : bool
        Show a tqdm progress bar (stderr), one step per section.
    section_time_limit : float, None or "auto"
        Wall-time limit per section (s); a section that runs longer is stopped and says so.
        ``"auto"``: :data:`LIGHT_SECTION_TIME_LIMIT` with light settings, no limit with full
        ones; None: no limit. Applies in the main thread only (see :mod:`.time_limit`).
    design : DesignResult, optional
        The loop to report (e.g. a tuned one, :func:`servo_toolkit.tuned_design`) instead of
        the automatic design.
    plant_frf : FrequencyData, optional
        A measured plant response (what ``frf -o`` writes, read with
        :func:`servo_toolkit.identify.data.read_data`): the design places its notch on its
        drivetrain mode, the requirements table adds the ``measured_*`` rows and a section
        shows the loop on it beside the model's.
    plant_frf_signal : str
        The signal it is the response to, from the motor current (``motor_angle_rad``,
        ``motor_speed_rad_s``, ``output_angle_rad``, ``output_travel_m``).

    Returns
    -------
    Report
    """
    if section_time_limit == "auto":
        section_time_limit = LIGHT_SECTION_TIME_LIMIT if light else None
    ctx = Context(scene, light=light, executor=executor, plant_frf=plant_frf, plant_frf_signal=plant_frf_signal)
    if design is not None:
        ctx.use_design(design)
    built = []
    # the requirements table first: what the report is signed on is never stopped half-way,
    # and the results it shares with the sections (the design, the large-signal run, the
    # Monte Carlo runs, the sizing) are computed in full before any section's time limit
    steps = [REQUIREMENTS] + sections_of(plant_frf, scene)
    with progress_bar(steps, show=progress, desc="report", unit="section", file=sys.stderr, leave=False) as bar:
        for key, title, builder in bar:
            bar.set_postfix_str(title[:40])
            limit = None if key == REQUIREMENTS[0] else section_time_limit
            built.append(run_section(key, title, builder, ctx, limit))
    req_section = built.pop(0)
    try:
        rows = tuple(requirements_section.requirement_rows(ctx))
    except Exception:  # noqa: BLE001 - the section already shows why
        rows = ()
    stamp = _dt.datetime.now().strftime("%Y-%m-%d %H:%M")
    subtitle = f"{reader_words(scene.description or scene.name)}. Generated {stamp} by servo_toolkit."
    return Report(scene.name, subtitle, tuple([req_section] + built), rows, scene_identity(scene, stamp, light))


def scene_identity(scene, date: str, light: bool = True) -> dict:
    """The report's identity: scene file, SHA-256 of its bytes (of the built-in scene's
    package file when it has none), toolkit version, date and settings."""
    from ..core.version import __version__
    try:
        digest = hashlib.sha256(Path(scene.source).read_bytes()).hexdigest()
    except (OSError, TypeError):
        digest = "(scene not read from a file)"
    return {"source": scene.source or "(built in memory)", "sha256": digest,
            "version": __version__, "date": date,
            "settings": "light (servo-toolkit report --full runs the studies as defined)" if light else "full"}


#: the files of a report folder (a folder holding only these is an earlier report)
REPORT_FILES = ("index.html", "report.pdf")
#: what each file of an earlier report holds near its start: a file of that name without it
#: is the user's, and the folder is not replaced
REPORT_MARKS = {"index.html": b'<meta name="generator" content="servo_toolkit', "report.pdf": b"%PDF-"}
#: the file that vouches for an earlier report: a PDF carries no mark of the toolkit near its
#: start, so a ``report.pdf`` without the report's ``index.html`` beside it is the user's
REPORT_ANCHORS = ("index.html",)


def check_report_folder(out_dir, key: str = "--output", parents: bool = False, inputs=()):
    """SceneError (naming ``key``) unless a report may be written as ``out_dir``: absent,
    empty or an earlier report holding none of ``inputs``, in a writable folder (see
    :func:`servo_toolkit.core.files.check_output_folder`)."""
    from ..core.files import check_output_folder
    return check_output_folder(out_dir, key, allowed=REPORT_FILES, inputs=inputs, parents=parents, marks=REPORT_MARKS,
                               anchors=REPORT_ANCHORS)


def write_report(report: Report, out_dir, progress: bool = False, key: str = "out_dir") -> dict:
    """Write ``index.html`` and ``report.pdf`` as the folder ``out_dir``; returns their paths.

    The folder is checked first (:func:`check_report_folder`: absent, empty or an earlier
    report), written in a temporary sibling and swapped in whole: an error or Ctrl-C
    leaves the earlier report, never a mixed or half-written one.

    Parameters
    ----------
    report : Report
    out_dir : str or pathlib.Path
        Created if missing (with its parents).
    progress : bool
        Show a tqdm progress bar (stderr), one step per rendered figure.
    key : str
        Name of the folder in errors (the CLI passes its option).
    """
    from ..core.folders import atomic_folder
    from .html_writer import render_html
    from .pdf_writer import write_pdf
    out = check_report_folder(out_dir, key, parents=True)
    n_fig = sum(len(s.figures) for s in report.sections)
    bar = progress_bar(total=2 * n_fig, show=progress, desc="writing", unit="figure", file=sys.stderr,
               leave=False)
    sources = {}  # each figure's SVG, rendered once for both documents
    with bar, atomic_folder(out, key, parents=True) as tmp:  # the bar's line is cleared on Ctrl-C too
        bar.set_postfix_str("index.html")
        (tmp / "index.html").write_text(render_html(report, tick=bar.update, sources=sources), encoding="utf-8")
        bar.set_postfix_str("report.pdf")
        engine = write_pdf(report, tmp / "report.pdf", tick=bar.update, sources=sources)
    return {"html": out / "index.html", "pdf": out / "report.pdf", "pdf_engine": engine}
