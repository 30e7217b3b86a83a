"""Index layout of the flat state and parameter arrays shared by every compiled kernel.

State ``x`` (float64)::

    0 p      motor-side position, expressed as the output angle a rigid chain would give (rad)
    1 pd     its rate (rad/s); motor speed omega_m = N(p) * pd
    2 q      load-side (output) angle (rad)
    3 qd     output rate (rad/s)
    4 i      armature current (A); unused (held) without inductance
    5 xi     current-PI integral (V)
    6 s      play-operator output (rad): the position of the backlash's load side, an absolute
             coordinate at the output like p and q (m for an output travel), kept within the
             half play of p by the cam paper's discrete scheme only; every other method holds
             it at its start value (the elasto-backlash law needs no state)
    7..      motion-controller states (continuous mode integrates them; sampled mode updates
             them at the sample instants)
    then     speed-estimator states (sampled mode, updated at the sample instants; their
             derivative is 0): "difference" [last motor-encoder angle, speed estimate],
             "kalman" [angle, speed, acceleration estimates] (rad, rad/s, rad/s^2 of the motor)
    then     the full chain's intermediate nodes (``NMID`` of them, from ``OFF_NODE``): angle
             and rate of each, referred to the output like p and q (rad, rad/s; m, m/s for an
             output travel)

The compiled kernels (``servo_toolkit/_physics``) read every constant below from
``layout.h``, generated from this module (:mod:`.layout_header`; the tests check the two agree).
"""

from __future__ import annotations

STATE_NAMES = ("motor_side_angle_rad", "motor_side_rate_rad_s", "output_angle_rad",
               "output_rate_rad_s", "current_A", "current_integral_V", "play_state_rad")
NX_PHYS = 7

# motor and current loop
# WS holds 1 / friction_speed
R, L, KT, KE, BM, TC, WS, VLIM, ILIM, KPI, KII = range(11)
# mechanics
JL, RIGID, KSCALE, BETA, HALF_PLAY, HINGE_M, HINGE_K, HINGE_D = range(11, 19)
STROKE_LO, STROKE_HI, STROKE_MODE, KSTOP, DSTOP = range(19, 24)
# tables
TAB_LO, TAB_H, TAB_N, PERIODIC = range(24, 28)
# controller
CMODE, NC, TS, LSB, V_OPEN, OFF_A, OFF_B, OFF_C, OFF_D = range(28, 37)
# reference
REF_KIND, REF_A, REF_F, REF_OFF, REF_T0 = range(37, 42)
# method flag (1 = the cam paper's play operator replaces the elasto-backlash law)
PAPER = 42
# reciprocals (the kernel multiplies instead of dividing)
INV_H, INV_L, INV_JL = 43, 44, 45
# speed estimator: kind, motor-encoder quantum (rad, 0 = unquantized), index in x of its first
# state, index in P of the constant-gain Kalman filter (F row-major 3x3, then the gain K, 3),
# 1 / sample time
EST, LSB_M, OFF_E, OFF_KF, INV_TS = 46, 47, 48, 49, 50
# back-calculation anti-windup gain of the current PI (1/s): Kii / Kpi (R / L for a pure I)
KAW = 51
# index in P of a chain-ending cam's parameters (mechanisms.cam_kernels.pack_cam; 0 = none):
# its follower weight and guide friction load the cam shaft (seed 002 eq 3)
CAM = 52
# drivetrain efficiency (LossyGear-like loss on the motor torque reflected to the output):
# mean and half difference of the loss coefficients 1 - eta (driving) and 1/eta_b - 1
# (back-driven), and 1 / the torque scale of the smooth sign of the transmitted torque
ETA_MEAN, ETA_HALF, INV_TAU_S = 53, 54, 55
# inertia before the losses at the motor shaft (kg*m^2): the motor side's share of the chain's
# J_w (drivetrain.chain.Chain.loss_inertia) over N^2; the loss never acts on its torque
JW = 56
# 1 / the motor side's inertia at q0 (J(q0) - JL): the scale of the loss's smooth torque sign
# (:func:`kernel.lossy`), a product where a division would cost the step rate
INV_JD0 = 57
# the full chain (:func:`servo_toolkit.sim.chain_model.chain_model`): number of intermediate
# nodes between the motor side (p) and the load (q) (0: two-mass or rigid), index in x of the
# first intermediate node's angle, and index in P of the segment block: per segment s = 0..NMID
# (between node s and s + 1), SEG_STRIDE values [half play, loss fraction of its spring
# (1 - eta / Pi_s) / (1 - eta), its damper's beta_s (s): the damper is beta_s k_s(p)]
NMID, OFF_NODE, OFF_SEG = 58, 59, 60
SEG_STRIDE = 3
SEG_PLAY, SEG_LOSS, SEG_BETA = range(3)
# friction that holds (:func:`servo_toolkit.sim.kernel.slip_friction`, STICK = 1): the
# motor's breakaway torque (N*m at the motor shaft; TC is its Coulomb level) and 1 / its
# Stribeck speed (s/rad; inf: the drop from Ts to Tc at once), the load's Coulomb and breakaway
# moments (N*m, N) and 1 / its Stribeck speed; STICK = 0: the smooth model Tc tanh(w / w_s) of
# the motor's Coulomb friction alone
TS_M, INV_VS_M, TC_L, TS_L, INV_VS_L, STICK = range(61, 67)
# feedforward from the commanded trajectory (:class:`servo_toolkit.loop.controller.Feedforward`,
# :func:`servo_toolkit.sim.kernel.feedforward`): 1 when the controller sample does more than
# the state-space update (a feedforward, a gain schedule, the clamp's back-calculation; 0: the
# controller's output alone), velocity and acceleration gains (A per rad/s, A per rad/s^2), 1
# for the model-based torque feedforward, the scale of its inertia relative to the tables', 1 when the speed loop
# takes the motor speed along the commanded trajectory as its reference, and the time (s) by
# which the feedforward current leads the sample instant (half a sample)
FF_ON, FF_KV, FF_KA, FF_MODEL, FF_JSCALE, FF_SPEED, FF_LEAD = range(67, 74)
# slots 74..117 are reserved for further header blocks (each block states its own meaning)
# 74..81: the drivetrain chain's per-node tables and damping (the full chain,
# :mod:`servo_toolkit.sim.chain_model`; 0 in a two-mass or rigid model): the table row of the
# motor node's inertia before the losses J_w,0(p) (value row, then its derivative along p), and
# the first table row of the further nodes: node j = 1..NMID + 1 (the intermediate nodes, then
# the load's) has NODE_ROWS rows from ROW_NODE + NODE_ROWS (j - 1), its inertia J_j(p), dJ_j/dp,
# its inertia before the losses J_w,j(p), dJ_w,j/dp, every one tabulated at the motor-side
# position p (each segment's damper is in the segment block, SEG_BETA); 76..81 free
ROW_JW0, ROW_NODE = 74, 75
NODE_ROWS = 4
# 82..89: friction at the chain's nodes. DIR_M, DIR_L: the direction the motor side's and the
# load's sliding friction is held at (+-1; 0, the default: the sign of the node's speed), set
# only in the scratch parameter copy with which ``servo_toolkit/_physics/split_step.h`` locates a
# speed reversal within the step (the motion before it continued smoothly past the zero)
DIR_M, DIR_L = 82, 83
# 84..86: the drivetrain's loss at rest (friction that holds, :func:`servo_toolkit.sim.kernel.
# gear_at_rest`): 1 / eta - 1 (eta the forward efficiency; 0: lossless) and 1 - max(eta_b, 0)
# (eta_b the back-drive efficiency, 0 or less for a self-locking chain; 0: lossless, 1:
# self-locking), and HOLD_GAUGE, set only in the scratch parameter copies with which
# ``servo_toolkit/_physics/split_step.h`` and :mod:`servo_toolkit.sim.ivp` locate a breakaway: 1, a
# node at rest reports its signed breakaway distance (> 0 beyond the band) in place of its
# acceleration times its inertia; 2, the side it would break away to (> 0 forward); 87..89 free
HOLD_FWD, HOLD_BACK, HOLD_GAUGE = 84, 85, 86
# 90..97: a sampled position command (REF_KIND = REF_TABLE, ``servo_toolkit/_physics/command.h``):
# index in P of its data (values y_0..y_{n-1}, then the slopes m_0..m_{n-1} of the cubic
# Hermite interpolant through them, rad/s or m/s), the number of samples n, the time of the first
# sample (s), 1 / the sample spacing (1/s), 1 for a periodic table (its last sample repeats the
# first: the command wraps with period (n - 1) spacings), and a fingerprint of the data (a
# 48-bit hash, exact in a float), so that equal slots mean equal commands; 96..97 unused
REF_TAB_OFF, REF_TAB_N, REF_TAB_T0, REF_TAB_INV_DT, REF_TAB_WRAP, REF_TAB_SUM = range(90, 96)
# gain scheduling along the stroke and command shaping (slots 98..105;
# :mod:`servo_toolkit.loop.schedule`, :mod:`servo_toolkit.loop.shaper`,
# ``servo_toolkit/_physics/command.h``): index in P of the gain schedule (0: none; its block
# [points, first position, 1 / step, the position-error factors, the speed factors], linear
# between its points, its end values held beyond them), the offset (kg*m^2; kg for a travel)
# of the feedforward's inertia from the model's (the load inertia the feedforward assumes less
# the model's: a Monte Carlo variant's feedforward keeps the nominal load), the command
# shaper's impulse amplitudes (SHAPE_A0 = 0: no shaper) and the times of its second and third
# impulses (s; the first is at 0), and the index in P of the clamp's back-calculation gains
# (one per motion-controller state: the integrator's direction over its output gain, and for a
# continuous controller then its tracking rate Kaw, 1/s; 0: none)
SCHED, FF_DJ, SHAPE_A0, SHAPE_A1, SHAPE_A2, SHAPE_T1, SHAPE_T2, AW = range(98, 106)
#: reference kind of a jerk-limited move (:class:`servo_toolkit.sim.reference.Reference`); its
#: REF_F slot holds the index in P of the move's block [signed jerk, jerk time,
#: constant-acceleration time, constant-speed time]
REF_MOVE = 6
# 106..113: toleranced parameters
# 114..117: friction at the full chain's intermediate nodes (:mod:`servo_toolkit.sim.node_friction`):
# the index in P of their block (0: none), NF_STRIDE values per intermediate node j = 1..NMID
# from NODE_FRIC + NF_STRIDE (j - 1): its Coulomb and breakaway levels (N*m; N for an output
# travel), 1 / its Stribeck speed (s/rad; s/m; inf: the drop at once) and its viscous
# coefficient, every one at the node's coordinate (referred to the output like q), and the
# direction its sliding friction is held at (+-1; 0, the default: the sign of its speed; as
# DIR_M for the motor side); the levels are 0 unless the friction holds (``STICK``); 115..117 free
NODE_FRIC = 114
NF_STRIDE = 5
NF_TC, NF_TS, NF_INV_VS, NF_VISC, NF_DIR = range(5)
NP_HEADER = 118
#: length of the packed cam parameters
NCAM = 14

# table rows (cubic Hermite: value row followed by derivative row); T_M is the motor angle
# (rad, 0 at mid-stroke), whose derivative row is N
T_J, T_DJ, T_N, T_DN, T_K, T_DK, T_M, T_DM = range(8)
NT_ROWS = 8
# the full chain's further segments s = 1..NMID: stiffness rows T_KS + 2 (s - 1) (value,
# derivative), tabulated at the motor-side position p like T_K (segment 0)
T_KS = 8

# speed estimators (``[sensors] speed_estimator``) and their state counts
EST_IDEAL, EST_DIFFERENCE, EST_KALMAN = 0, 1, 2
ESTIMATORS = ("ideal", "difference", "kalman")
EST_STATES = (0, 2, 3)

# controller modes
OPEN_LOOP, SAMPLED, CONTINUOUS = 0, 1, 2
# stroke-end modes
STROKE_ERROR, STROKE_STOP, STROKE_NONE = 0, 1, 2
# reference kinds
REF_CONST, REF_SINE, REF_STEP, REF_RAMP = 0, 1, 2, 3
#: a sampled command: REF_OFF plus the table's interpolated value (slots 90..95)
REF_TABLE = 4

# aux outputs written by the right-hand side
AUX_I, AUX_V, AUX_IREF, AUX_TAU = range(4)
NAUX = 4

# loop status codes
OK, NONFINITE, STROKE_END = 0, 1, 2

# a fixed-step run's figures, kept at every step (not only at the records): status, steps
# done, max |q - r| (rad or m), max |i| (A), 1 when the current reference or the voltage
# reached its limit, max |motor torque| (N*m)
F_STATUS, F_STEP, F_ERR, F_CUR, F_SAT, F_TAU = range(6)
NFIG = 6
# its snapshots (state, then time and held i_ref): at the peak |current|, at the largest
# |p - q|, at the end
S_PEAK, S_DEFLECTION, S_END = range(3)
NSNAP = 3

# friction switches located within a step (``servo_toolkit/_physics/split_step.h``): the
# switch's instant is located to TAU_TOL of the step (the Illinois bracket's width), in at most
# MAX_ITER iterations (about 6 to 10 are taken), at most MAX_SWITCHES switches per step (the
# rest of the step after the last is one RK4 step); HELD, a breakaway level out of reach (the node held at rest); SEED, the speed
# (rad/s, m/s) a node breaking away leaves rest with: its direction only
TAU_TOL = 1e-12
MAX_ITER = 60
MAX_SWITCHES = 4
HELD = 1e300
SEED = 1e-290

# the smooth friction's steps through the band of its smooth sign (``servo_toolkit/_physics/
# integrate.h``, smooth_substeps): a step whose motor speed changes sign or comes within
# SMOOTH_BAND smoothing speeds of zero (tanh(3) = 0.995: beyond it the sign has settled), and
# that moves the sign's argument N p' / w_s by more than SMOOTH_RESOLUTION, is taken in
# SMOOTH_SUBSTEPS RK4 substeps
SMOOTH_BAND = 3.0
SMOOTH_RESOLUTION = 0.1
SMOOTH_SUBSTEPS = 8

# a fixed-step run advanced in chunks (:func:`servo_toolkit.sim.integrators.integrate`): the loops'
# state carried from one chunk to the next: held current reference, steps to the next
# controller sample and to the next record, records written, peak |motor torque|, and RK4's
# running figures (peak |tracking error|, |current|, deflection, a limit reached)
C_IREF, C_TO_SAMPLE, C_TO_RECORD, C_NREC, C_MAX_TAU, C_MAX_ERR, C_MAX_CUR, C_MAX_DEFL, C_SAT = range(9)
NCARRY = 9
