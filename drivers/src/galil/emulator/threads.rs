//! The controller side of programs: `DL`, `XQ`, `HX`, variables, and the threads run at every
//! servo sample.

use std::sync::Arc;

use super::program::{self, Expr, LINES_PER_TICK, Machine, Program, Slice};
use super::{Dmc, MAX_PROGRAM, MAX_VARIABLES, Reply, THREADS};

/// Galil code for "not valid while a program runs" (`DL` with a thread running).
const CODE_RUNNING: u16 = 7;

impl Dmc {
    /// A host or program assignment `name=expr` (or the query `name=?`); `None` when `text` is
    /// not one. Names that begin with two capitals are commands (`KPA=10`).
    pub(super) fn assignment(&mut self, text: &str) -> Option<Result<Reply, u16>> {
        let (name, value) = text.split_once('=')?;
        let name = name.trim();
        if !program::is_variable_name(name) || name.bytes().take(2).all(|c| c.is_ascii_uppercase())
        {
            return None;
        }
        let value = value.trim();
        if value == "?" {
            return Some(
                self.variables
                    .get(name)
                    .copied()
                    .map(|v| Reply::Text(self.fmt_dec(v)))
                    .ok_or(1),
            );
        }
        Some(
            Expr::parse(value)
                .and_then(|e| e.eval(self))
                .and_then(|v| self.set_variable(name, v))
                .map(|()| Reply::Ack),
        )
    }

    /// A variable's value (`None`: not defined).
    pub fn variable(&self, name: &str) -> Option<f64> {
        self.variables.get(name).copied()
    }

    /// True while thread `t` runs a program.
    pub fn thread_running(&self, t: usize) -> bool {
        self.threads.get(t).is_some_and(Option::is_some)
    }

    pub(super) fn begin_download(&mut self, rest: &str) -> Result<Reply, u16> {
        if !rest.is_empty() {
            return Err(1);
        }
        if self.threads.iter().any(Option::is_some) {
            return Err(CODE_RUNNING);
        }
        self.download = Some(Vec::new());
        Ok(Reply::Later)
    }

    /// One byte of program text; `\` or Ctrl-Z ends it with `:` (or `?` for a program that does
    /// not parse).
    pub(super) fn download_byte(&mut self, b: u8, out: &mut Vec<u8>) {
        let Some(buf) = self.download.as_mut() else {
            return;
        };
        if b != b'\\' && b != 0x1A {
            if buf.len() < MAX_PROGRAM + 1 {
                buf.push(b);
            }
            return;
        }
        let text = self.download.take().unwrap_or_default();
        let parsed = if text.len() > MAX_PROGRAM {
            Err(program::CODE_BAD_PROGRAM)
        } else {
            Program::parse(&String::from_utf8_lossy(&text))
        };
        match parsed {
            Ok(p) => {
                self.program = Some(Arc::new(p));
                out.push(b':');
            }
            Err(code) => {
                self.error_code = code;
                out.push(b'?');
            }
        }
    }

    /// `XQ`, `XQ #LABEL` or `XQ #LABEL,t`.
    pub(super) fn execute_thread(&mut self, rest: &str) -> Result<(), u16> {
        let program = self.program.clone().ok_or(program::CODE_NO_LABEL)?;
        let (label, thread) = match rest.split_once(',') {
            Some((l, t)) => (l.trim(), super::number(t.trim())?),
            None => (rest.trim(), 0.0),
        };
        if !(0.0..THREADS as f64).contains(&thread) || thread.fract() != 0.0 {
            return Err(6);
        }
        let t = if label.is_empty() {
            program.first()
        } else {
            program.start(label.strip_prefix('#').ok_or(1u16)?)?
        };
        let i = thread as usize;
        self.halted &= !(1 << i);
        self.threads[i] = Some(t);
        Ok(())
    }

    /// `HX` (every thread) or `HX t`.
    pub(super) fn halt_threads(&mut self, rest: &str) -> Result<(), u16> {
        if rest.is_empty() {
            self.threads = Default::default();
            self.halted = 0xFF;
            return Ok(());
        }
        let t = super::number(rest)?;
        if !(0.0..THREADS as f64).contains(&t) || t.fract() != 0.0 {
            return Err(6);
        }
        self.threads[t as usize] = None;
        self.halted |= 1 << t as usize;
        Ok(())
    }

    /// Gives each running thread its slice of one servo sample.
    pub(super) fn run_threads(&mut self) {
        let Some(program) = self.program.clone() else {
            return;
        };
        for i in 0..THREADS {
            let Some(mut thread) = self.threads[i].take() else {
                continue;
            };
            self.halted &= !(1 << i);
            let slice = program.run(&mut thread, self, LINES_PER_TICK);
            let replaced = self.threads[i].is_some() || self.halted & (1 << i) != 0;
            match slice {
                Slice::Running if !replaced => self.threads[i] = Some(thread),
                Slice::Error(code) => {
                    // As a DMC does: the thread stops and says where.
                    self.error_code = code;
                    self.queue_unsolicited(format!("?thread {i} stopped: {code}\r\n").as_bytes());
                }
                _ => {}
            }
        }
    }
}

impl Machine for Dmc {
    fn variable(&self, name: &str) -> Option<f64> {
        self.variables.get(name).copied()
    }

    fn set_variable(&mut self, name: &str, value: f64) -> Result<(), u16> {
        if !self.variables.contains_key(name) && self.variables.len() >= MAX_VARIABLES {
            return Err(1);
        }
        self.variables.insert(name.to_string(), value);
        Ok(())
    }

    fn time(&self) -> f64 {
        self.ticks as f64
    }

    fn operand(&self, name: &str, axis: usize) -> Option<f64> {
        (axis < self.axes.len() && ["TP", "TE", "TV", "TT", "TS", "SC", "BG"].contains(&name))
            .then(|| Dmc::operand(self, name, axis))
    }

    fn command(&mut self, text: &str) -> Result<(), u16> {
        let mut out = Vec::new();
        match self.execute(text, &mut out)? {
            Reply::Text(t) if text.starts_with("MG") => {
                self.queue_unsolicited(format!("{t}\r\n").as_bytes());
            }
            // A program cannot download.
            Reply::Later => {
                self.download = None;
                return Err(1);
            }
            _ => {}
        }
        self.note_motors();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::super::{Dmc, DmcConfig};

    fn send(dmc: &mut Dmc, t: f64, text: &str) -> String {
        let mut out = Vec::new();
        dmc.input(text.as_bytes(), Duration::from_secs_f64(t), &mut out);
        String::from_utf8_lossy(&out).into_owned()
    }

    #[test]
    fn a_downloaded_watchdog_turns_the_motors_off_on_its_own() {
        let mut d = Dmc::new(DmcConfig::default());
        send(&mut d, 0.0, "EO0\r");
        let program = "#WD\rlast=beat\rt0=TIME\r#L\rIF (beat<>last)\rlast=beat;t0=TIME\rENDIF\r\
                       IF ((TIME-t0)>30)\rMO;trip=1\rEN\rENDIF\rJP #L\r";
        assert_eq!(send(&mut d, 0.0, &format!("DL\r{program}\\")), ":");
        assert_eq!(send(&mut d, 0.0, "beat=0;trip=0;SH;OF 1\r"), "::::");
        assert_eq!(send(&mut d, 0.0, "XQ #WD,3\r"), ":");
        assert!(d.thread_running(3));
        // Heartbeats every 10 ms keep the motors on.
        for k in 1..=20 {
            send(&mut d, 0.01 * f64::from(k), &format!("beat={k}\r"));
        }
        assert!(d.axis(0).unwrap().motor_on);
        let last = d.last_command_at().unwrap();
        // Silence: the program turns the motors off about 30 samples later.
        d.advance(Duration::from_secs_f64(0.5));
        let a = d.axis(0).unwrap();
        assert!(!a.motor_on);
        let delay = a.off_at.unwrap() - last;
        assert!(
            delay >= Duration::from_millis(29) && delay <= Duration::from_millis(36),
            "{delay:?}"
        );
        assert_eq!(d.variable("trip"), Some(1.0));
        assert!(!d.thread_running(3));
        assert_eq!(send(&mut d, 0.5, "MG trip\r"), " 1.0000\r\n:");
    }

    #[test]
    fn download_and_threads_refuse_bad_input() {
        let mut d = Dmc::new(DmcConfig::default());
        send(&mut d, 0.0, "EO0\r");
        assert_eq!(send(&mut d, 0.0, "DL\rIF (1)\r\\"), "?");
        assert_eq!(send(&mut d, 0.0, "XQ #NONE\r"), "?");
        assert_eq!(send(&mut d, 0.0, "DL\r#A\rWT 1000\rJP #A\r\\"), ":");
        assert_eq!(send(&mut d, 0.0, "XQ #A,9\r"), "?");
        assert_eq!(send(&mut d, 0.0, "XQ #A,1\r"), ":");
        // No download over a running program.
        assert_eq!(send(&mut d, 0.0, "DL\r"), "?");
        assert_eq!(send(&mut d, 0.1, "HX\r"), ":");
        assert!(!d.thread_running(1));
        assert_eq!(send(&mut d, 0.1, "x=?\r"), "?");
        assert_eq!(send(&mut d, 0.1, "x=2*3;x=?\r"), ": 6.0000\r\n:");
    }
}
