//! A real board cannot be stepped by a simulated clock: a creator (a node started with
//! `--sim-clock`) refuses to create a `board/galil` with a typed error that says so, whether
//! the board comes by a `create` or from a system file, and keeps nothing; the same board on a
//! real-time creator, and a `board/sim` on the simulated one, are made as before.

use penelope_protocol::proto::{CallError, WireError};
use penelope_runtime::objects::clock::ClockMode;
use penelope_runtime::objects::{Creator, CreatorConfig};
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig};
use penelope_supervisor::system::{SystemFile, SystemFileError};

/// The shipped Galil variant of the demo.
const DEMO_GALIL: &str = include_str!("../../config/demo-galil.toml");

const GALIL: &str = "device = \"/dev/ttyUSB0\"";

fn creator(clock: ClockMode) -> Creator {
    let mut config = CreatorConfig::new("lab");
    config.clock = clock;
    Creator::new(config)
}

fn is_the_refusal(e: &WireError) -> bool {
    matches!(e, WireError::Call(CallError::Unsupported { kind, method })
        if kind == "board/galil" && method.contains("simulated clock"))
}

#[test]
fn a_galil_board_is_refused_on_the_simulated_clock_and_made_in_real_time() {
    let sim = creator(ClockMode::Simulated);
    let e = WireError::from(sim.create("board/galil", "dmc", GALIL).unwrap_err());
    assert!(is_the_refusal(&e), "{e:?}");
    assert!(
        e.to_string()
            .contains("`board/galil` does not support a node on the simulated clock"),
        "{e}"
    );
    assert_eq!(sim.object_count(), 0, "nothing is kept");
    // A simulated board is what the simulated clock steps.
    sim.create("board/sim", "sim0", "").unwrap();

    let real = creator(ClockMode::RealTime);
    let info = real.create("board/galil", "dmc", GALIL).unwrap();
    assert_eq!(info.kind, "board/galil");
}

#[test]
fn a_system_file_with_a_galil_board_is_refused_whole_on_a_sim_clock_node() {
    let mut config = NodeConfig::new("lab", NamingChoice::None);
    config.listen = std::net::SocketAddr::from(([127, 0, 0, 1], 0));
    config.creator.clock = ClockMode::Simulated;
    let node = Node::start(config).unwrap();
    let file = SystemFile::parse(DEMO_GALIL).unwrap();
    match file.apply(&node) {
        Err(SystemFileError::Step { key, error, .. }) => {
            assert_eq!(key, "boards.puma-io");
            assert!(is_the_refusal(&error), "{error:?}");
        }
        other => panic!("expected the galil board to be refused, got {other:?}"),
    }
    assert_eq!(
        node.creator().object_count(),
        0,
        "nothing from the file is kept"
    );
    node.shutdown();
}
