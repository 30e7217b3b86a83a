"""The report's sections of the scene's study kinds, read from their descriptors.

Each registered kind (:func:`servo_toolkit.scene.study_kind.study_kinds`) names its own
section builder (``section``), or none: it then gets the generic section, each of the
scene's studies of that kind run with :func:`servo_toolkit.studies.run.run_study` and shown
as its result's table (the scalars of ``to_dict()`` with their units,
:mod:`servo_toolkit.display.result_table`) and its ``plot()`` figure. A kind with
``in_report = False`` has no section of its own.
"""

from __future__ import annotations

import functools

from ..display.result_table import scalar_rows
from ..scene.study_kind import study_kinds
from .section import FigureSpec, NotApplicable, Section, esc, para, table


def kind_sections(scene=None) -> list:
    """``(key, title, builder)`` of the study kinds' report sections, in their rank order:
    every registered kind's own section and, given ``scene``, the generic section of each
    kind without one that the scene has studies of."""
    out = []
    for kind in sorted(study_kinds().values(), key=lambda k: (k.section_rank, k.name)):
        if not kind.in_report:
            continue
        if kind.section is not None:
            out.append((kind.section_key, kind.section_title, kind.resolve("section")))
        elif scene is not None and scene.studies_of_kind(kind.name):
            out.append((kind.section_key, kind.section_title, functools.partial(generic_section, kind)))
    return out


def _figure(result):
    """The figure of ``result.plot``: drawn on a report figure's axes when ``plot`` takes
    ``ax``, else the figure of the axes (or figure) it returns."""
    import numpy as np

    from .figures import new_figure
    fig, ax = new_figure()
    try:
        result.plot(ax=ax)
        return fig
    except TypeError:
        drawn = np.ravel(result.plot())[0]
    return drawn if hasattr(drawn, "savefig") else drawn.figure


def generic_section(kind, ctx) -> Section:
    """Each study of ``kind`` in the scene: its result's scalars with units and its figure."""
    from ..studies.run import run_study
    studies = ctx.scene.studies_of_kind(kind.name)
    if not studies:
        raise NotApplicable(f"the scene defines no [studies.NAME] of kind {kind.name!r}")
    parts, figs = [para(kind.summary)], []
    for study in studies:
        result = run_study(ctx.scene, study.name)
        data = result.to_dict()
        parts.append(f"<h3>{esc(study.name)}</h3>" + table(("quantity", "value", "unit"), scalar_rows(data)))
        if hasattr(result, "plot"):
            figs.append(FigureSpec(_figure(result), f"Study {study.name} ({kind.name})."))
    return Section(kind.section_title, "".join(parts), tuple(figs), key=kind.section_key)


__all__ = ["generic_section", "kind_sections"]
