//! A stable, bounded, seeded fuzz test of the URDF loader (the `drivers/fuzz` target `urdf`
//! does the same unbounded, on nightly): thousands of mutations of the committed URDFs (tokens
//! inserted, ranges deleted or repeated, the text truncated). Properties: nothing panics, every
//! refusal has a message, and every model that loads is usable (finite forward kinematics,
//! Jacobian, gravity and RNE at its start pose).

use penelope_drivers::model::{UrdfChain, urdf};
use penelope_hal::{Dynamics, JacobianFrame, JointVector, Kinematics, NamedPose};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

const SOURCES: [&str; 2] = [
    include_str!("../robots/puma560.urdf"),
    include_str!("../robots/scara.urdf"),
];

/// Fragments a mutation inserts: XML punctuation, numbers at the edges of f64, joint types and
/// elements the loader refuses.
const TOKENS: [&str; 20] = [
    "<",
    ">",
    "/>",
    "\"",
    "=",
    " ",
    "0",
    "-1",
    "1e308",
    "-1e308",
    "nan",
    "inf",
    "1e-320",
    "type=\"fixed\"",
    "type=\"floating\"",
    "type=\"continuous\"",
    "<mimic joint=\"elbow\"/>",
    "<link name=\"link3\"/>",
    "<axis xyz=\"0 0 0\"/>",
    "</joint>",
];

fn boundary(text: &str, rng: &mut ChaCha8Rng) -> usize {
    let mut i = rng.random_range(0..=text.len());
    while !text.is_char_boundary(i) {
        i -= 1;
    }
    i
}

fn mutate(text: &str, rng: &mut ChaCha8Rng) -> String {
    let mut t = text.to_string();
    for _ in 0..rng.random_range(1..4) {
        let a = boundary(&t, rng);
        let b = boundary(&t, rng);
        let (a, b) = (a.min(b), a.max(b));
        match rng.random_range(0..4) {
            0 => t.insert_str(a, TOKENS[rng.random_range(0..TOKENS.len())]),
            1 => t.replace_range(a..b.min(a + 40), ""),
            2 => {
                let piece = t[a..b.min(a + 200)].to_string();
                t.insert_str(b.min(a + 200), &piece);
            }
            _ => t.truncate(b),
        }
    }
    t
}

#[test]
fn mutated_urdfs_never_panic_and_loaded_ones_are_usable() {
    let mut rng = ChaCha8Rng::seed_from_u64(0x5552_4446);
    let (mut loaded, mut refused) = (0, 0);
    for case in 0..3000 {
        let text = mutate(SOURCES[case % 2], &mut rng);
        let chain = if case % 2 == 0 {
            UrdfChain::whole()
        } else {
            UrdfChain::to_tip("tool")
        };
        match urdf::model_from_str(&text, &chain) {
            Ok(m) => {
                loaded += 1;
                let q = m.named_pose(NamedPose::Start);
                let qd = JointVector::repeat(0.1);
                assert!(m.forward_matrix(&q).iter().all(|x| x.is_finite()), "{text}");
                assert!(
                    m.jacobian(&q, JacobianFrame::Tool)
                        .iter()
                        .all(|x| x.is_finite())
                );
                assert!(m.gravity(&q).iter().all(|x| x.is_finite()), "{text}");
                assert!(
                    m.inverse_dynamics(&q, &qd, &qd)
                        .iter()
                        .all(|x| x.is_finite())
                );
            }
            Err(e) => {
                refused += 1;
                assert!(!e.to_string().is_empty());
            }
        }
    }
    println!("{loaded} mutated URDFs loaded, {refused} refused");
    // Both outcomes occur, or the mutations test nothing.
    assert!(
        loaded > 100 && refused > 100,
        "{loaded} loaded, {refused} refused"
    );
}
