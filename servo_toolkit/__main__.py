"""``python -m servo_toolkit``."""

from .cli import entry

entry()
