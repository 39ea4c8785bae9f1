//! The 3D view's data: what a robot looks like (its description), for the page to draw it.
//! Its live joint positions come through the live socket ([`crate::live`]), one per robot.

use std::sync::Arc;

use axum::Json;
use axum::extract::{Query, State};
use penelope_protocol::client::RobotProxy;
use penelope_protocol::proto::ContactShapeMsg;
use serde::Deserialize;
use serde_json::{Value, json};

use super::WebState;
use super::api::{ApiResult, blocking};

/// `?path=`.
#[derive(Deserialize)]
pub(crate) struct RobotQuery {
    path: String,
}

/// `GET /api/robot?path=`: the robot's URDF, its frames (root first), its joint names (the
/// order of a telemetry record's `q`) and the contact shapes its simulated tool touches, in its
/// root frame: `{"kind":"plane","point":[..],"normal":[..]}` or
/// `{"kind":"sphere","center":[..],"radius":r}`.
pub(crate) async fn robot(
    State(state): State<Arc<WebState>>,
    Query(q): Query<RobotQuery>,
) -> ApiResult {
    blocking(&state, move |client| {
        let robot: RobotProxy = client.proxy(&q.path)?;
        let d = robot.description()?;
        let contacts: Vec<Value> = d.contacts.iter().map(contact).collect();
        Ok(Json(json!({
            "path": q.path, "urdf": d.urdf, "frames": d.frames, "joint_names": d.joint_names,
            "contacts": contacts,
        })))
    })
    .await
}

/// A contact shape as the page draws it.
fn contact(shape: &ContactShapeMsg) -> Value {
    match shape {
        ContactShapeMsg::Plane { point, normal } => {
            json!({ "kind": "plane", "point": point, "normal": normal })
        }
        ContactShapeMsg::Sphere { center, radius } => {
            json!({ "kind": "sphere", "center": center, "radius": radius })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contact_shapes_read_as_the_page_draws_them() {
        let wall = contact(&ContactShapeMsg::Plane {
            point: [0.35, 0.127, 0.29],
            normal: [0.0, 0.0, 1.0],
        });
        assert_eq!(
            wall,
            json!({ "kind": "plane", "point": [0.35, 0.127, 0.29], "normal": [0.0, 0.0, 1.0] })
        );
        let ball = contact(&ContactShapeMsg::Sphere {
            center: [0.5, 0.0, 0.1],
            radius: 0.05,
        });
        assert_eq!(ball["kind"], "sphere");
        assert_eq!(ball["radius"], 0.05);
        assert_eq!(ball["center"][0], 0.5);
    }
}
