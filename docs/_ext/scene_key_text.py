"""One sentence per scene key where the component's docstring gives none of its own.

The scene reference takes a key's meaning from the numpydoc ``Parameters`` of the component
its table builds; a docstring that documents several keys at once (``viscous_friction,
coulomb_friction : float``), a bare unit (``K.``) or a table without a component (the study
tables) leaves a key without its own sentence. These sentences fill them: what the key is,
in the words of the physics; the unit, default and range are in the row's other columns.
"""

from __future__ import annotations

#: (table pattern, key) -> sentence; the pattern as the reference groups tables
#: (``motor``, ``drivetrain[]``, ``studies.*``, ...)
BY_TABLE = {
    # the motor
    ("motor", "kind"): "Motor type: `dc`, a permanent-magnet DC motor (the only kind).",
    ("motor", "torque_constant"): "Torque constant Kt: motor torque per armature ampere.",
    ("motor", "back_emf_constant"): "Back-EMF constant Ke: armature voltage per motor speed; equals Kt in SI "
                                    "within 10 % (the scene is refused otherwise, naming the likely unit slip).",
    ("motor", "rotor_inertia"): "Rotor inertia Jm about the motor shaft.",
    ("motor", "viscous_friction"): "Viscous friction coefficient b of the motor: torque per motor speed.",
    ("motor", "coulomb_friction"): "Coulomb (sliding) friction torque Tc of the motor, opposing its motion.",
    ("motor", "voltage_limit"): "Supply voltage the drive can apply to the armature; unlimited when absent.",
    ("motor", "current_limit"): "Armature current the drive allows; unlimited when absent.",
    ("motor", "continuous_torque"): "Datasheet continuous (stall) torque; absent: the sizing takes it from "
                                    "the thermal network.",
    ("motor", "peak_torque"): "Datasheet peak torque; absent: the sizing takes it from the current limit.",
    ("motor", "thermal_resistance_winding"): "Thermal resistance from the winding to the housing.",
    ("motor", "thermal_resistance_housing"): "Thermal resistance from the housing to the ambient air.",
    ("motor", "thermal_time_constant_winding"): "Thermal time constant of the winding node (its heat "
                                                "capacity times the winding-to-housing resistance).",
    ("motor", "thermal_time_constant_housing"): "Thermal time constant of the housing node (its heat "
                                                "capacity times the housing-to-ambient resistance).",
    ("motor", "ambient_temperature"): "Temperature of the air around the motor, the thermal network's "
                                      "reference (an absolute temperature: \"40 degC\" is 313.15 K).",
    # stages
    ("drivetrain[]", "kind"): "Stage type: `gear`, `ball_screw`, `roller_screw`, `rocker_linkage`, `cam` or "
                              "`compliance`; each stage takes what the previous one delivers.",
    ("drivetrain[]", "name"): "The stage's name in tables, figures and messages.",
    ("drivetrain[]", "stroke"): "Range [lowest, highest] of the output this stage drives (a gear's output "
                                "angle, a screw's nut travel); only on the stage that drives the output.",
    ("drivetrain[]", "inertia"): "Each gear's inertia about its own axis, in the order of `teeth` (with "
                                 "`ratio` alone: [input gear, output gear]).",
    ("drivetrain[]", "screw_inertia"): "Inertia of the screw about its axis.",
    ("drivetrain[]", "stages"): "The roller screw's stages, `[[drivetrain.stages]]` from the motor side, "
                                "each with the keys of a roller-screw stage below.",
    ("drivetrain[]", "roller_screw_friction"): "Friction coefficient mu_RS between rollers and screw.",
    ("drivetrain[]", "screw_screw_friction"): "Friction coefficient mu_SS between a stage's screw and the next "
                                              "stage's (the spline joint).",
    ("drivetrain[]", "nut_screw_friction"): "Friction coefficient mu_NS between a nut and the screw it drives.",
    ("drivetrain[]", "axial_stiffness"): "Axial stiffness of the screw, nut and bearings in series; `inf` or "
                                         "absent: rigid.",
    ("drivetrain[]", "rod_axial_stiffness"): "Axial stiffness of the link rod along the line of its pins; `inf` "
                                             "or absent: rigid.",
    ("drivetrain[]", "viscous_friction"): "Viscous friction coefficient at the stage's output: moment per speed "
                                          "(force per speed for a travel).",
    ("drivetrain[]", "guide_friction_coefficient"): "Friction coefficient mu of the follower's ball guide.",
    ("drivetrain[]", "law"): "Cam law of the profile: `modified_constant_velocity`.",
    ("load", "damping"): "Viscous damping of the load: moment per output speed (force per speed for an output "
                         "travel).",
    ("drivetrain[]", "arm_length"): "Rocker arm radius r, from the output shaft to the rod's pin.",
    ("drivetrain[]", "rod_length"): "Length l of the link rod between its two pins.",
    ("drivetrain[]", "rod_offset"): "Offset h - r of the screw axis from the arm tip's line at zero angle (0: "
                                    "the rod is parallel to the screw there).",
    ("drivetrain[]", "output_shaft_mass"): "Mass of the output shaft (it carries no rotation of its own: "
                                           "reported, not reflected).",
    ("drivetrain[]", "output_shaft_inertia"): "Inertia of the output shaft about its axis.",
    ("drivetrain[]", "profile_constant"): "Cam profile constant A: the follower's lift scale.",
    ("drivetrain[]", "follower_mass"): "Mass m of the cam follower.",
    ("drivetrain[]", "follower_weight"): "Weight G of the follower carried by the cam (a spring or gravity).",
    ("drivetrain[]", "gravity_tilt"): "Tilt gamma of the follower's axis from the vertical.",
    ("drivetrain[]", "gravity_heading"): "Heading beta of the follower's tilt about the vertical.",
    # tables without a component of their own
    ("robustness", "seed"): "Seed of the random variants (the same seed draws the same variants).",
    ("robustness", "min_gain_margin"): "Smallest gain margin over the stable variants.",
    ("robustness", "min_phase_margin"): "Smallest phase margin over the stable variants.",
    ("robustness", "max_sensitivity_peak"): "Largest sensitivity peak Ms over the stable variants.",
    ("tolerances", "samples"): "Number of built actuators (variants) drawn from the distributions.",
    ("tolerances", "max_tracking_error"): "Largest tracking error of each variant's nonlinear time run (in the "
                                          "output's unit: rad or m).",
    ("tolerances", "max_peak_current"): "Largest peak motor current of each variant's nonlinear time run.",
    ("duty_cycle", "segments"): "The motion's segments in order, `[[duty_cycle.segments]]`, each with a kind.",
    ("duty_cycle.segments[]", "frequency"): "Frequency of a sine segment (or give its period).",
    ("duty_cycle.segments[]", "period"): "Period of a sine segment (or give its frequency).",
    ("mechanism", "ratio_x"): "Gear ratio z4/z3 of the x axis drive.",
    ("mechanism", "ratio_y"): "Gear ratio z2/z1 of the y axis drive.",
    ("mechanism", "kind"): "Mechanism type: `crossed_arch_platform`, a deflection platform on two crossed arches.",
    ("operating", "screw_speed"): "Speed of the first screw at the operating point.",
    ("operating", "load"): "Axial load on the last nut at the operating point.",
    ("operating", "roller_screw_friction"): "Friction coefficients mu_RS between rollers and screw, one per "
                                            "stage (or one for all).",
    ("operating", "screw_screw_friction"): "Friction coefficients mu_SS at the spline joints between stages.",
    ("operating", "nut_screw_friction"): "Friction coefficients mu_NS between each nut and the screw it drives.",
}

#: key -> sentence, for a key that means the same in every table that reads it
BY_KEY = {
    "kind": "The table's type, one of the values in the rule column.",
    "name": "A name for tables, figures and messages.",
    # study keys
    "frequency": "Frequency of the sine command (or give its period).",
    "period": "Period of the sine command (or give its frequency).",
    "amplitude": "Amplitude of the sine command about the operating point, in the output's unit (deg or mm).",
    "amplitudes": "Amplitudes of the sine command, one run each, in the output's unit.",
    "frequencies": "Frequencies of the sweep: a list, or `{start, stop, points, spacing}`.",
    "duration": "Length of the simulated run.",
    "sample_time": "Time step of the run (the fixed step of rk4 and paper).",
    "method": "Integration method: `rk4`, `paper`, `reference` or `auto`.",
    "trajectory": "Shape of the prescribed motion: `sine`.",
    "amplitude_at": "Where the amplitude applies: at the `output`, or at the `motor` gear (an angle).",
    "offset": "Centre of the sine about which the output moves (default: the design's operating point).",
    "load_inertias": "External load inertias (masses for an output travel) the Kv study runs with, one run each.",
    "voltage": "Constant armature voltage of an open-loop run (no controller).",
    "speed_estimator": "Speed signal of the run's speed loop: `ideal`, `difference` or `kalman` (`true` is "
                       "`ideal`).",
    "encoder_counts": "Motor encoder counts per revolution for the run's speed estimator.",
    "kalman_jerk": "Jerk level of the Kalman speed estimator's random-jerk model.",
    "rate_alpha": "Rate of the platform's alpha axis during the inverse-dynamics run.",
    "rate_beta": "Rate of the platform's beta axis during the inverse-dynamics run.",
    "external_moments": "External moments on the platform's axes, `{x, y}`.",
    "speed": "Speed of the mechanism's input during the sweep.",
    "gravity_tilts": "Tilts of the gravity direction, one sweep each.",
    "gravity_headings": "Headings of the gravity direction's tilt, one sweep each.",
    "x": "External moment about the platform's x axis.",
    "y": "External moment about the platform's y axis.",
    "start": "Lowest frequency of the sweep.",
    "stop": "Highest frequency of the sweep.",
    "points": "Number of frequencies of the sweep, ends included.",
    "spacing": "Spacing of the sweep's frequencies: `log` or `linear`.",
    # roller-screw stages
    "screw_radius": "Pitch radius of the stage's screw.",
    "roller_radius": "Pitch radius of each roller.",
    "nut_radius": "Pitch radius of the nut's thread.",
    "screw_starts": "Number of thread starts of the screw.",
    "lead": "Travel of the nut per turn of the screw.",
    "flank_angle": "Flank angle of the thread profile.",
    "ring_gear_pressure_angle": "Pressure angle of the ring gears that keep the rollers parallel.",
    "rollers": "Number of rollers in the nut.",
    "roller_mass": "Mass of one roller.",
    "nut_mass": "Mass of the nut and what it carries rigidly.",
    "roller_inertia": "Inertia of one roller about its own axis.",
    "screw_inertia": "Inertia of the stage's screw about its axis.",
    "carrier_inertia": "Inertia of the roller carrier (cage) about the screw axis.",
    "screw_mass": "Mass of the stage's screw (it travels with the previous stage's nut).",
    "screw_spline_radius": "Radius of the spline joining this stage's screw to the previous stage.",
    "nut_screw_joint_radius": "Radius of the joint between the previous nut and this stage's screw.",
    # crossed-arch platform
    "inertia_large_arch": "Inertia of the large arch about its axis.",
    "inertia_small_arch": "Inertia of the small arch about its axis.",
    "inertia_small_guide": "Inertia of the small arch's guide.",
    "inertia_large_guide": "Inertia of the large arch's guide.",
    "inertia_pin_8": "Inertia of pin 8 about its axis.",
    "inertia_pin_11_about_o": "Inertia of pin 11 about the platform's centre O.",
    "inertia_pin_11_spin": "Inertia of pin 11 about its own axis.",
    "inertia_pinion_15": "Inertia of pinion 15 about its axis.",
    "inertia_pinion_16": "Inertia of pinion 16 about its axis.",
}


def key_text(pattern: str, key: str, documented: str) -> str:
    """The sentence for ``key`` of a table ``pattern``: this module's when it has one for the
    table or the key, else ``documented`` (the component's docstring)."""
    return BY_TABLE.get((pattern, key)) or (documented if documented else BY_KEY.get(key, ""))


__all__ = ["BY_KEY", "BY_TABLE", "key_text"]
