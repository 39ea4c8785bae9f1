//! Hardware in the loop: a real ATI Net F/T, named by `PENELOPE_NETFT_ADDR` (`ip:49152`), with
//! its calibration in `PENELOPE_NETFT_CPF` and `PENELOPE_NETFT_CPT` (counts per N and per N·m;
//! 1000000 each when unset). Unloaded transducer. Runs only with `--features hardware-tests`:
//!
//! ```sh
//! PENELOPE_NETFT_ADDR=192.168.1.1:49152 cargo test --release -p penelope-drivers \
//!     --features hardware-tests --test netft_hardware -- --nocapture
//! ```

use std::time::Duration;

use penelope_drivers::netft::{Calibration, NetFt, NetFtConfig};
use penelope_hal::Sensor;
use penelope_rt_core::clock::MonotonicClock;

fn env_f64(name: &str) -> f64 {
    std::env::var(name)
        .ok()
        .map(|v| v.parse().unwrap_or_else(|e| panic!("{name}={v}: {e}")))
        .unwrap_or(1_000_000.0)
}

#[test]
#[cfg_attr(
    not(feature = "hardware-tests"),
    ignore = "needs a Net F/T: --features hardware-tests and PENELOPE_NETFT_ADDR"
)]
fn a_real_net_ft_streams_and_biases() {
    let addr = std::env::var("PENELOPE_NETFT_ADDR")
        .expect("PENELOPE_NETFT_ADDR names the box (ip:49152)")
        .parse()
        .expect("PENELOPE_NETFT_ADDR is ip:port");
    let mut config = NetFtConfig::new(addr);
    config.calibration = Calibration {
        counts_per_force: env_f64("PENELOPE_NETFT_CPF"),
        counts_per_torque: env_f64("PENELOPE_NETFT_CPT"),
    };
    config.timeout = Duration::from_millis(100);
    let ft = NetFt::open(config).unwrap();
    let mut reader = ft.reader();
    assert!(
        ft.wait_for_records(2000, Duration::from_secs(10)),
        "{:?}",
        ft.counters()
    );
    let c = ft.counters();
    eprintln!("{c:?}");
    assert_eq!(c.malformed, 0);
    assert_eq!(
        c.status_errors + c.saturated,
        0,
        "the box reports a fault: {:?}",
        ft.latest()
    );

    // Bias the unloaded transducer: its reading then sits near zero.
    ft.request_bias();
    let n = ft.counters().records;
    assert!(ft.wait_for_records(n + 500, Duration::from_secs(10)));
    let w = reader
        .read(MonotonicClock::read())
        .expect("a healthy reading");
    eprintln!("after bias: {w:?}");
    assert!(w.force.norm() < 1.0, "{w:?}");
}
