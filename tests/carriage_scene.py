"""A linear EMA as a user writes it from the docs, shared by the tests of a travel output: a DC
motor, a 5:1 gearhead, a 10 mm ball screw and a 15 kg carriage over 0..200 mm (a constant ratio
and stiffness). Each test adds what it is about: lash in both stages, the carriage's Coulomb
and static friction, the motor's, its own requirements and studies."""

from __future__ import annotations

#: the loop requirements every variant starts from
LOOP_REQUIREMENTS = '''bandwidth = "15 Hz"
min_gain_margin = "6 dB"
min_phase_margin = "45 deg"
'''


def carriage_scene(name: str = "carriage", *, lash: bool = False, load_friction: bool = False,
                   motor_friction: bool = False, requirements: str = LOOP_REQUIREMENTS, extra: str = "") -> str:
    """The scene's TOML text.

    Parameters
    ----------
    lash : bool
        18 arcmin of backlash in the gearhead and 5 um in the screw.
    load_friction : bool
        The carriage's 30 N Coulomb and 40 N static friction (Stribeck speed 5 mm/s).
    motor_friction : bool
        The motor's 0.005 N*m Coulomb friction.
    requirements : str
        The body of ``[requirements]``.
    extra : str
        Tables after it (studies, ...).
    """
    return f'''name = "{name}"
description = "DC motor, 5:1 gearhead, 10 mm ball screw, 15 kg carriage"

[motor]
kind = "dc"
resistance = "1.2 ohm"
inductance = "0.3 mH"
torque_constant = "0.06 N*m/A"
back_emf_constant = "0.06 V*s/rad"
rotor_inertia = "140 g*cm^2"
viscous_friction = "2e-6 N*m*s/rad"
{'coulomb_friction = "0.005 N*m"' if motor_friction else ''}
voltage_limit = "48 V"
current_limit = "15 A"

[[drivetrain]]
kind = "gear"
name = "planetary gearhead"
ratio = 5
inertia = ["2.0e-6 kg*m^2", "1.0e-5 kg*m^2"]
efficiency = 0.9
torsional_stiffness = "2000 N*m/rad"
{'backlash = "18 arcmin"' if lash else ''}

[[drivetrain]]
kind = "ball_screw"
name = "ball screw"
lead = "10 mm"
screw_inertia = "2.5 kg*cm^2"
nut_mass = "0.4 kg"
efficiency = 0.92
axial_stiffness = "150 N/um"
{'backlash = "5 um"' if lash else ''}
stroke = ["0 mm", "200 mm"]

[load]
inertia = "15 kg"
damping = "20 N*s/m"
{'coulomb_friction = "30 N"' + chr(10) + 'static_friction = "40 N"' + chr(10) + 'stribeck_speed = "5 mm/s"'
 if load_friction else ''}

[sensors]
output_scale_resolution = "1 um"
motor_encoder_counts = 2048
sample_time = "125 us"

[requirements]
{requirements}
{extra}'''
