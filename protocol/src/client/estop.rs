//! The answer a console's red button shows (`penelope web`, `penelope foxglove`): every node's
//! e-stop report, or which nodes a global e-stop did not reach.

use crate::proto::StopReport;

use super::NodeStop;

/// Some node did not answer a global e-stop (the others are stopped all the same).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "E-STOP did not reach every node: {} (stopped: {})",
    self.unreached.join("; "),
    stopped_list(&self.stopped)
)]
pub struct EStopIncomplete {
    /// Each node not reached, with why (`node: error`).
    pub unreached: Vec<String>,
    /// The reports of the nodes reached.
    pub stopped: Vec<StopReport>,
}

/// `node [loop, …]` for each report, `;`-separated; `none` when no node was reached.
fn stopped_list(reports: &[StopReport]) -> String {
    if reports.is_empty() {
        return "none".into();
    }
    reports
        .iter()
        .map(|r| format!("{} [{}]", r.node, r.stopped.join(", ")))
        .collect::<Vec<_>>()
        .join("; ")
}

/// Every node's report from [`Client::estop_all`](super::Client::estop_all)'s answers, in
/// their order.
///
/// # Errors
/// [`EStopIncomplete`] when any node's answer is an error.
pub fn estop_reports(answers: Vec<NodeStop>) -> Result<Vec<StopReport>, EStopIncomplete> {
    let mut stopped = Vec::new();
    let mut unreached = Vec::new();
    for (node, answer) in answers {
        match answer {
            Ok(report) => stopped.push(report),
            Err(e) => unreached.push(format!("{node}: {e}")),
        }
    }
    if unreached.is_empty() {
        Ok(stopped)
    } else {
        Err(EStopIncomplete { unreached, stopped })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::net::conn::RpcError;
    use crate::proto::{CallError, WireError};

    fn report(node: &str, stopped: &[&str]) -> StopReport {
        StopReport {
            node: node.into(),
            stopped: stopped.iter().map(|s| s.to_string()).collect(),
            pending: Vec::new(),
        }
    }

    #[test]
    fn every_node_reached_gives_every_report_in_order() {
        let answers = vec![
            ("a".to_string(), Ok(report("a", &["pid"]))),
            ("b".to_string(), Ok(report("b", &[]))),
        ];
        assert_eq!(
            estop_reports(answers),
            Ok(vec![report("a", &["pid"]), report("b", &[])])
        );
    }

    #[test]
    fn a_node_not_reached_is_named_with_why_and_the_stopped_ones_kept() {
        let lost = RpcError::Remote(WireError::Call(CallError::Internal("gone".into())));
        let answers = vec![
            ("a".to_string(), Ok(report("a", &["display", "follow"]))),
            ("b".to_string(), Err(lost)),
        ];
        let e = estop_reports(answers).unwrap_err();
        assert_eq!(e.stopped, vec![report("a", &["display", "follow"])]);
        assert_eq!(e.unreached.len(), 1);
        let message = e.to_string();
        assert!(
            message.starts_with("E-STOP did not reach every node: b: "),
            "{message}"
        );
        assert!(message.contains("gone"), "{message}");
        assert!(
            message.ends_with("(stopped: a [display, follow])"),
            "{message}"
        );
    }
}
