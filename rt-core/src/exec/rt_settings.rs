//! A thread's real-time settings (Linux, feature `std`): SCHED_FIFO, CPU affinity,
//! `mlockall`, `/dev/cpu_dma_latency` and a prefaulted stack, each refusal said once per
//! process with its fix. Re-exported by [`exec`](crate::exec), whose threads ask for them
//! before their first tick.

use std::sync::OnceLock;
use std::sync::atomic::{AtomicBool, Ordering};

use super::{PeriodicConfig, RtStatus, Setting};

/// Asks for the real-time settings of `config` for the calling thread, warning once per process
/// about each refusal.
pub fn apply_rt(config: &PeriodicConfig) -> RtStatus {
    let mut status = RtStatus::default();
    if let Some(p) = config.priority {
        status.fifo = set_fifo(p);
        if let Setting::Refused(errno) = status.fifo {
            warn_once(&WARNED_FIFO, || {
                format!(
                    "SCHED_FIFO priority {p} refused ({}); running with normal scheduling. Fix: \
                     run as root, or `setcap cap_sys_nice+ep <binary>`, or add `<user> - rtprio 98` \
                     to /etc/security/limits.conf and log in again (docs/deployment.md)",
                    errno_text(errno)
                )
            });
        }
    }
    if let Some(cpu) = config.cpu {
        status.affinity = if core_affinity::set_for_current(core_affinity::CoreId { id: cpu }) {
            Setting::Applied
        } else {
            warn_once(&WARNED_AFFINITY, || {
                format!(
                    "cannot pin thread `{}` to CPU {cpu} (this machine has {} CPUs online, or a \
                     cpuset excludes it); running unpinned. Fix: choose a CPU from `nproc` / the \
                     isolated set",
                    config.name,
                    std::thread::available_parallelism().map_or(0, |n| n.get())
                )
            });
            Setting::Refused(libc::EINVAL)
        };
    }
    if config.lock_memory {
        status.memory_locked = lock_memory();
        if let Setting::Refused(errno) = status.memory_locked {
            warn_once(&WARNED_MLOCK, || {
                format!(
                    "mlockall refused ({}); pages may fault in the real-time path. Fix: run as \
                     root, or `setcap cap_ipc_lock+ep <binary>`, or add `<user> - memlock \
                     unlimited` to /etc/security/limits.conf (docs/deployment.md)",
                    errno_text(errno)
                )
            });
        }
    }
    if config.prefault_stack > 0 {
        prefault_stack(config.prefault_stack.div_ceil(PREFAULT_CHUNK));
    }
    if config.hold_dma_latency {
        status.dma_latency = hold_dma_latency();
        if let Setting::Refused(errno) = status.dma_latency {
            warn_once(&WARNED_DMA, || {
                format!(
                    "cannot hold /dev/cpu_dma_latency at 0 ({}); idle CPUs may enter deep sleep \
                     states and add wake-up latency. Fix: run as root, or a udev rule giving the \
                     real-time group write access (docs/deployment.md)",
                    errno_text(errno)
                )
            });
        }
    }
    status
}

static WARNED_FIFO: AtomicBool = AtomicBool::new(false);
static WARNED_AFFINITY: AtomicBool = AtomicBool::new(false);
static WARNED_MLOCK: AtomicBool = AtomicBool::new(false);
static WARNED_DMA: AtomicBool = AtomicBool::new(false);

fn warn_once(flag: &AtomicBool, message: impl FnOnce() -> String) {
    if !flag.swap(true, Ordering::Relaxed) {
        eprintln!("penelope: warning: {}", message());
    }
}

fn errno_text(errno: i32) -> String {
    std::io::Error::from_raw_os_error(errno).to_string()
}

/// Tries to give the calling thread SCHED_FIFO `priority` (1 to 99), without warning. Used by
/// `penelope doctor` (from a throw-away thread) to probe for real-time rights.
pub fn set_fifo(priority: u8) -> Setting {
    use thread_priority::{
        RealtimeThreadSchedulePolicy, ThreadPriority, ThreadPriorityValue, ThreadSchedulePolicy,
        set_thread_priority_and_policy, thread_native_id,
    };
    let Ok(value) = ThreadPriorityValue::try_from(priority) else {
        return Setting::Refused(libc::EINVAL);
    };
    // For real-time policies the crate passes cross-platform values 1..=99 through unchanged.
    match set_thread_priority_and_policy(
        thread_native_id(),
        ThreadPriority::Crossplatform(value),
        ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
    ) {
        Ok(()) => Setting::Applied,
        Err(thread_priority::Error::OS(errno)) => Setting::Refused(errno),
        Err(_) => Setting::Refused(0),
    }
}

fn lock_memory() -> Setting {
    static LOCKED: OnceLock<Setting> = OnceLock::new();
    *LOCKED.get_or_init(|| {
        use nix::sys::mman::{MlockAllFlags, mlockall};
        match mlockall(MlockAllFlags::MCL_CURRENT | MlockAllFlags::MCL_FUTURE) {
            Ok(()) => Setting::Applied,
            Err(e) => Setting::Refused(e as i32),
        }
    })
}

/// Opens `/dev/cpu_dma_latency`, writes a 32-bit 0 and keeps the file open for the life of the
/// process (closing it would lift the request). Done once per process.
pub fn hold_dma_latency() -> Setting {
    static HELD: OnceLock<Setting> = OnceLock::new();
    static FILE: OnceLock<std::fs::File> = OnceLock::new();
    *HELD.get_or_init(|| {
        use std::io::Write;
        let opened = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/cpu_dma_latency")
            .and_then(|mut f| f.write_all(&0i32.to_ne_bytes()).map(|()| f));
        match opened {
            Ok(f) => {
                let _ = FILE.set(f);
                Setting::Applied
            }
            Err(e) => Setting::Refused(e.raw_os_error().unwrap_or(0)),
        }
    })
}

const PREFAULT_CHUNK: usize = 16 * 1024;

/// Touches `chunks` × 16 KiB of stack so the pages are mapped (and locked) before the first tick.
#[inline(never)]
fn prefault_stack(chunks: usize) {
    let mut buffer = [0u8; PREFAULT_CHUNK];
    std::hint::black_box(&mut buffer);
    if chunks > 1 {
        prefault_stack(chunks - 1);
    }
    std::hint::black_box(&buffer);
}
