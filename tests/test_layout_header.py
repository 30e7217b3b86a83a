"""The kernels' C layout header is the Python layout table, regenerated."""

from servo_toolkit.sim import layout
from servo_toolkit.sim.layout_header import HEADER, constants, header_text


def test_header_is_generated_from_the_python_table():
    assert HEADER.read_text() == header_text(), (
        "servo_toolkit/_physics/layout.h is stale: run python -m servo_toolkit.sim.layout_header")


def test_every_slot_of_the_table_is_in_the_header():
    text = HEADER.read_text()
    for name in ("NX_PHYS", "KT", "NP_HEADER", "T_KS", "NCAM", "F_TAU", "S_END", "REF_TABLE"):
        assert f"#define {name} {getattr(layout, name)}\n" in text
    assert "STATE_NAMES" not in constants()
