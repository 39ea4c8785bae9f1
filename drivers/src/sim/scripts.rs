//! The virtual operator's built-in scripts (the demo's, by name), and the names of their phases.

use core::time::Duration;

use super::operator::{Motion, OperatorScript, Segment};
use nalgebra::Vector3;

/// Phases in which the slave moves freely (no contact, no clutch): where tracking and drag are
/// measured.
pub const FREE_MOTION_PHASES: &[&str] = &["reach", "sweep", "sweep-fast", "return", "approach"];

/// The phase of steady contact with the wall: where displayed and sensed forces are compared.
pub const CONTACT_PHASE: &str = "contact";

/// The tapping phase: where energy is watched.
pub const TAP_PHASE: &str = "tap";

/// The clutch (indexing) phase.
pub const INDEX_PHASE: &str = "index";

fn seg(label: &'static str, motion: Motion, seconds: f64, clutch: bool) -> Segment {
    Segment {
        label,
        motion,
        duration: Duration::from_secs_f64(seconds),
        clutch,
    }
}

/// The demo's 20-second script, in the master's base frame relative to the handle's start:
/// settle, reach forward, a slow side-to-side sweep, a faster fore-and-aft sweep, an indexing
/// move with the clutch held (the slave holds while the hand rises 2 cm), return, approach the
/// wall, push into it, hold steady contact, lift, tap the wall, release and rest.
pub fn demo() -> OperatorScript {
    let z = |z: f64| Motion::MoveTo {
        offset: Vector3::new(0.0, 0.0, z),
    };
    let segments = [
        seg("settle", Motion::Hold, 1.0, false),
        seg(
            "reach",
            Motion::MoveTo {
                offset: Vector3::new(0.04, 0.0, 0.0),
            },
            1.5,
            false,
        ),
        seg(
            "sweep",
            Motion::Sine {
                axis: Vector3::y_axis(),
                amplitude: 0.04,
                frequency: 0.5,
                fade: Duration::from_millis(500),
            },
            4.0,
            false,
        ),
        seg(
            "sweep-fast",
            Motion::Sine {
                axis: Vector3::x_axis(),
                amplitude: 0.008,
                frequency: 1.5,
                fade: Duration::from_millis(400),
            },
            2.0,
            false,
        ),
        seg(
            "index",
            Motion::MoveTo {
                offset: Vector3::new(0.0, 0.0, 0.02),
            },
            1.0,
            true,
        ),
        seg("return", z(0.0), 1.0, false),
        seg("approach", z(-0.012), 1.0, false),
        seg("push", z(-0.045), 1.0, false),
        seg(CONTACT_PHASE, Motion::Hold, 2.0, false),
        seg("lift", z(-0.01), 0.5, false),
        seg(
            TAP_PHASE,
            Motion::Tap {
                direction: -Vector3::z_axis(),
                depth: 0.035,
                frequency: 2.0,
            },
            3.0,
            false,
        ),
        seg("release", z(0.0), 1.5, false),
        seg("rest", Motion::Hold, 0.5, false),
    ];
    // Thirteen segments fit in the script's fixed capacity.
    OperatorScript::new(&segments).unwrap_or_else(|_| unreachable!("13 segments < MAX_SEGMENTS"))
}

/// A script by name.
pub fn by_name(name: &str) -> Option<OperatorScript> {
    match name {
        "demo" => Some(demo()),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_demo_script_lasts_twenty_seconds_and_names_its_phases() {
        let s = demo();
        assert_eq!(s.duration(), Duration::from_secs(20));
        for phase in FREE_MOTION_PHASES
            .iter()
            .chain([&CONTACT_PHASE, &TAP_PHASE, &INDEX_PHASE])
        {
            assert!(
                s.segments().iter().any(|seg| seg.label == *phase),
                "{phase}"
            );
        }
        assert!(
            s.clutch(Duration::from_millis(9_000)),
            "the clutch is held while indexing"
        );
    }
}
