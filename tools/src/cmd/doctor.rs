//! `penelope doctor`: checks this host for real-time use and prints what to fix.
//!
//! Checks: the kernel (PREEMPT_RT), the preemption model, the right to SCHED_FIFO (tried for real,
//! in a throw-away thread) and the rtprio limit, the memlock limit, CPU isolation, the frequency
//! governor, SMT, access to `/dev/cpu_dma_latency`, real-time throttling, the clock source and
//! virtualisation. Every finding that is not `ok` comes with its fix; `docs/deployment.md` has the
//! details.

use std::process::ExitCode;

use penelope_rt_core::exec::{self, Setting};
use serde_json::json;

/// Options of `penelope doctor`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Exit with code 1 when any check fails (for provisioning scripts).
    #[arg(long)]
    pub strict: bool,
}

/// How a check came out.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Level {
    /// Fine for real-time use.
    Ok,
    /// Information only.
    Info,
    /// Works, but costs latency.
    Warn,
    /// Real-time use is not possible or not safe until fixed.
    Fail,
}

impl Level {
    fn tag(self) -> &'static str {
        match self {
            Level::Ok => "[ ok ]",
            Level::Info => "[info]",
            Level::Warn => "[warn]",
            Level::Fail => "[FAIL]",
        }
    }
}

/// One finding.
#[derive(Clone, Debug)]
pub struct Finding {
    /// What was checked.
    pub check: &'static str,
    /// The outcome.
    pub level: Level,
    /// What was found.
    pub detail: String,
    /// What to do (empty when nothing).
    pub fix: String,
}

fn finding(
    check: &'static str,
    level: Level,
    detail: impl Into<String>,
    fix: impl Into<String>,
) -> Finding {
    Finding {
        check,
        level,
        detail: detail.into(),
        fix: fix.into(),
    }
}

fn read(path: &str) -> Option<String> {
    std::fs::read_to_string(path)
        .ok()
        .map(|s| s.trim().to_string())
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let findings = check_all();
    if args.json {
        let list: Vec<_> = findings
            .iter()
            .map(|f| {
                json!({
                    "check": f.check,
                    "level": format!("{:?}", f.level).to_lowercase(),
                    "detail": f.detail,
                    "fix": f.fix,
                })
            })
            .collect();
        println!(
            "{}",
            serde_json::to_string_pretty(&json!({ "findings": list }))?
        );
    } else {
        println!("Real-time readiness of this host (details: docs/deployment.md)\n");
        for f in &findings {
            println!("{} {:<22} {}", f.level.tag(), f.check, f.detail);
            if !f.fix.is_empty() {
                println!("       {:<22} fix: {}", "", f.fix);
            }
        }
        let fails = findings.iter().filter(|f| f.level == Level::Fail).count();
        let warns = findings.iter().filter(|f| f.level == Level::Warn).count();
        println!("\n{fails} to fix, {warns} to improve.");
    }
    let failed = findings.iter().any(|f| f.level == Level::Fail);
    Ok(if args.strict && failed {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}

/// Every check, in order.
pub fn check_all() -> Vec<Finding> {
    let uname_v = command_output("uname", &["-v"]).unwrap_or_default();
    let release = command_output("uname", &["-r"]).unwrap_or_default();
    let config = read(&format!("/boot/config-{release}"));
    let status = read("/proc/self/status").unwrap_or_default();
    let limits = read("/proc/self/limits").unwrap_or_default();
    let cmdline = read("/proc/cmdline").unwrap_or_default();
    vec![
        check_kernel(&release, &uname_v, config.as_deref()),
        check_preemption(
            &uname_v,
            config.as_deref(),
            read("/sys/kernel/debug/sched/preempt").as_deref(),
            &cmdline,
        ),
        check_fifo(&status, &limits),
        check_memlock(&status, &limits),
        check_isolation(
            read("/sys/devices/system/cpu/isolated").as_deref(),
            &cmdline,
        ),
        check_governor(),
        check_smt(read("/sys/devices/system/cpu/smt/active").as_deref()),
        check_dma_latency(),
        check_throttling(read("/proc/sys/kernel/sched_rt_runtime_us").as_deref()),
        check_clocksource(
            read("/sys/devices/system/clocksource/clocksource0/current_clocksource").as_deref(),
        ),
        check_virtualization(),
    ]
}

fn command_output(cmd: &str, args: &[&str]) -> Option<String> {
    let out = std::process::Command::new(cmd).args(args).output().ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

fn config_has(config: Option<&str>, key: &str) -> bool {
    config.is_some_and(|c| c.lines().any(|l| l.trim() == format!("{key}=y")))
}

/// PREEMPT_RT or not.
pub fn check_kernel(release: &str, uname_v: &str, config: Option<&str>) -> Finding {
    let realtime = read("/sys/kernel/realtime").is_some_and(|v| v == "1")
        || uname_v.contains("PREEMPT_RT")
        || config_has(config, "CONFIG_PREEMPT_RT");
    if realtime {
        finding("kernel", Level::Ok, format!("{release}: PREEMPT_RT"), "")
    } else {
        finding(
            "kernel",
            Level::Fail,
            format!("{release}: not PREEMPT_RT (worst-case latency is unbounded)"),
            "install a PREEMPT_RT kernel (Debian/Ubuntu: `apt install linux-image-rt-amd64` / Ubuntu Pro `pro enable realtime-kernel`) and boot it",
        )
    }
}

/// The preemption model (full is what a non-RT kernel can offer at best).
pub fn check_preemption(
    uname_v: &str,
    config: Option<&str>,
    debugfs: Option<&str>,
    cmdline: &str,
) -> Finding {
    // /sys/kernel/debug/sched/preempt reads like "none (voluntary) full" with the current one in
    // parentheses (PREEMPT_DYNAMIC kernels).
    let current = debugfs.and_then(|s| {
        let start = s.find('(')?;
        let end = s[start..].find(')')? + start;
        Some(s[start + 1..end].to_string())
    });
    let from_cmdline = cmdline
        .split_whitespace()
        .find_map(|w| w.strip_prefix("preempt="))
        .map(str::to_string);
    let model = if uname_v.contains("PREEMPT_RT") || config_has(config, "CONFIG_PREEMPT_RT") {
        "full (PREEMPT_RT)".to_string()
    } else if let Some(m) = current.or(from_cmdline) {
        m
    } else if uname_v.contains("PREEMPT_DYNAMIC") {
        "dynamic (default chosen at build time; mount debugfs to see it)".to_string()
    } else if uname_v.contains("PREEMPT") {
        "full".to_string()
    } else {
        "none or voluntary".to_string()
    };
    let level = if model.starts_with("full") {
        Level::Ok
    } else {
        Level::Warn
    };
    let fix = if level == Level::Ok {
        String::new()
    } else {
        "boot PREEMPT_RT; on a PREEMPT_DYNAMIC kernel at least add `preempt=full` to the kernel command line".to_string()
    };
    finding("preemption model", level, model, fix)
}

fn limit_line(limits: &str, name: &str) -> Option<(String, String)> {
    let line = limits.lines().find(|l| l.starts_with(name))?;
    let rest = line[name.len()..].split_whitespace().collect::<Vec<_>>();
    Some((rest.first()?.to_string(), rest.get(1)?.to_string()))
}

fn capability(status: &str, bit: u32) -> bool {
    status
        .lines()
        .find_map(|l| l.strip_prefix("CapEff:"))
        .and_then(|v| u64::from_str_radix(v.trim(), 16).ok())
        .is_some_and(|caps| caps & (1 << bit) != 0)
}

const CAP_IPC_LOCK: u32 = 14;
const CAP_SYS_NICE: u32 = 23;

/// SCHED_FIFO rights, tried for real in a throw-away thread.
pub fn check_fifo(status: &str, limits: &str) -> Finding {
    let tried = std::thread::spawn(|| exec::set_fifo(80))
        .join()
        .unwrap_or(Setting::Refused(0));
    let (soft, _) = limit_line(limits, "Max realtime priority").unwrap_or(("?".into(), "?".into()));
    let how = if capability(status, CAP_SYS_NICE) {
        "CAP_SYS_NICE".to_string()
    } else {
        format!("rtprio limit {soft}")
    };
    match tried {
        Setting::Applied => finding(
            "SCHED_FIFO",
            Level::Ok,
            format!("priority 80 granted ({how})"),
            "",
        ),
        other => finding(
            "SCHED_FIFO",
            Level::Fail,
            format!("priority 80 refused ({how}; {other:?})"),
            "add `@realtime - rtprio 98` to /etc/security/limits.d/penelope.conf and put the user in group realtime, or `setcap cap_sys_nice+ep $(which penelope)`",
        ),
    }
}

/// Whether memory can be locked.
pub fn check_memlock(status: &str, limits: &str) -> Finding {
    let (soft, _) = limit_line(limits, "Max locked memory").unwrap_or(("?".into(), "?".into()));
    if capability(status, CAP_IPC_LOCK) {
        return finding(
            "memlock",
            Level::Ok,
            format!("CAP_IPC_LOCK (limit {soft} does not apply)"),
            "",
        );
    }
    if soft == "unlimited" {
        return finding("memlock", Level::Ok, "unlimited", "");
    }
    finding(
        "memlock",
        Level::Fail,
        format!("limit {soft} bytes: mlockall of a whole process will fail"),
        "add `@realtime - memlock unlimited` to /etc/security/limits.d/penelope.conf (or `LimitMEMLOCK=infinity` in the systemd unit)",
    )
}

/// isolcpus / nohz_full.
pub fn check_isolation(isolated: Option<&str>, cmdline: &str) -> Finding {
    let isolated = isolated.unwrap_or("").trim();
    let nohz = cmdline
        .split_whitespace()
        .find(|w| w.starts_with("nohz_full="));
    if !isolated.is_empty() {
        finding(
            "CPU isolation",
            Level::Ok,
            format!(
                "isolated CPUs {isolated}{}",
                nohz.map(|n| format!(", {n}")).unwrap_or_default()
            ),
            "",
        )
    } else {
        finding(
            "CPU isolation",
            Level::Warn,
            "no isolated CPUs: the control thread shares its CPU with everything else",
            "add `isolcpus=N nohz_full=N rcu_nocbs=N irqaffinity=<others>` to the kernel command line and run with --cpu N",
        )
    }
}

/// cpufreq governors.
pub fn check_governor() -> Finding {
    let mut governors = std::collections::BTreeSet::new();
    if let Ok(dir) = std::fs::read_dir("/sys/devices/system/cpu") {
        for entry in dir.flatten() {
            let p = entry.path().join("cpufreq/scaling_governor");
            if let Ok(g) = std::fs::read_to_string(&p) {
                governors.insert(g.trim().to_string());
            }
        }
    }
    if governors.is_empty() {
        finding(
            "frequency governor",
            Level::Info,
            "no cpufreq interface (fixed frequency, or a virtual machine)",
            "",
        )
    } else if governors.iter().all(|g| g == "performance") {
        finding(
            "frequency governor",
            Level::Ok,
            "performance on every CPU",
            "",
        )
    } else {
        finding(
            "frequency governor",
            Level::Warn,
            format!(
                "governors in use: {}",
                governors.into_iter().collect::<Vec<_>>().join(", ")
            ),
            "`cpupower frequency-set -g performance` (and disable deep C-states in the BIOS)",
        )
    }
}

/// Hyper-threading.
pub fn check_smt(active: Option<&str>) -> Finding {
    match active {
        Some("0") => finding("SMT", Level::Ok, "off", ""),
        Some("1") => finding(
            "SMT",
            Level::Warn,
            "on: a sibling hyper-thread can stall the control thread",
            "add `nosmt` to the kernel command line, or keep the isolated CPU's sibling idle",
        ),
        _ => finding(
            "SMT",
            Level::Info,
            "not reported (not supported, or a virtual machine)",
            "",
        ),
    }
}

/// /dev/cpu_dma_latency.
pub fn check_dma_latency() -> Finding {
    match std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/cpu_dma_latency")
    {
        Ok(_) => finding(
            "cpu_dma_latency",
            Level::Ok,
            "writable: idle CPUs can be kept out of deep sleep",
            "",
        ),
        Err(e) => finding(
            "cpu_dma_latency",
            Level::Warn,
            format!("cannot open /dev/cpu_dma_latency for writing ({e})"),
            "run as root, or a udev rule: KERNEL==\"cpu_dma_latency\", GROUP=\"realtime\", MODE=\"0660\"",
        ),
    }
}

/// RT throttling.
pub fn check_throttling(runtime: Option<&str>) -> Finding {
    match runtime {
        Some("-1") => finding(
            "RT throttling",
            Level::Ok,
            "off (sched_rt_runtime_us = -1)",
            "",
        ),
        Some(v) => finding(
            "RT throttling",
            Level::Info,
            format!(
                "sched_rt_runtime_us = {v}: real-time threads may use at most {v} us of each second"
            ),
            "keep it as a safety net during development; for production `sysctl kernel.sched_rt_runtime_us=-1`",
        ),
        None => finding("RT throttling", Level::Info, "not reported", ""),
    }
}

/// The clock source behind CLOCK_MONOTONIC.
pub fn check_clocksource(source: Option<&str>) -> Finding {
    match source {
        Some("tsc") | Some("arch_sys_counter") => {
            finding("clock source", Level::Ok, source.unwrap_or_default(), "")
        }
        Some(other) => finding(
            "clock source",
            Level::Warn,
            format!("{other}: clock reads may be slow system calls"),
            "use `tsc` (kernel command line `tsc=reliable` if the TSC is stable)",
        ),
        None => finding("clock source", Level::Info, "not reported", ""),
    }
}

/// Virtual machines add host steal that no guest setting removes.
pub fn check_virtualization() -> Finding {
    let virt = command_output("systemd-detect-virt", &[]).filter(|v| v != "none");
    let hypervisor = read("/proc/cpuinfo").is_some_and(|c| c.contains(" hypervisor"));
    match (virt, hypervisor) {
        (Some(kind), _) => finding(
            "virtualisation",
            Level::Warn,
            format!(
                "running in a virtual machine ({kind}): host steal adds milliseconds no guest setting removes"
            ),
            "measure on bare metal; compare with cyclictest in the same run (`penelope bench jitter`)",
        ),
        (None, true) => finding(
            "virtualisation",
            Level::Warn,
            "running under a hypervisor: host steal adds latency no guest setting removes",
            "measure on bare metal; compare with cyclictest in the same run (`penelope bench jitter`)",
        ),
        (None, false) => finding("virtualisation", Level::Ok, "bare metal", ""),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn preemption_model_is_read_from_debugfs() {
        let f = check_preemption(
            "#1 SMP PREEMPT_DYNAMIC",
            None,
            Some("none voluntary (full) lazy"),
            "",
        );
        assert_eq!((f.level, f.detail.as_str()), (Level::Ok, "full"));
        let f = check_preemption(
            "#1 SMP PREEMPT_DYNAMIC",
            None,
            Some("(none) voluntary full"),
            "",
        );
        assert_eq!(f.level, Level::Warn);
        assert!(f.fix.contains("preempt=full"));
        let f = check_preemption("#1 SMP PREEMPT_RT", None, None, "");
        assert_eq!(f.level, Level::Ok);
    }

    #[test]
    fn limits_and_capabilities_parse() {
        let limits = "Limit Soft Hard Units\nMax locked memory         8388608              8388608              bytes\n";
        assert_eq!(
            limit_line(limits, "Max locked memory"),
            Some(("8388608".into(), "8388608".into()))
        );
        let status = "Name:\tx\nCapEff:\t0000000000004000\n";
        assert!(capability(status, CAP_IPC_LOCK));
        assert!(!capability(status, CAP_SYS_NICE));
        assert_eq!(check_memlock(status, limits).level, Level::Ok);
        assert_eq!(check_memlock("CapEff:\t0\n", limits).level, Level::Fail);
    }

    #[test]
    fn isolation_smt_and_throttling() {
        assert_eq!(check_isolation(Some(""), "quiet").level, Level::Warn);
        assert_eq!(
            check_isolation(Some("3"), "isolcpus=3 nohz_full=3").level,
            Level::Ok
        );
        assert_eq!(check_smt(Some("1")).level, Level::Warn);
        assert_eq!(check_throttling(Some("-1")).level, Level::Ok);
        assert_eq!(check_clocksource(Some("hpet")).level, Level::Warn);
    }
}
