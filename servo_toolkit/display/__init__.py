"""How results look: one-line reprs, HTML cards for Jupyter, and the HTML and number
formatting the report shares with them.

Modules: :mod:`.html` (escaping, the number format, tables, status badges: shared with the
report) and :mod:`.cards` (the card, badges, requirement tables, inline SVG and the
:class:`RichDisplay` mixin). Each result draws its own card from these pieces, in its own
module, beside its ``table()`` and ``plot()``.
"""

from .cards import RichDisplay, badge, card, esc, facts, num, svg, table

__all__ = ["RichDisplay", "badge", "card", "esc", "facts", "num", "svg", "table"]
