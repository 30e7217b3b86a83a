"""A commented scene to start from: ``servo-toolkit new SCENE.toml --output angle|travel``.

Every section a scene has, the keys a motor-driven actuator needs, each with its unit and a
typical value, and the optional keys commented out with their defaults. The two starting
points load and pass ``check`` as written (the tests hold them to it): a gearmotor turning an
output shaft (``angle``) and a gearmotor driving a ball screw and a carriage (``travel``).
"""

from __future__ import annotations

#: the outputs a starting scene is written for
OUTPUTS = ("angle", "travel")

_HEAD = """\
# {title}
#
# A starting point written by `servo-toolkit new`: replace the values with your actuator's.
# A quantity is a string with its unit ("0.5 mH", "1696.8 N*m/deg", "6 dB") or a bare number
# in SI (a bare number far from its key's typical values loads with a note naming the unit it
# was read in). Lines starting with # are optional keys at their defaults. Every key, its
# unit, default and rule: docs/reference/scene_keys.md.
#   servo-toolkit check {file}       does the loop meet [requirements]? (exit 0 yes, 1 no)
#   servo-toolkit report {file}      the full report, HTML and PDF

name = "{name}"
description = "{description}"

[motor]                                  # a permanent-magnet DC motor (kind = "dc")
kind = "dc"
resistance = "0.5 ohm"                   # armature resistance R, terminal to terminal
inductance = "0.5 mH"                    # armature inductance L ("0 H" neglects it)
torque_constant = "0.2 N*m/A"            # Kt
back_emf_constant = "0.2 V*s/rad"        # Ke: equals Kt in SI (within 10 %); "V/krpm" works too
rotor_inertia = "2.0e-4 kg*m^2"
viscous_friction = "1.0e-4 N*m*s/rad"    # b, at the motor shaft
coulomb_friction = "0.02 N*m"            # Tc, at the motor shaft
voltage_limit = "270 V"                  # drive supply (default: unlimited)
current_limit = "60 A"                   # drive current limit (default: unlimited)
# static_friction = "0.03 N*m"           # breakaway torque, at least coulomb_friction
# stribeck_speed = "0.5 rad/s"

# Stages, listed from the motor to the load ([[drivetrain]] once per stage).
[[drivetrain]]
kind = "gear"
name = "gear train"
ratio = {ratio}                             # input turns per output turn (or teeth = [z1, z2, ...])
inertia = ["1.0e-5 kg*m^2", "3.5e-5 kg*m^2"]   # [input gear, output gear], each about its own axis
efficiency = 0.97                        # power efficiency in (0, 1]
torsional_stiffness = "{gear_stiffness}"   # mesh stiffness seen at the output shaft ("inf" or absent: rigid)
backlash = "0.05 deg"                    # lost motion at the output shaft
"""

_ANGLE = """\
stroke = ["-90 deg", "90 deg"]           # range of the output angle (default +-180 deg)

[load]                                   # at the output shaft
inertia = "0.5 kg*m^2"
hinge_moment = "20 N*m"                  # constant moment opposing positive motion
# hinge_stiffness = "0 N*m/rad"          # a spring to the frame
# damping = "0 N*m*s/rad"
# coulomb_friction = "0 N*m"
"""

_TRAVEL = """\

[[drivetrain]]
kind = "ball_screw"
name = "ball screw"
lead = "5 mm"                            # nut travel per screw turn ("5 mm/turn" reads the same)
screw_inertia = "1.3e-5 kg*m^2"
nut_mass = "0.6 kg"                      # the nut and what it carries rigidly
efficiency = 0.90
axial_stiffness = "2.0e8 N/m"            # screw, nut and bearings ("inf" or absent: rigid)
backlash = "10 um"                       # axial lash of the nut
stroke = ["-50 mm", "50 mm"]             # range of the nut's travel (default +-50 mm)

[load]                                   # at the nut: the output is a travel
inertia = "20 kg"                        # the carriage's mass
hinge_moment = "50 N"                    # constant force opposing positive travel
# damping = "0 N*s/m"
# coulomb_friction = "0 N"               # the carriage's guide friction
"""

_TAIL = """\

[sensors]
{output_encoder}
motor_encoder_counts = 4096              # motor encoder counts per revolution (0: ideal)
sample_time = "0.1 ms"                   # controller sample time (0: continuous)
# speed_estimator = "ideal"              # or "difference", "kalman" (from the motor encoder)

[requirements]                           # what the position loop must do (small signal)
bandwidth = "{bandwidth}"                       # closed-loop -3 dB
max_phase_lag_at_bandwidth = "90 deg"
min_gain_margin = "6 dB"
min_phase_margin = "45 deg"
max_sensitivity_peak = "6 dB"

# Named studies: `servo-toolkit simulate {file} --study sine`, `kv ... --study kv`.
[studies.sine]
kind = "simulate"                        # a sine command, closed loop
amplitude = "{amplitude}"                      # its amplitude about the operating point
frequency = "2 Hz"
duration = "1 s"

[studies.kv]
kind = "kv"
trajectory = "sine"
frequency = "2 Hz"
amplitudes = ["{amplitude}"]
load_inertias = [{load_inertias}]
"""

_FILLS = {
    "angle": dict(title="A gearmotor turning an output shaft (output angle)",
                  description="DC gearmotor, 100:1, on an output shaft", ratio="100.0",
                  gear_stiffness="2.0e4 N*m/rad", bandwidth="5 Hz", amplitude="2 deg",
                  output_encoder="output_encoder_bits = 16                 # output encoder, counts per revolution "
                                 "= 2**bits (0: ideal)",
                  load_inertias='"0 kg*m^2", "0.5 kg*m^2"'),
    "travel": dict(title="A gearmotor driving a ball screw and a carriage (output travel)",
                   description="DC motor, 2:1 gear, 5 mm ball screw, 20 kg carriage", ratio="2.0",
                   gear_stiffness="1.6e4 N*m/rad", bandwidth="8 Hz", amplitude="1 mm",
                   output_encoder='output_scale_resolution = "1 um"         # linear scale on the carriage, '
                                  'length per count (0: ideal)',
                   load_inertias='"0 kg", "20 kg"'),
}


def scene_template(output: str = "angle", name: str = "my_actuator", file: str = "SCENE.toml") -> str:
    """The text of a commented scene to start from.

    Parameters
    ----------
    output : {"angle", "travel"}
        The actuator's output: a shaft angle (a gearmotor) or a travel (a gearmotor and a
        ball screw driving a carriage).
    name : str
        The scene's ``name``.
    file : str
        The file name the comments' example commands use.

    Returns
    -------
    str
        TOML text that loads and passes ``check`` as written.

    Raises
    ------
    ValueError
        ``output`` is not one of :data:`OUTPUTS`.
    """
    if output not in OUTPUTS:
        raise ValueError(f"output must be one of {OUTPUTS}, got {output!r}")
    fills = dict(_FILLS[output], name=name.replace('"', "'"), file=file)
    return (_HEAD + (_ANGLE if output == "angle" else _TRAVEL) + _TAIL).format(**fills)


__all__ = ["OUTPUTS", "scene_template"]
