//! A PUMA 560 `arm` on a simulated board, driven by a controller the test names: the set-up of
//! the CRTK verbs' and the tool goals' allocation tests.

use penelope_hal::Transition;
use penelope_protocol::proto::{ControllerMethod, Method};
use penelope_runtime::objects::{Creator, CreatorConfig};

use crate::papers_task::{map_all, ok};

/// A creator for node `node` (normal priority) holding a PUMA 560 `arm` on a simulated board
/// `sim` (joint j on axis j), both configured.
pub fn puma_on_sim_board(node: &str) -> Creator {
    let mut config = CreatorConfig::new(node);
    config.rt.priority = None;
    let c = Creator::new(config);
    c.create("robot/puma560", "arm", "").unwrap();
    c.create("board/sim", "sim", "").unwrap();
    map_all(&c, "arm", "sim");
    ok(&c, "sim", Method::Transition(Transition::Configure));
    ok(&c, "arm", Method::Transition(Transition::Configure));
    c
}

/// Creates controller `name` of `kind` (its keys `config`) driving `arm` along `trajectory`
/// (configured already), and configures it.
pub fn arm_controller(c: &Creator, kind: &str, name: &str, config: &str, trajectory: &str) {
    c.create(kind, name, config).unwrap();
    for m in [
        ControllerMethod::SetRobot {
            robot: "arm".into(),
        },
        ControllerMethod::SetTrajectory {
            trajectory: trajectory.into(),
        },
    ] {
        ok(c, name, Method::Controller(m));
    }
    ok(c, name, Method::Transition(Transition::Configure));
}
