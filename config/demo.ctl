# The demo's system (config/demo.toml) made object by object with `penelope ctl` verbs, on a
# node named `lab`, in another order than the system file's: robots before their boards,
# the channel and the controllers before the sensors, the sensors last, and the slave's
# controller activated before the master's. Same keys, same values, same result:
#
#   penelope naming &
#   penelope node --name lab --sim-clock &
#   penelope ctl run config/demo.ctl
#   penelope ctl advance lab 20s          # the operator's 20-second script
#
# `tools/tests/demo_by_ctl.rs` checks that this gives, tick for tick and bit for bit, the
# telemetry of `penelope demo --sim-clock` with the same seed.

# Robots first, then the boards they sit on.
create lab robot/puma200 puma start=start
create lab robot/frhc frhc start=start
create lab board/sim puma-io --config 'shapes = [{ kind = "plane", point = [0.350868, 0.127, 0.2902], normal = [0.0, 0.0, 1.0], stiffness = 4000.0, damping = 20.0 }]'
create lab board/sim frhc-io
call lab/puma map-joints puma-io 0:0 1:1 2:2 3:3 4:4 5:5
call lab/frhc map-joints frhc-io 0:0 1:1 2:2 3:3 4:4 5:5

# The channel, and the halves of the laws with the file's [timing] keys.
create lab trajectory/teleop link master=frhc slave=puma scale=1.0 force_gain=0.5 'rotation_rpy_deg=[0.0, 0.0, 0.0]'
create lab controller/slave-tracking follow period_us=1000 comm_period_us=2000 watchdog_ms=50
create lab controller/position-error-master position-error period_us=1000 comm_period_us=2000 watchdog_ms=50
create lab controller/force-display display period_us=1000 comm_period_us=2000 watchdog_ms=50

# The sensors last: the slave's wrist sensor (seed 1, as `penelope demo --seed 1`) and the
# operator's scripted hand on the FRHC.
create lab sensor/virtual wrist robot=puma 'mount_xyz=[0.0, 0.0, 0.02]' force_noise=0.05 torque_noise=0.002 cutoff_hz=30.0 seed=1
create lab sensor/operator-hand hand robot=frhc script=demo stiffness_n_per_m=400.0 damping_ns_per_m=12.0

call lab/follow set-robot puma
call lab/follow set-trajectory link
call lab/follow set-sensor wrist
call lab/display set-robot frhc
call lab/display set-trajectory link
call lab/position-error set-robot frhc
call lab/position-error set-trajectory link

# Configure: the slave's side first, then the master's, then the channel and the controllers.
configure lab/puma-io
configure lab/wrist
configure lab/puma
configure lab/frhc-io
configure lab/hand
configure lab/frhc
configure lab/link
configure lab/follow
configure lab/display
configure lab/position-error

# One master half at a time: the force-position law, as `penelope demo` runs by default.
activate lab/follow
activate lab/display
