"""The crossed-arch deflection platform of seed 003: :mod:`.geometry` (description and
validation) and :mod:`.model` (kinematics and Lagrange dynamics)."""
