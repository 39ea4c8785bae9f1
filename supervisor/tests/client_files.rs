//! Issue 31, files a client names: a hostile client of a real node on loopback names robot
//! description files the node must not read (`/dev/zero`, a FIFO, a link, a huge file, a file
//! outside the node's robot-file directories). Each is refused at once, and the node keeps
//! answering other calls meanwhile.

use std::net::SocketAddr;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use penelope_protocol::client::Client;
use penelope_protocol::net::conn::{ClientConfig, RpcError};
use penelope_protocol::proto::{CallError, WireError};
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig};
use penelope_testkit::scratch::scratch_dir;

/// A node hosting its naming service on loopback, reading robot files from `dir` only.
fn node(name: &str, dir: &std::path::Path) -> Node {
    let mut config = NodeConfig::new(name, NamingChoice::Host);
    config.creator.rt.priority = None;
    config.creator.robot_files = vec![dir.to_path_buf()];
    Node::start(config).unwrap()
}

fn refusal(e: RpcError) -> String {
    match e {
        RpcError::Remote(WireError::Call(CallError::BadConfig { message, .. })) => message,
        other => panic!("not a BadConfig refusal: {other:?}"),
    }
}

#[test]
fn robot_files_a_client_names_are_read_only_from_the_nodes_directories_regular_and_bounded() {
    let dir = scratch_dir("files", "robots");
    let outside = scratch_dir("files", "outside");
    hostile_files(&dir, &outside);

    let n = node("files", &dir);
    let client = Client::connect(n.address(), ClientConfig::admin("hostile")).unwrap();
    let lab = client.node("files").unwrap();

    // What the directory holds is read: by name, or by its absolute path.
    lab.create("robot/urdf", "ok", "file = \"puma560.urdf\"")
        .unwrap();
    let absolute = dir.join("puma560.urdf");
    lab.create(
        "robot/urdf",
        "ok-abs",
        &format!("file = {:?}", absolute.display().to_string()),
    )
    .unwrap();

    // While the hostile calls go on, another client's calls are answered.
    let stop = Arc::new(AtomicBool::new(false));
    let (watcher, ready_rx) = another_client_listing(n.address(), stop.clone());

    ready_rx
        .recv_timeout(Duration::from_secs(30))
        .expect("the other client is served");
    let outside_file = outside.join("puma560.urdf").display().to_string();
    let cases: [(&str, String, &str); 7] = [
        ("zero", "/dev/zero".into(), "outside"),
        ("fifo", "fifo.urdf".into(), "not a regular file"),
        ("link", "link.urdf".into(), "not a regular file"),
        ("huge", "huge.urdf".into(), "larger than 4194304 bytes"),
        (
            "up",
            format!(
                "../penelope-files-{}-outside/puma560.urdf",
                std::process::id()
            ),
            "outside",
        ),
        ("abs", outside_file, "outside"),
        ("passwd", "/etc/passwd".into(), "outside"),
    ];
    for (name, file, why) in &cases {
        let t = Instant::now();
        let message = refusal(
            lab.create("robot/urdf", name, &format!("file = {file:?}"))
                .unwrap_err(),
        );
        let took = t.elapsed();
        println!("{name} ({file}): refused in {took:?}: {message}");
        assert!(message.contains(why), "{name}: {message}");
        assert!(took < Duration::from_secs(1), "{name} took {took:?}");
    }
    stop.store(true, Ordering::Relaxed);
    let (calls, slowest) = watcher.join().unwrap();
    println!("{calls} list calls meanwhile, the slowest {slowest:?}");
    assert!(calls > 0);
    assert!(
        slowest < Duration::from_secs(1),
        "a call waited {slowest:?}"
    );
    // The node is well: the good robots are there, the refused ones are not.
    let names: Vec<String> = lab.list().unwrap().into_iter().map(|o| o.name).collect();
    assert_eq!(names, ["ok", "ok-abs"]);
    drop(client);
    n.shutdown();
    let _ = std::fs::remove_dir_all(dir);
    let _ = std::fs::remove_dir_all(outside);
}

/// In `dir`: a real URDF, a FIFO nobody writes, a link to a file in `outside`, and a sparse
/// file past the bound; in `outside`, the same URDF.
fn hostile_files(dir: &Path, outside: &Path) {
    let puma = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../drivers/robots/puma560.urdf"
    );
    std::fs::copy(puma, dir.join("puma560.urdf")).unwrap();
    std::fs::copy(puma, outside.join("puma560.urdf")).unwrap();
    // A FIFO nobody writes (its open would block without O_NONBLOCK, its read forever).
    nix::unistd::mkfifo(&dir.join("fifo.urdf"), nix::sys::stat::Mode::S_IRWXU).unwrap();
    // A link in the directory to a file outside it.
    std::os::unix::fs::symlink(outside.join("puma560.urdf"), dir.join("link.urdf")).unwrap();
    // A sparse file past the bound.
    let huge = std::fs::File::create(dir.join("huge.urdf")).unwrap();
    huge.set_len(64 * 1024 * 1024).unwrap();
    drop(huge);
}

/// Another client listing the node's objects until `stop` (or 100,000 calls); it says on the
/// channel when its first call was answered, and its thread answers how many calls it made
/// and the slowest.
fn another_client_listing(
    address: SocketAddr,
    flag: Arc<AtomicBool>,
) -> (
    std::thread::JoinHandle<(u32, Duration)>,
    std::sync::mpsc::Receiver<()>,
) {
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    let watcher = std::thread::spawn(move || {
        let client = Client::connect(address, ClientConfig::new("operator")).unwrap();
        let lab = client.node("files").unwrap();
        // Answered once before the hostile calls start (they take microseconds).
        let t = Instant::now();
        lab.list().unwrap();
        let mut slowest = t.elapsed();
        let mut calls = 1u32;
        ready_tx.send(()).unwrap();
        while !flag.load(Ordering::Relaxed) && calls < 100_000 {
            let t = Instant::now();
            lab.list().unwrap();
            slowest = slowest.max(t.elapsed());
            calls += 1;
        }
        (calls, slowest)
    });
    (watcher, ready_rx)
}

#[test]
fn a_node_without_robot_file_directories_reads_no_robot_file() {
    let mut config = NodeConfig::new("nodir", NamingChoice::Host);
    config.creator.rt.priority = None;
    let n = Node::start(config).unwrap();
    let client = Client::connect(n.address(), ClientConfig::admin("hostile")).unwrap();
    let lab = client.node("nodir").unwrap();
    let puma = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../drivers/robots/puma560.urdf"
    );
    let message = refusal(
        lab.create("robot/urdf", "r", &format!("file = {puma:?}"))
            .unwrap_err(),
    );
    assert!(message.contains("--robot-files"), "{message}");
    n.shutdown();
    // Even a directory that holds devices gives no device: `/dev/zero` is no regular file.
    let n = node("devdir", std::path::Path::new("/dev"));
    let client = Client::connect(n.address(), ClientConfig::admin("hostile")).unwrap();
    let lab = client.node("devdir").unwrap();
    let t = Instant::now();
    let message = refusal(
        lab.create("robot/urdf", "z", "file = \"/dev/zero\"")
            .unwrap_err(),
    );
    println!(
        "/dev/zero from /dev: refused in {:?}: {message}",
        t.elapsed()
    );
    assert!(message.contains("not a regular file"), "{message}");
    assert!(t.elapsed() < Duration::from_secs(1));
    n.shutdown();
}
