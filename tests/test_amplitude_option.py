"""``--amplitude`` takes an angle or a travel; a ratio ("10 %", "1000 ppm"), which pint counts
as a bare number, is refused naming the option, as the scene's study keys refuse it."""

import pytest

from servo_toolkit import SceneError
from servo_toolkit.cli import main
from servo_toolkit.core.output_units import OutputUnit

from .conftest import SCENES

EMA = str(SCENES / "ema_reference.toml")

COMMANDS = {"simulate": [EMA], "kv": [EMA], "reduce": [EMA, "--estimate-only"],
            "montecarlo": [EMA, "--samples", "8", "--duration", "0.02"],
            "sweep": [EMA, "--method", "multisine"]}


@pytest.mark.parametrize("text", ["10 %", "1000 ppm", "0.5 percent"])
@pytest.mark.parametrize("si", ["rad", "m"])
def test_a_ratio_is_not_an_amplitude(text, si):
    with pytest.raises(SceneError, match="a ratio is not") as info:
        OutputUnit(si).parse(text, "--amplitude")
    assert info.value.key == "--amplitude"


@pytest.mark.parametrize("text, deg", [("10", 10.0), ("10 deg", 10.0), ("0.1 rad", 5.729577951308232)])
def test_a_bare_number_or_an_angle_is_an_amplitude(text, deg):
    assert OutputUnit("rad").parse(text, "--amplitude") * 180 / 3.141592653589793 == pytest.approx(deg)


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_command_refuses_a_ratio_for_its_amplitude(command, capsys):
    code = main([command, *COMMANDS[command], "--amplitude", "10 %"])
    err = capsys.readouterr().err
    assert code == 2
    assert "--amplitude" in err and "a ratio is not an angle" in err
    assert len(err.strip().splitlines()) == 1
