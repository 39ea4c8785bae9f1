//! Fuzzes the URDF loader: nothing may panic, and a model that loads answers finite forward
//! kinematics and gravity at its start pose.
//!
//! Run with `cargo +nightly fuzz run urdf` from `drivers/` (seed the corpus with
//! `drivers/robots/*.urdf`). The stable, bounded version of this target runs in the normal test
//! suite: `drivers/tests/urdf_fuzz.rs`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use penelope_drivers::model::{UrdfChain, urdf};
use penelope_hal::{Dynamics, NamedPose};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(m) = urdf::model_from_str(text, &UrdfChain::whole()) {
        let q = m.named_pose(NamedPose::Start);
        assert!(m.forward_matrix(&q).iter().all(|x| x.is_finite()));
        assert!(m.gravity(&q).iter().all(|x| x.is_finite()));
    }
});
