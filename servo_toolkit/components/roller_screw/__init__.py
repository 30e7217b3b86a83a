"""Planetary roller screws of seed 004: :mod:`.stages` (description, validation, ratios,
efficiency) and :mod:`.model` (carrier dynamics)."""
