//! A stop cannot be queued behind work: while another client's `create` blocks on a FIFO (a
//! robot/urdf whose file never ends) and the node's object registry is held locked, an e-stop
//! of the node, and one of a single controller, are answered and acted on by the running loop
//! (its e-stop latched, its amplifiers off) — the registry still locked throughout.
//!
//! The registry is held through the creator's fault-injection hook as well as by the FIFO
//! create, so the test keeps showing the property once plain-file checks refuse a FIFO.

use std::net::SocketAddr;
use std::os::unix::fs::OpenOptionsExt as _;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::channel;
use std::time::{Duration, Instant};

use penelope_hal::Transition;
use penelope_protocol::client::Client;
use penelope_protocol::net::conn::ClientConfig;
use penelope_protocol::net::server::{Server, ServerConfig};
use penelope_protocol::proto::{
    BoardMethod, Class, ControllerMethod, JointAxis, Method, ObjectRef, Reply, RobotMethod,
    object_path,
};
use penelope_runtime::objects::{Creator, CreatorConfig};
use penelope_supervisor::naming::{NamingLimits, NamingService};
use penelope_testkit::wait::wait_until;

const NODE: &str = "lab";

/// A naming service and one node on loopback, with a PUMA 560 on a simulated board held by a
/// running joint PID.
struct Lab {
    _naming: Server,
    _node: Server,
    creator: Arc<Creator>,
    naming: SocketAddr,
}

fn ok(c: &Creator, name: &str, method: Method) -> Reply {
    c.call_object(name, method)
        .unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn loop_state(c: &Creator) -> (String, u64) {
    match ok(c, "pid", Method::Controller(ControllerMethod::Status)) {
        Reply::Status(s) => (s.last.map(|r| r.state).unwrap_or_default(), s.ticks),
        other => panic!("status answered {other:?}"),
    }
}

fn amplifiers_on(c: &Creator) -> bool {
    match ok(c, "sim", Method::Board(BoardMethod::AmplifiersEnabled)) {
        Reply::Flag(f) => f,
        other => panic!("amplifiers answered {other:?}"),
    }
}

impl Lab {
    fn start() -> Lab {
        let any: SocketAddr = "127.0.0.1:0".parse().unwrap();
        let naming = Server::bind(
            any,
            ServerConfig::new("naming"),
            Arc::new(NamingService::new("naming", NamingLimits::default())),
        )
        .unwrap();
        let mut config = CreatorConfig::new(NODE);
        config.rt.priority = None;
        let creator = Arc::new(Creator::new(config));
        let node = Server::bind(any, ServerConfig::new(NODE), creator.clone()).unwrap();
        let client = Client::connect(naming.local_addr(), ClientConfig::node(NODE)).unwrap();
        let bind = |class: Class, name: &str, kind: &str| {
            let path = object_path(NODE, class, name);
            let name = if class == Class::Creator {
                "creator"
            } else {
                name
            };
            client
                .naming()
                .bind(
                    &path,
                    ObjectRef {
                        node: NODE.into(),
                        address: node.local_addr().to_string(),
                        name: name.into(),
                        class,
                        kind: kind.into(),
                    },
                    false,
                )
                .unwrap();
        };
        bind(Class::Creator, "", "creator");
        bind(Class::Controller, "pid", "controller/joint-pid");

        let c = &creator;
        for (kind, name, cfg) in [
            ("robot/puma560", "arm", ""),
            ("board/sim", "sim", ""),
            ("trajectory/step", "hold", "pose = \"start\""),
            ("controller/joint-pid", "pid", ""),
        ] {
            c.create(kind, name, cfg).unwrap();
        }
        ok(
            c,
            "arm",
            Method::Robot(RobotMethod::MapJoints {
                board: "sim".into(),
                joints: (0..6).map(|j| JointAxis { joint: j, axis: j }).collect(),
            }),
        );
        for name in ["sim", "arm", "hold"] {
            ok(c, name, Method::Transition(Transition::Configure));
        }
        for m in [
            ControllerMethod::SetRobot {
                robot: "arm".into(),
            },
            ControllerMethod::SetTrajectory {
                trajectory: "hold".into(),
            },
        ] {
            ok(c, "pid", Method::Controller(m));
        }
        ok(c, "pid", Method::Transition(Transition::Configure));
        ok(c, "pid", Method::Transition(Transition::Activate));
        wait_until("the loop runs", || loop_state(c).1 > 100);
        assert!(amplifiers_on(c));
        Lab {
            naming: naming.local_addr(),
            _naming: naming,
            _node: node,
            creator,
        }
    }

    fn client(&self, name: &str) -> Client {
        Client::connect(self.naming, ClientConfig::new(name)).unwrap()
    }

    /// Runs `stop` (an e-stop from a client of its own) while the registry is held: by
    /// another client's `create` blocked reading the FIFO `fifo` when given (and when the node
    /// accepts a FIFO as a file at all), else by the creator's hook. Returns how long `stop`
    /// took, having checked that the registry was held all along.
    fn stop_while_busy(&self, fifo: Option<&PathBuf>, stop: impl FnOnce() + Send) -> Duration {
        let creator = &self.creator;
        let describe_done = AtomicBool::new(false);
        std::thread::scope(|s| {
            let (release_tx, release_rx) = channel::<()>();
            let mut writer = None;
            let mut fifo_create = None;
            if let Some(fifo) = fifo {
                // Another client's create, reading a FIFO: blocked in its read while the
                // registry is locked, once a writer holds the FIFO open without writing.
                // An admin: the create must reach the file (a reader's is refused at once).
                let slow = Client::connect(self.naming, ClientConfig::admin("slow")).unwrap();
                let create = s.spawn(move || {
                    let config = format!("file = \"{}\"", fifo.display());
                    slow.node(NODE)
                        .and_then(|n| n.create("robot/urdf", "from-fifo", &config))
                });
                // A non-blocking writer opens only once the create has the FIFO open.
                let deadline = Instant::now() + Duration::from_secs(20);
                while writer.is_none() && !create.is_finished() {
                    assert!(
                        Instant::now() < deadline,
                        "the create never opened the FIFO"
                    );
                    writer = std::fs::OpenOptions::new()
                        .write(true)
                        .custom_flags(0o4000) // O_NONBLOCK
                        .open(fifo)
                        .ok();
                    std::thread::sleep(Duration::from_millis(2));
                }
                if writer.is_none() {
                    println!(
                        "the node refused a FIFO as a file ({:?}): the registry is held by the hook",
                        create.join().unwrap()
                    );
                } else {
                    fifo_create = Some(create);
                }
            }
            let hold = writer.is_none().then(|| {
                let (held_tx, held_rx) = channel();
                let hold = s.spawn(move || {
                    creator.hold_registry_lock(|| {
                        held_tx.send(()).unwrap();
                        let _ = release_rx.recv_timeout(Duration::from_secs(30));
                    })
                });
                held_rx.recv_timeout(Duration::from_secs(20)).unwrap();
                hold
            });
            // A call that needs the registry: it cannot finish until the registry is free.
            let probe = self.client("probe");
            let describe_done = &describe_done;
            let describe = s.spawn(move || {
                let r = probe.call(
                    &object_path(NODE, Class::Controller, "pid"),
                    Method::Describe,
                );
                describe_done.store(true, Ordering::SeqCst);
                r
            });
            let started = Instant::now();
            stop();
            let took = started.elapsed();
            assert!(
                !describe_done.load(Ordering::SeqCst),
                "the registry was not held while the e-stop was served"
            );
            // Free the registry: the writer closes (the create reads an empty file and is
            // refused), or the hook lets go.
            drop(writer);
            if let Some(create) = fifo_create {
                assert!(
                    create.join().unwrap().is_err(),
                    "an empty URDF was accepted"
                );
            }
            let _ = release_tx.send(());
            if let Some(hold) = hold {
                hold.join().unwrap().unwrap();
            }
            describe.join().unwrap().unwrap();
            took
        })
    }
}

fn make_fifo(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("penelope-estop-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    let _ = std::fs::remove_file(&path);
    let status = std::process::Command::new("mkfifo")
        .arg(&path)
        .status()
        .unwrap();
    assert!(status.success(), "mkfifo {}", path.display());
    path
}

#[test]
fn an_estop_is_served_and_latched_while_a_create_holds_the_registry() {
    let lab = Lab::start();
    let fifo = make_fifo("arm.urdf");

    // The node's red button, from a client of its own.
    let stopper = lab.client("stopper");
    let node = stopper.node(NODE).unwrap();
    let mut report = None;
    let took = lab.stop_while_busy(Some(&fifo), || report = Some(node.estop().unwrap()));
    let report = report.unwrap();
    println!("node e-stop answered, its loop latched, in {took:?} (registry locked)");
    assert_eq!(report.stopped, vec!["pid".to_string()], "{report:?}");
    assert!(report.pending.is_empty(), "{report:?}");
    assert!(took < Duration::from_secs(2), "{took:?}");
    // The loop's telemetry says so (the pump publishes its samples a little later).
    wait_until("the loop's samples show estop", || {
        loop_state(&lab.creator).0 == "estop"
    });
    assert!(!amplifiers_on(&lab.creator));

    // Re-armed; then one controller's e-stop, likewise while the registry is held.
    ok(
        &lab.creator,
        "pid",
        Method::Controller(ControllerMethod::Rearm),
    );
    wait_until("the loop runs again", || {
        matches!(loop_state(&lab.creator).0.as_str(), "running" | "holding")
    });
    assert!(amplifiers_on(&lab.creator));
    let pid = stopper
        .controller(&object_path(NODE, Class::Controller, "pid"))
        .unwrap();
    let took = lab.stop_while_busy(None, || pid.estop().unwrap());
    println!("controller e-stop answered in {took:?} (registry locked)");
    assert!(took < Duration::from_secs(2), "{took:?}");
    // The loop's telemetry says so (the pump publishes its samples a little later).
    wait_until("the loop's samples show estop", || {
        loop_state(&lab.creator).0 == "estop"
    });
    assert!(!amplifiers_on(&lab.creator));
}
