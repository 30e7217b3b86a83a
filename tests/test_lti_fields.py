"""A result's linear blocks: built as the toolkit's own state-space form, read as
python-control systems with the same matrices and names, and carried through
``dataclasses.replace`` as built (so a text verdict never imports python-control)."""

from __future__ import annotations

import subprocess
import sys
from dataclasses import dataclass, replace
from pathlib import Path

import control as ct
import numpy as np
import pytest

from servo_toolkit.lti.lazy import ControlSystem, block_of
from servo_toolkit.lti.system import StateSpace, ss
from servo_toolkit.loop.closed_loop import closed_loop_block, linear_closed_loop, open_loop, open_loop_block
from servo_toolkit.loop.design import evaluate


@dataclass(frozen=True)
class _Holder:
    name: str
    block: object = ControlSystem()
    other: object = ControlSystem(None)


def _first_order():
    return ss([[-2.0]], [[1.0]], [[3.0]], [[0.5]], inputs=["u"], outputs=["y"], states=["x"], name="lag")


def test_a_field_reads_as_python_control_and_keeps_the_block():
    h = _Holder("a", _first_order())
    assert isinstance(block_of(h, "block"), StateSpace) and h.other is None
    sys_ = h.block
    assert isinstance(sys_, ct.StateSpace) and h.block is sys_  # made once
    assert sys_.input_labels == ["u"] and sys_.output_labels == ["y"] and sys_.state_labels == ["x"]
    assert np.array_equal(sys_.A, [[-2.0]]) and np.array_equal(sys_.D, [[0.5]])
    with pytest.raises(AttributeError):
        object.__setattr__(h, "block", _first_order())
    with pytest.raises(TypeError):
        _Holder("no block")


def test_replace_carries_the_block_as_built():
    h = _Holder("a", _first_order())
    moved = replace(h, name="b")
    assert moved.__dict__["_block_block"] is h.__dict__["_block_block"]
    assert "_block_control" not in moved.__dict__ and "_block_control" not in h.__dict__
    assert moved.block is h.block  # both read the one python-control system of their block
    given = replace(h, block=h.block)  # a python-control system given back is kept as given
    assert block_of(given, "block").A.tolist() == [[-2.0]] and given.block is h.block


def test_a_design_result_reads_python_control_systems_equal_to_its_blocks(ema):
    scene, controller = ema
    r = evaluate(scene, controller, stroke_points=0)
    w = 2 * np.pi * np.geomspace(0.1, 2e3, 60)
    for name in ("plant", "loop", "closed_loop", "closed_loop_full"):
        block, system = r.block(name), getattr(r, name)
        assert isinstance(block, StateSpace) and isinstance(system, ct.StateSpace)
        for m in ("A", "B", "C", "D"):
            assert np.array_equal(getattr(block, m), getattr(system, m)), (name, m)
        assert system.input_labels == list(block.inputs) and system.output_labels == list(block.outputs)
        resp = np.asarray(ct.frequency_response(system, w).complex).reshape(block.noutputs, block.ninputs, -1)
        assert np.array_equal(np.asarray(block(1j * w)).reshape(block.noutputs, block.ninputs, -1), resp), name
    motion = r.controller.motion
    assert isinstance(motion, ct.StateSpace) and np.array_equal(motion.D, r.controller.motion_block.D)


def test_the_public_builders_are_the_blocks_as_python_control(ema):
    scene, controller = ema
    for public, own in ((linear_closed_loop, closed_loop_block), (open_loop, open_loop_block)):
        a, b = public(scene, controller), own(scene, controller)
        assert isinstance(a, ct.StateSpace) and isinstance(b, StateSpace)
        assert all(np.array_equal(getattr(a, m), getattr(b, m)) for m in "ABCD")
        assert a.state_labels == list(b.states)


def test_the_sampled_controller_is_python_controls_tustin(ema):
    """The simulation's discrete motion controller is ``control.sample_system(..., "tustin")``
    of the python-control system, to the bit."""
    _, controller = ema
    assert controller.sample_time > 0
    want = ct.sample_system(controller.motion, controller.sample_time, method="tustin")
    got = controller.discrete_motion()
    assert all(np.array_equal(g, getattr(want, m)) for g, m in zip(got, "ABCD"))


def test_a_design_in_a_new_process_imports_no_python_control():
    """Designing and judging a loop (the margins, the stroke, the n-mass plant) runs on the
    toolkit's own blocks; python-control comes in when a python-control system is read."""
    code = ("import sys\n"
            "from servo_toolkit.scene.loader import load_scene\n"
            "from servo_toolkit.loop.design import design\n"
            "from dataclasses import replace\n"
            "r = design(load_scene('servo_toolkit/data/ema_reference.toml'))\n"
            "r = replace(r, notes=r.notes + ('x',))\n"
            "before = 'control' in sys.modules\n"
            "r.loop\n"
            "print(before, 'control' in sys.modules)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600,
                          cwd=Path(__file__).resolve().parents[1])
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.split() == ["False", "True"]
