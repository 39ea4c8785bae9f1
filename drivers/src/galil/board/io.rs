//! The board's I/O thread: owns the protocol client, runs the exchange cycle, supervises the
//! board-side watchdog and makes every fault end safe.

// Several per-axis arrays (commands, modes, replies, state) are walked in step by axis index.
#![allow(clippy::needless_range_loop)]

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use penelope_hal::board::{AxisCommand, AxisState, MAX_AXES};
use penelope_rt_core::cell::{ArcLatestReader, ArcLatestWriter, Fresh};

use super::super::client::{BoardInfo, Client, Reply};
use super::super::command::{Axes, Command, MAX_GALIL_AXES, Setting, Tell, encode_line};
use super::super::error::GalilError;
use super::super::link::Link;
use super::super::number::{parse_numbers, to_counts};
use super::watchdog::{self, HEARTBEAT, TRIPPED, WATCHDOG_LABEL, WATCHDOG_THREAD};
use super::{
    BoardFault, CommandFrame, GalilBoardConfig, LinkFactory, MAX_VOLTS, Shared, StateFrame,
    TargetMode,
};

/// What an axis is currently set up for on the board.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Mode {
    /// Not known (at start: whatever the board was doing).
    Unknown,
    Off,
    Position,
    Effort,
}

/// The I/O thread's state.
pub(super) struct Io {
    config: GalilBoardConfig,
    factory: LinkFactory,
    client: Option<Client<Box<dyn Link + Send>>>,
    modes: [Mode; MAX_AXES],
    gains: [[f64; 3]; MAX_AXES],
    /// Axes whose position gains were zeroed for effort mode and not restored yet (an axis can go
    /// effort, then off, then position: the gains must come back even though it was off).
    gains_zeroed: [bool; MAX_AXES],
    /// Last target sent per axis (relative mode), counts.
    sent_target: [Option<i64>; MAX_AXES],
    state: [AxisState; MAX_AXES],
    moving: [bool; MAX_AXES],
    cycle: u64,
    /// The axes argument of reports: empty (all, the shortest line) when every board axis is
    /// driven.
    report_axes: Axes,
    /// The heartbeat value sent last (the watchdog looks for changes).
    beat: u32,
}

impl Io {
    pub(super) fn new(config: GalilBoardConfig, factory: LinkFactory) -> Self {
        let n = config.axes;
        Io {
            config,
            factory,
            client: None,
            modes: [Mode::Unknown; MAX_AXES],
            gains: [[0.0; 3]; MAX_AXES],
            gains_zeroed: [false; MAX_AXES],
            sent_target: [None; MAX_AXES],
            state: [AxisState::default(); MAX_AXES],
            moving: [false; MAX_AXES],
            cycle: 0,
            report_axes: Axes::first(n),
            beat: 0,
        }
    }

    fn n(&self) -> usize {
        self.config.axes
    }

    /// Initialises the board over `link` and sends the configured limits.
    pub(super) fn connect(&mut self, link: Box<dyn Link + Send>) -> Result<BoardInfo, GalilError> {
        let mut client = Client::new(link, self.config.client.clone());
        let info = client.initialize()?;
        let n = self.n();
        if info.layout.axes < n {
            return Err(GalilError::InvalidArgument(
                "the board has fewer axes than configured",
            ));
        }
        let per_axis = |v: &[f64; MAX_AXES]| -> [Option<f64>; MAX_AXES] {
            let mut out = [None; MAX_AXES];
            for (o, x) in out.iter_mut().zip(v).take(n) {
                *o = Some(*x);
            }
            out
        };
        if let Some(tl) = &self.config.torque_limit_volts {
            client.set(Setting::TorqueLimit, &per_axis(tl)[..n])?;
        }
        if let Some(er) = &self.config.error_limit_counts {
            client.set(Setting::ErrorLimit, &per_axis(er)[..n])?;
        }
        if let Some(oe) = self.config.off_on_error {
            client.set(Setting::OffOnError, &[Some(f64::from(oe)); MAX_AXES][..n])?;
        }
        match &self.config.gains {
            Some(g) => {
                self.gains = *g;
                for (k, s) in [Setting::Kp, Setting::Ki, Setting::Kd]
                    .into_iter()
                    .enumerate()
                {
                    let mut v = [None; MAX_AXES];
                    for (i, x) in v.iter_mut().enumerate().take(n) {
                        *x = Some(g[i][k]);
                    }
                    client.set(s, &v[..n])?;
                }
            }
            None => {
                for (k, s) in [Setting::Kp, Setting::Ki, Setting::Kd]
                    .into_iter()
                    .enumerate()
                {
                    let v = client.query(s, n)?;
                    for (i, x) in v.iter().enumerate() {
                        self.gains[i][k] = *x;
                    }
                }
            }
        }
        self.modes = [Mode::Unknown; MAX_AXES];
        self.sent_target = [None; MAX_AXES];
        self.report_axes = if info.layout.axes == n {
            Axes::NONE
        } else {
            Axes::first(n)
        };
        if let Some(timeout) = self.config.watchdog {
            start_watchdog(&mut client, timeout, n)?;
        }
        self.client = Some(client);
        Ok(info)
    }

    pub(super) fn run(
        mut self,
        mut commands: ArcLatestReader<CommandFrame>,
        mut state: ArcLatestWriter<StateFrame>,
        shared: &Shared,
    ) {
        let mut rearm_seen = shared.rearm.load(Ordering::SeqCst);
        let mut fault: Option<BoardFault> = None;
        let mut window_start = Instant::now();
        let mut window_cycles = 0u64;
        let mut disabled_in_fault = false;
        // When the I/O thread last saw a new command frame: the control tick's proof of life.
        let mut last_fresh = Instant::now();
        while !shared.stop.load(Ordering::SeqCst) {
            let started = Instant::now();
            let frame = match commands.read() {
                Fresh::New(f) => {
                    last_fresh = started;
                    Some(f)
                }
                Fresh::Old(f) => Some(f),
                Fresh::NoData => None,
            };
            if fault.is_none() && self.command_is_stale(frame, started, last_fresh) {
                let f = BoardFault::CommandStale;
                log::warn!(
                    "galil board: no command from the control loop for {} ms with torque on; \
                     amplifiers off",
                    started.saturating_duration_since(last_fresh).as_millis()
                );
                self.fail_safe(f);
                fault = Some(f);
            }
            if let Some(f) = fault {
                // Publish the fault, honour an explicit disable, wait for a re-arm.
                state.write(StateFrame {
                    axes: self.state,
                    fault: Some(f),
                });
                shared.fault.store(f.encode(), Ordering::Relaxed);
                if frame.is_some_and(|f| !f.enabled) && !disabled_in_fault {
                    disabled_in_fault = true;
                    if let Some(c) = self.client.as_mut() {
                        let _ = c.ack(&Command::MotorOff(Axes::first(self.config.axes)));
                    }
                }
                // A fault the line survived (a rejection, an axis switched off) leaves the host
                // alive: keep the watchdog fed so a held position stays held. A hung control
                // loop does not: the board's watchdog is left to switch everything off too.
                if !f.is_link_fault() && f != BoardFault::CommandStale {
                    self.heartbeat();
                }
                let r = shared.rearm.load(Ordering::SeqCst);
                if r != rearm_seen {
                    rearm_seen = r;
                    if self.reconnect().is_ok() {
                        fault = None;
                        last_fresh = Instant::now();
                        disabled_in_fault = false;
                        shared.fault.store(0, Ordering::Relaxed);
                    }
                } else {
                    std::thread::sleep(Duration::from_millis(10));
                }
                continue;
            }
            match self.cycle_once(frame) {
                Ok(()) => {
                    state.write(StateFrame {
                        axes: self.state,
                        fault: None,
                    });
                    shared.cycles.fetch_add(1, Ordering::Relaxed);
                    window_cycles += 1;
                    let elapsed = window_start.elapsed();
                    if elapsed >= Duration::from_millis(500) {
                        let hz = window_cycles as f64 / elapsed.as_secs_f64();
                        shared.rate_bits.store(hz.to_bits(), Ordering::Relaxed);
                        window_start = Instant::now();
                        window_cycles = 0;
                    }
                }
                Err(f) => {
                    let f = self.classify(f);
                    log::warn!("galil board fault: {f:?}");
                    self.fail_safe(f);
                    fault = Some(f);
                }
            }
            let spent = started.elapsed();
            if spent < self.config.min_cycle {
                std::thread::sleep(self.config.min_cycle - spent);
            }
        }
        self.release(fault);
    }

    /// True when the control thread's commands stopped coming while it drives an axis by
    /// effort: the newest frame is enabled, has an effort axis, and was first seen more than
    /// `command_timeout` ago.
    fn command_is_stale(
        &self,
        frame: Option<CommandFrame>,
        now: Instant,
        last_fresh: Instant,
    ) -> bool {
        let (Some(timeout), Some(frame)) = (self.config.command_timeout, frame) else {
            return false;
        };
        let torque = frame.enabled
            && frame.commands[..self.n()]
                .iter()
                .any(|c| matches!(c, AxisCommand::Effort(_)));
        torque && now.saturating_duration_since(last_fresh) > timeout
    }

    /// A motor the board switched off is the watchdog's doing when its trip flag says so.
    fn classify(&mut self, f: BoardFault) -> BoardFault {
        if !matches!(f, BoardFault::MotorOff(_)) || self.config.watchdog.is_none() {
            return f;
        }
        let Some(c) = self.client.as_mut() else {
            return f;
        };
        let mut line = heapless::String::<16>::new();
        let _ = line.push_str("MG ");
        let _ = line.push_str(TRIPPED);
        match c.command(&Command::Raw(&line)) {
            Ok(r) => match super::super::number::parse_number(&r.text) {
                Ok(1.0) => BoardFault::Watchdog,
                _ => f,
            },
            Err(_) => f,
        }
    }

    /// Makes a fault end safe while the line still answers: axes in effort mode get `OF 0` then
    /// `MO` (no torque may stay on), axes in position mode `ST` (the board's servo holds); after
    /// [`BoardFault::CommandStale`] every driven axis gets `OF 0` and `MO`.
    /// Nothing is sent on a closed line; the board's watchdog turns the motors off then.
    fn fail_safe(&mut self, f: BoardFault) {
        if matches!(f, BoardFault::Closed | BoardFault::Io) {
            return;
        }
        let n = self.n();
        let Some(c) = self.client.as_mut() else {
            return;
        };
        let mut effort = Axes::NONE;
        let mut position = Axes::NONE;
        for i in 0..n {
            match self.modes[i] {
                // A hung control loop: nothing the host sent may stay on, held targets included.
                _ if f == BoardFault::CommandStale => effort.0 |= 1 << i,
                Mode::Effort => effort.0 |= 1 << i,
                Mode::Position => position.0 |= 1 << i,
                _ => {}
            }
        }
        if !effort.is_empty() {
            let mut zeros = [None; MAX_AXES];
            for i in effort.indices() {
                zeros[i] = Some(0.0);
            }
            // The line may be gone after all: a link failure ends the attempt (each would cost
            // a timeout); a rejected `OF` still leaves `MO` worth sending.
            if let Err(e) = c.set(Setting::Offset, &zeros[..n])
                && e.is_link_fault()
            {
                return;
            }
            if c.ack(&Command::MotorOff(effort)).is_err() {
                return;
            }
            for i in effort.indices() {
                self.modes[i] = Mode::Off;
                self.state[i].effort = 0.0;
            }
        }
        if !position.is_empty() {
            let _ = c.ack(&Command::Stop(position));
        }
    }

    /// The board is released (dropped): amplifiers off on every driven axis (`OF 0`, `MO`), the
    /// watchdog halted, when the line still answers. A line that is gone leaves it to the
    /// watchdog.
    fn release(&mut self, fault: Option<BoardFault>) {
        if fault.is_some_and(|f| matches!(f, BoardFault::Closed | BoardFault::Io)) {
            return;
        }
        let n = self.n();
        let Some(c) = self.client.as_mut() else {
            return;
        };
        let zeros = [Some(0.0); MAX_AXES];
        if c.set(Setting::Offset, &zeros[..n]).is_err() && fault.is_some() {
            return;
        }
        if c.ack(&Command::MotorOff(Axes::first(n))).is_err() {
            return;
        }
        if self.config.watchdog.is_some() {
            let _ = c.ack(&Command::Halt(Some(WATCHDOG_THREAD)));
        }
    }

    /// Writes a new heartbeat value (best effort; used while faulted).
    fn heartbeat(&mut self) {
        if self.config.watchdog.is_none() {
            return;
        }
        self.beat = next_beat(self.beat);
        if let Some(c) = self.client.as_mut() {
            let _ = c.ack(&Command::Assign(HEARTBEAT, f64::from(self.beat)));
        }
    }

    fn reconnect(&mut self) -> Result<(), GalilError> {
        // Try the existing line first; reopen it if that fails.
        if let Some(c) = self.client.take() {
            let link = c.into_link();
            if self.connect(link).is_ok() {
                return Ok(());
            }
        }
        let link = (self.factory)()?;
        self.connect(link).map(|_| ())
    }

    /// One exchange cycle: mode changes, targets out, positions and errors back.
    fn cycle_once(&mut self, frame: Option<CommandFrame>) -> Result<(), BoardFault> {
        if self.client.is_none() {
            return Err(BoardFault::Closed);
        }
        let desired = self.desired_commands(frame);
        self.change_modes(&desired)?;
        self.exchange_cycle_line(&desired)?;
        // Status every few cycles: velocity, torque, switches.
        self.cycle += 1;
        if self
            .cycle
            .is_multiple_of(u64::from(self.config.status_every.max(1)))
        {
            self.read_status()?;
        }
        Ok(())
    }

    /// What each driven axis should do this cycle: the frame's command, or off while the frame
    /// is disabled; nothing without a frame.
    fn desired_commands(&self, frame: Option<CommandFrame>) -> [Option<AxisCommand>; MAX_AXES] {
        let mut desired = [None; MAX_AXES];
        if let Some(f) = frame {
            for i in 0..self.n() {
                desired[i] = Some(if f.enabled {
                    f.commands[i]
                } else {
                    AxisCommand::Off
                });
            }
        }
        desired
    }

    /// The axes whose mode must change for `desired`, grouped by what the board must do.
    fn plan_mode_changes(&self, desired: &[Option<AxisCommand>; MAX_AXES]) -> ModeChanges {
        let mut changes = ModeChanges::default();
        for i in 0..self.n() {
            let want = match desired[i] {
                None => continue,
                Some(AxisCommand::Off) => Mode::Off,
                Some(AxisCommand::Position(_)) => Mode::Position,
                Some(AxisCommand::Effort(_)) => Mode::Effort,
            };
            if want == self.modes[i] {
                continue;
            }
            let bit = Axes(1 << i);
            match want {
                Mode::Off => changes.off.0 |= bit.0,
                Mode::Position => changes.position.0 |= bit.0,
                Mode::Effort => changes.effort.0 |= bit.0,
                Mode::Unknown => {}
            }
            if want != Mode::Off && matches!(self.modes[i], Mode::Off | Mode::Unknown) {
                changes.on.0 |= bit.0;
            }
            if want == Mode::Position
                && (matches!(self.modes[i], Mode::Effort | Mode::Unknown) || self.gains_zeroed[i])
            {
                changes.restore_gains.0 |= bit.0;
            }
        }
        changes
    }

    /// Makes the board's axis modes match `desired` (rare; several exchanges) and records them.
    fn change_modes(
        &mut self,
        desired: &[Option<AxisCommand>; MAX_AXES],
    ) -> Result<(), BoardFault> {
        let changes = self.plan_mode_changes(desired);
        let client = self.client.as_mut().ok_or(BoardFault::Closed)?;
        if !changes.off.is_empty() {
            client.ack(&Command::MotorOff(changes.off)).map_err(fault)?;
        }
        if !changes.effort.is_empty() {
            self.enter_effort(changes.effort)?;
        }
        if !changes.position.is_empty() {
            self.enter_position(&changes)?;
        }
        let on_effort = Axes(changes.on.0 & changes.effort.0);
        if !on_effort.is_empty() {
            let client = self.client.as_mut().ok_or(BoardFault::Closed)?;
            client.ack(&Command::ServoHere(on_effort)).map_err(fault)?;
        }
        for i in 0..self.n() {
            match desired[i] {
                Some(AxisCommand::Off) => self.modes[i] = Mode::Off,
                Some(AxisCommand::Position(_)) => self.modes[i] = Mode::Position,
                Some(AxisCommand::Effort(_)) => self.modes[i] = Mode::Effort,
                None => {}
            }
        }
        Ok(())
    }

    /// Puts `axes` in effort mode: their gains zeroed, so the offset (`OF`) is the output.
    fn enter_effort(&mut self, axes: Axes) -> Result<(), BoardFault> {
        let n = self.n();
        let client = self.client.as_mut().ok_or(BoardFault::Closed)?;
        let mut zeros = [None; MAX_AXES];
        let mut of = [None; MAX_AXES];
        for i in axes.indices() {
            zeros[i] = Some(0.0);
            of[i] = Some(0.0);
        }
        for s in [
            Setting::PositionTracking,
            Setting::Kp,
            Setting::Ki,
            Setting::Kd,
        ] {
            client.set(s, &zeros[..n]).map_err(fault)?;
        }
        client.set(Setting::Offset, &of[..n]).map_err(fault)?;
        for i in axes.indices() {
            self.gains_zeroed[i] = true;
        }
        Ok(())
    }

    /// Puts `changes.position` in position mode: gains written back where they were zeroed,
    /// servo on where the axis was off, then tracking set per the configured target mode.
    fn enter_position(&mut self, changes: &ModeChanges) -> Result<(), BoardFault> {
        let n = self.n();
        let client = self.client.as_mut().ok_or(BoardFault::Closed)?;
        let mut of = [None; MAX_AXES];
        let mut g = [[None; MAX_AXES]; 3];
        let mut pt = [None; MAX_AXES];
        let tracking = self.config.target_mode == TargetMode::PositionTracking;
        for i in changes.position.indices() {
            pt[i] = Some(if tracking { 1.0 } else { 0.0 });
        }
        for i in changes.restore_gains.indices() {
            of[i] = Some(0.0);
            for (k, gk) in g.iter_mut().enumerate() {
                gk[i] = Some(self.gains[i][k]);
            }
        }
        if !changes.restore_gains.is_empty() {
            client.set(Setting::Offset, &of[..n]).map_err(fault)?;
            for (k, s) in [Setting::Kp, Setting::Ki, Setting::Kd]
                .into_iter()
                .enumerate()
            {
                client.set(s, &g[k][..n]).map_err(fault)?;
            }
            for i in changes.restore_gains.indices() {
                self.gains_zeroed[i] = false;
            }
        }
        // Servo on (holding the current position) before tracking starts.
        let on = Axes(changes.on.0 & changes.position.0);
        if !on.is_empty() {
            client.ack(&Command::ServoHere(on)).map_err(fault)?;
        }
        client
            .set(Setting::PositionTracking, &pt[..n])
            .map_err(fault)?;
        for i in changes.position.indices() {
            self.sent_target[i] = None;
        }
        Ok(())
    }

    /// The per-axis values of this cycle's line: position targets (absolute, or relative moves
    /// begun where the axis stands still) and effort offsets in volts.
    fn cycle_targets(&mut self, desired: &[Option<AxisCommand>; MAX_AXES]) -> CycleTargets {
        let mut out = CycleTargets {
            targets: [None; MAX_AXES],
            offsets: [None; MAX_AXES],
            relative: false,
            begin: Axes::NONE,
        };
        for i in 0..self.n() {
            match desired[i] {
                Some(AxisCommand::Position(p)) => match self.config.target_mode {
                    TargetMode::PositionTracking => out.targets[i] = Some(p as f64),
                    TargetMode::Relative => {
                        let from = self.sent_target[i].unwrap_or(self.state[i].position);
                        if p != from && !self.moving[i] {
                            out.targets[i] = Some(p.saturating_sub(from) as f64);
                            self.sent_target[i] = Some(p);
                            out.begin.0 |= 1 << i;
                            out.relative = true;
                        }
                    }
                },
                Some(AxisCommand::Effort(t)) => {
                    let v =
                        (t * self.config.volts_per_newton_metre[i]).clamp(-MAX_VOLTS, MAX_VOLTS);
                    out.offsets[i] = Some(v);
                    self.state[i].effort = t;
                }
                _ => {}
            }
        }
        out
    }

    /// The cycle line: heartbeat and targets out, then `TP` and `TE` (and `TS` in relative mode)
    /// back into the axis state.
    fn exchange_cycle_line(
        &mut self,
        desired: &[Option<AxisCommand>; MAX_AXES],
    ) -> Result<(), BoardFault> {
        let n = self.n();
        let report = self.report_axes;
        let CycleTargets {
            targets,
            offsets,
            relative,
            begin,
        } = self.cycle_targets(desired);
        let watchdog = self.config.watchdog.is_some();
        if watchdog {
            self.beat = next_beat(self.beat);
        }
        let client = self.client.as_mut().ok_or(BoardFault::Closed)?;
        let mut parts: heapless::Vec<Command<'_>, 7> = heapless::Vec::new();
        let _ = parts.push(Command::Assign(HEARTBEAT, f64::from(self.beat)));
        let target_setting = if relative {
            Setting::PositionRelative
        } else {
            Setting::PositionAbsolute
        };
        let has_targets = targets.iter().any(Option::is_some);
        let has_offsets = offsets.iter().any(Option::is_some);
        let relative_mode = self.config.target_mode == TargetMode::Relative;
        let _ = parts.push(Command::Set(target_setting, &targets[..n]));
        let _ = parts.push(Command::Set(Setting::Offset, &offsets[..n]));
        let _ = parts.push(Command::Begin(begin));
        let _ = parts.push(Command::Tell(Tell::Position, report));
        let _ = parts.push(Command::Tell(Tell::Error, report));
        let _ = parts.push(Command::Tell(Tell::Switches, report));
        let used = [
            watchdog,
            has_targets,
            has_offsets,
            !begin.is_empty(),
            true,
            true,
            relative_mode,
        ];
        let mut line: heapless::Vec<Command<'_>, 7> = heapless::Vec::new();
        for (c, u) in parts.iter().zip(used) {
            if u {
                let _ = line.push(*c);
            }
        }
        let mut replies: [Reply; 7] = Default::default();
        let reads = line.len() - usize::from(relative_mode) - 2;
        if encode_line(&line).is_ok() {
            client.transact(&line, &mut replies).map_err(fault)?;
        } else {
            // Too long for one line: one command per exchange.
            for (c, r) in line.iter().zip(replies.iter_mut()) {
                *r = client.command(c).map_err(fault)?;
            }
        }
        let mut values = [0.0; MAX_GALIL_AXES];
        parse_axes(&replies[reads].text, n, &mut values)?;
        for i in 0..n {
            self.state[i].position = to_counts(values[i]).map_err(|_| BoardFault::Garbled)?;
        }
        parse_axes(&replies[reads + 1].text, n, &mut values)?;
        for i in 0..n {
            self.state[i].following_error =
                to_counts(values[i]).map_err(|_| BoardFault::Garbled)?;
        }
        if relative_mode {
            parse_axes(&replies[reads + 2].text, n, &mut values)?;
            self.apply_switches(&values)?;
        }
        Ok(())
    }

    /// The status exchange: velocity, torque (the effort of axes not in effort mode) and
    /// switches.
    fn read_status(&mut self) -> Result<(), BoardFault> {
        let n = self.n();
        let report = self.report_axes;
        let client = self.client.as_mut().ok_or(BoardFault::Closed)?;
        let status = [
            Command::Tell(Tell::Velocity, report),
            Command::Tell(Tell::Torque, report),
            Command::Tell(Tell::Switches, report),
        ];
        let mut replies: [Reply; 3] = Default::default();
        client.transact(&status, &mut replies).map_err(fault)?;
        let mut values = [0.0; MAX_GALIL_AXES];
        parse_axes(&replies[0].text, n, &mut values)?;
        for i in 0..n {
            self.state[i].velocity = values[i];
        }
        parse_axes(&replies[1].text, n, &mut values)?;
        for i in 0..n {
            let scale = self.config.volts_per_newton_metre[i];
            if self.modes[i] != Mode::Effort && scale != 0.0 {
                self.state[i].effort = values[i] / scale;
            }
        }
        parse_axes(&replies[2].text, n, &mut values)?;
        self.apply_switches(&values)
    }

    /// Reads `TS` values: amplifier state and motion; an axis the board switched off while it
    /// should be on is a fault.
    fn apply_switches(&mut self, ts: &[f64; MAX_GALIL_AXES]) -> Result<(), BoardFault> {
        for i in 0..self.n() {
            let bits = ts[i] as u32;
            let off = bits & 0x20 != 0;
            self.state[i].enabled = !off;
            self.moving[i] = bits & 0x80 != 0;
            if off && matches!(self.modes[i], Mode::Position | Mode::Effort) {
                return Err(BoardFault::MotorOff(i as u8));
            }
        }
        Ok(())
    }
}

/// The mode changes one cycle asks for, as axis sets.
#[derive(Clone, Copy, Default)]
struct ModeChanges {
    /// Axes to switch off.
    off: Axes,
    /// Axes to servo on (they were off or in an unknown mode).
    on: Axes,
    /// Axes to put in position mode.
    position: Axes,
    /// Axes to put in effort mode.
    effort: Axes,
    /// Position axes whose gains must be written back (zeroed for effort, or unknown).
    restore_gains: Axes,
}

/// The per-axis values one cycle line sends.
struct CycleTargets {
    /// Position targets, counts (absolute, or relative moves).
    targets: [Option<f64>; MAX_AXES],
    /// Effort offsets, volts.
    offsets: [Option<f64>; MAX_AXES],
    /// Whether the targets are relative moves.
    relative: bool,
    /// Axes whose relative move begins this cycle.
    begin: Axes,
}

/// A protocol error as the fault it means for the board.
fn fault(e: GalilError) -> BoardFault {
    BoardFault::from_error(&e)
}

/// Parses one report reply into `values`; anything but one number per driven axis is garbled.
fn parse_axes(
    text: &[u8],
    axes: usize,
    values: &mut [f64; MAX_GALIL_AXES],
) -> Result<(), BoardFault> {
    match parse_numbers(text, values) {
        Ok(k) if k == axes => Ok(()),
        _ => Err(BoardFault::Garbled),
    }
}

/// The heartbeat after `beat` (1..=30000, then around again).
fn next_beat(beat: u32) -> u32 {
    beat % 30_000 + 1
}

/// Halts every program thread, downloads the watchdog and starts it in its thread.
fn start_watchdog(
    client: &mut Client<Box<dyn Link + Send>>,
    timeout: Duration,
    axes: usize,
) -> Result<(), GalilError> {
    let tm = client.servo_period()?;
    let period = tm * 1e-6 * (1000.0 / 1024.0);
    client.ack(&Command::Halt(None))?;
    client.download(&watchdog::program(timeout, period, axes))?;
    client.ack(&Command::Assign(HEARTBEAT, 0.0))?;
    client.ack(&Command::Assign(TRIPPED, 0.0))?;
    client.ack(&Command::Execute(WATCHDOG_LABEL, WATCHDOG_THREAD))
}
