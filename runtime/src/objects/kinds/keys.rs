//! The configuration keys of the kinds whose configuration lives in this module, as
//! `penelope ctl kinds` shows them (TOML with a comment per key: units and defaults).

pub(super) const ROBOT_KEYS: &str = r#"
start = "start"       # named pose (nest, start, work) where a simulated body starts and where
                      # Galil encoders read zero (the arm is parked there at power-up)
role = "slave"        # "master" (a hand controller: force and moment caps, zero force on a
                      # fault) or "slave" (holds its pose); default: master for frhc, else slave
max_force_n = 10.0    # a master's largest displayed force, N (the FRHC's)
max_moment_nm = 0.5   # a master's largest displayed moment, N·m
"#;

pub(super) const URDF_KEYS: &str = r#"
file = "arm.urdf"     # the URDF file (required): in one of the node's robot-file directories
                      # (`--robot-files`), by name or absolute path; a regular file, 4 MiB
                      # at most; read when the robot is created
tip = "tool0"         # the link whose frame is the tool frame (default: the single leaf link)
base = "base_link"    # the link whose frame is the robot's base frame (default: the root link)
poses = { start = [0.0, 0.8, -3.1, 0.0, 0.8, 0.0] }  # named poses (nest, start, work, ...), rad (m
                      # for prismatic joints), one value per joint; default: all at the zero
                      # configuration (mid-range for a joint whose limits exclude zero)
"#;

pub(super) const SHAPE_KEYS: &str = r#"
[[shapes]]                       # up to 8 contact shapes, base frame of the robot
kind = "plane"                   # "plane" or "sphere"
point = [0.0, 0.0, 0.0]          # m: a point on the plane, or the sphere's centre
normal = [0.0, 0.0, 1.0]         # plane: normal into free space (normalised)
radius = 0.05                    # sphere: radius, m (> 0)
stiffness = 5000.0               # N/m, 0..=1e7
damping = 20.0                   # N·s/m, 0..=1e5
"#;

pub(super) const SIM_BOARD_KEYS: &str = r#"
axes = 6           # number of axes, 1..=8
dac_bits = 16      # DAC resolution, 8..=24 bits
substep_us = 200   # plant integration sub-step, 20..=2000 µs
friction = true    # joint friction of the model in the plant
command_timeout_ms = 50  # with torque on, no new command from the control tick for this long turns
                   # every axis off (the board's own check; the plant keeps moving), 40..=10000 ms (0: off)
brake = false      # power-off holding brakes: the joints stand while the amplifiers are off
                   # (without, an arm whose amplifiers are off falls under gravity)
# the environment the plant's tool touches (none by default):
"#;

pub(super) const FPGA_BOARD_KEYS: &str = r#"
# The FRHC's kinematics board: a robot whose joints are on it (the FRHC only, all six joints)
# computes its forward kinematics, Jacobian frames and tau = J^T F with the board's bit-exact
# model; the results reach the host after 61 (FK) and 92 (FK + force) cycles at 40 MHz plus
# the DMA transfers (`penelope ctl describe` of the board shows the figures). Behind it, the
# simulated plant, with the keys of board/sim:
"#;

pub(super) const GALIL_KEYS: &str = r#"
device = "/dev/ttyUSB0"        # serial device, or else:
address = "127.0.0.1:7400"     # TCP address of a DMC or of `penelope galil-sim` (one of the two is required)
baud = 115200                  # serial baud rate, 1200..=921600
axes = 6                       # axes driven, 1..=8
volts_per_newton_metre = 0.1   # amplifier scaling, V per N·m of joint torque: one value or one per axis (|v| <= 10);
                               # the sign per joint comes from the robot's gear and encoder (negative flips a reversed amplifier)
connect_timeout_ms = 1000      # TCP connect timeout, 10..=60000 ms
watchdog_ms = 30               # the DMC turns its motors off when no exchange reached it for this long, 5..=1000 ms (0: no watchdog)
command_timeout_ms = 50        # with torque on, no new command from the control tick for this long: OF 0, MO, heartbeat stopped, 40..=10000 ms (0: off)
"#;

pub(super) const SENSOR_KEYS: &str = r#"
# A 6-axis wrist sensor model. With `robot`, it reads the contact of that robot's simulated
# body (its board's shapes, or the operator's hand) at the wrist, as a real sensor would:
robot = "puma"               # optional; without it, the shapes below are probed at the reader's tool
mount_xyz = [0.0, 0.0, 0.0]  # sensor frame origin in the tool frame, m
bias = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]   # constant offset, N and N·m (sensor frame)
force_noise = 0.0            # standard deviation per axis, N, 0..=100
torque_noise = 0.0           # standard deviation per axis, N·m, 0..=10
cutoff_hz = 0.0              # first-order low-pass, 0 (off) or 0.1..=10000 Hz
seed = 1                     # noise seed (`penelope demo --seed` sets it)
# Probe mode only: publish on the data plane for controllers on other nodes (read over UDP, the
# same samples for every reader); without it, such a controller is refused at activation.
publish = "127.0.0.1:7420"   # optional; host:port (an IP address), port 0: any free port
publish_period_ms = 1        # measure and send every this many ms, 1..=1000
# Probe mode (no `robot`): the wrench the environment applies to the probe (N, N·m, base frame,
# about the probe point), minus the bias. Empty space by default:
"#;

pub(super) const NETFT_KEYS: &str = r#"
address = "192.168.1.1:49152"  # the box's RDT address, ip:port or an IP alone for port 49152 (required); `penelope netft-sim` prints its own
counts_per_force = 1000000.0   # counts per N, the box's cfgcpf (its /netftapi2.xml), > 0
counts_per_torque = 1000000.0  # counts per N·m, the box's cfgcpt, > 0
mount_xyz = [0.0, 0.0, 0.0]    # sensor frame origin in the tool frame, m
mount_rpy_deg = [0.0, 0.0, 0.0]  # sensor frame orientation in the tool frame (roll, pitch, yaw), degrees
timeout_ms = 20                # a reading older than this is refused (the loop uses no wrench), 1..=10000 ms
max_gap = 4                    # more records lost in one gap than this is a fault (held for timeout_ms)
bias_on_start = false          # ask the box for a software bias when configured (`ctl call NAME bias` any time)
# Status bit 31 (error), saturation (bits 30, 27), a silence past the timeout or a loss burst: the
# loop notes a sensor error and uses no wrench, so a master displays zero force.
"#;

pub(super) const LOOP_KEYS: &str = r#"
period_us = 1000          # control period T_ctrl, 250..=20000 µs
comm_period_us = 2000     # communication period T_com (reference), 250..=100000 µs
watchdog_ms = 50          # a reference older than this holds the robot, 1..=10000 ms
sensor_period_ms = 2      # force-sensor feed period, 1..=1000 ms
sensor_timeout_ms = 20    # an older wrench is not used, 1..=10000 ms
telemetry_period_ms = 10  # telemetry batch period to subscribers, 1..=1000 ms
"#;

pub(super) const JOINT_PID_KEYS: &str = r#"
kp = [...]                      # N·m/rad, one value or one per joint (default 10 × the joint's torque limit, per rad)
ki = 0.0                        # N·m/(rad·s)
kd = [...]                      # N·m·s/rad (default 0.5 × the joint's torque limit, per rad/s)
integral_limit = 0.0            # N·m, cap of the integral term
gravity_compensation = true     # add g(q)
acceleration_feedforward = false # add M(q) qdd_ref
# plus the loop keys:
"#;

pub(super) const JOINT_POSITION_KEYS: &str = r#"
max_velocity = 1.0              # rad/s, one value or one per joint: how fast the servo's target may move
# plus the loop keys:
"#;

pub(super) const JOINT_GROUPS_KEYS: &str = r#"
groups = [{ controller = "arm", joints = [0, 1, 2] }, { controller = "wrist", joints = [3, 4, 5] }]
# each joint of the robot in exactly one group; a member is a configured controller/joint-pid or
# controller/joint-position with the same robot, following its own trajectory (joint or tool
# goals); the members run in this controller's loop, not on their own
# plus the loop keys:
"#;

pub(super) const IMPEDANCE_KEYS: &str = r#"
stiffness = [2000.0, 2000.0, 2000.0, 50.0, 50.0, 50.0]  # N/m then N·m/rad, base frame
damping = [150.0, 150.0, 150.0, 3.0, 3.0, 3.0]          # N·s/m then N·m·s/rad
gravity_compensation = true
max_force = inf          # N, cap of the commanded force (inf: none)
max_torque = inf         # N·m
ramp_in_ms = 0           # stiffness ramp after activation, 0..=60000 ms
# plus the loop keys:
"#;
