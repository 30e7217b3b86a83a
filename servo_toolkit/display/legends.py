"""Legends outside the data: in a row above an axes, or at its right.

matplotlib's ``loc="best"`` picks the emptiest corner, and a sine, a bar chart or a limit
line across the axes leaves none: the legend then covers curves. The results' plots place
theirs outside the axes instead; a layout engine (``layout="constrained"``, or the cards'
``tight_layout``) makes room for them.
"""

from __future__ import annotations


def _entries(axes):
    """(handles, labels) of ``axes``' labelled artists, each label once (the first met)."""
    handles, labels = [], []
    for ax in axes:
        for handle, label in zip(*ax.get_legend_handles_labels()):
            if label not in labels:
                handles.append(handle)
                labels.append(label)
    return handles, labels


def legend_above(ax, fontsize="small"):
    """The legend of ``ax`` in one row just above it, unframed; None without labels (an axes
    with a legend above has no title: the two would share the space)."""
    handles, labels = _entries([ax])
    if not labels:
        return None
    return ax.legend(handles, labels, fontsize=fontsize, loc="lower center", bbox_to_anchor=(0.5, 1.0),
                     ncol=len(labels), frameon=False)


def legend_beside(ax, sources=(), fontsize="small"):
    """One legend at the right of ``ax`` with the entries of ``ax`` and of ``sources`` (other
    axes whose curves are drawn alike: a column of panels shares it); None without labels."""
    handles, labels = _entries([ax, *sources])
    if not labels:
        return None
    return ax.legend(handles, labels, fontsize=fontsize, loc="upper left", bbox_to_anchor=(1.01, 1.0))


__all__ = ["legend_above", "legend_beside"]
