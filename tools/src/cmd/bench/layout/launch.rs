//! One layout run: the system file placed on the layout's hosts, the naming service and the
//! nodes started in their network namespaces, the UDP echo and a watcher beside the task, and
//! the recordings read back into the layout's figures.

use std::net::{IpAddr, SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use penelope_runtime::objects::clock::ClockMode;
use penelope_runtime::objects::recording::read_recording;
use penelope_supervisor::runs::recording::from_recordings;
use penelope_supervisor::runs::{RunOptions, RunOutput};
use penelope_supervisor::system::SystemFile;

use super::hosts::Hosts;
use super::latency::{self, Echo, Percentiles};
use super::{
    Layout, LayoutRecord, NAMING_PORT, NODE_PORT, READY, layout_record, system_nodes_of_task,
};

/// A directory removed when dropped.
struct ScratchDir(PathBuf);

impl Drop for ScratchDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// `file` with each node's data-plane address, and each sensor's `publish` address, moved to
/// the address of the host it runs on (ports kept).
fn placed(file: &str, host_of: &dyn Fn(&str) -> Option<IpAddr>) -> anyhow::Result<String> {
    let mut table: toml::Table = file.parse().context("parsing the system file")?;
    let moved = |value: &mut toml::Value, ip: IpAddr| -> anyhow::Result<()> {
        let addr: SocketAddr = value
            .as_str()
            .context("an address is not a string")?
            .parse()
            .context("an address is not HOST:PORT")?;
        *value = toml::Value::String(SocketAddr::new(ip, addr.port()).to_string());
        Ok(())
    };
    if let Some(nodes) = table.get_mut("nodes").and_then(toml::Value::as_table_mut) {
        for (name, node) in nodes.iter_mut() {
            if let (Some(v), Some(ip)) = (node.get_mut("data_plane"), host_of(name)) {
                moved(v, ip)?;
            }
        }
    }
    if let Some(sensors) = table.get_mut("sensors").and_then(toml::Value::as_table_mut) {
        for (_, sensor) in sensors.iter_mut() {
            let node = sensor
                .get("node")
                .and_then(toml::Value::as_str)
                .map(String::from);
            if let (Some(node), Some(v)) = (node, sensor.get_mut("publish"))
                && let Some(ip) = host_of(&node)
            {
                moved(v, ip)?;
            }
        }
    }
    Ok(table.to_string())
}

/// `file` with the tables of `extra` merged in (a table of `extra` adds its entries to the
/// file's table of the same name, replacing an entry of the same name).
fn with_tables(file: &str, extra: &toml::Table) -> anyhow::Result<String> {
    let mut table: toml::Table = file.parse().context("parsing the system file")?;
    for (section, entries) in extra {
        match (table.get_mut(section), entries) {
            (Some(toml::Value::Table(into)), toml::Value::Table(from)) => {
                into.extend(from.clone());
            }
            _ => {
                table.insert(section.clone(), entries.clone());
            }
        }
    }
    Ok(table.to_string())
}

/// `file` with every teleoperation channel's `handoff` set to `handoff`.
fn with_handoff(file: &str, handoff: &str) -> anyhow::Result<String> {
    let mut table: toml::Table = file.parse().context("parsing the system file")?;
    if let Some(trajectories) = table
        .get_mut("trajectories")
        .and_then(toml::Value::as_table_mut)
    {
        for (_, t) in trajectories.iter_mut() {
            if let Some(t) = t.as_table_mut()
                && t.get("kind").and_then(toml::Value::as_str) == Some("teleop")
            {
                t.insert("handoff".into(), toml::Value::String(handoff.into()));
            }
        }
    }
    Ok(table.to_string())
}

/// Runs the task in `layout` and measures it.
pub fn run_layout(
    layout: &Layout,
    duration: Option<Duration>,
    handoff: Option<&str>,
) -> anyhow::Result<LayoutRecord> {
    let plan = LayoutPlan {
        layout,
        duration,
        handoff,
        extra: None,
    };
    run_layout_watched(&plan, None::<Watcher<()>>).map(|(record, _)| record)
}

/// What a layout run is: the layout, the task's length, the channel's handoff, and objects
/// added to the system file.
pub struct LayoutPlan<'a> {
    /// Where each process runs.
    pub layout: &'a Layout,
    /// Length of the task (default: the operator's script, 20 s).
    pub duration: Option<Duration>,
    /// The channel's handoff, if not the file's.
    pub handoff: Option<&'a str>,
    /// TOML tables merged into the system file after its addresses are placed (a camera, say).
    pub extra: Option<&'a toml::Table>,
}

/// What a watcher started on a host during a layout run is given.
pub struct WatchContext {
    /// The naming service's address.
    pub naming: SocketAddr,
    /// The shared secret's file.
    pub secret_file: PathBuf,
    /// The task's length: the watcher watches about this long.
    pub task_length: Duration,
}

/// A client run on a host of the layout while the task runs (after every node is ready), and
/// what it found: `(node whose host it runs on, the client)`.
pub type Watcher<T> = (
    &'static str,
    Box<dyn FnOnce(WatchContext) -> anyhow::Result<T> + Send + 'static>,
);

/// Runs `plan` and measures it; with a watcher, runs it on its node's host during the task and
/// returns what it found beside the layout's figures.
pub fn run_layout_watched<T: Send + 'static>(
    plan: &LayoutPlan<'_>,
    watcher: Option<Watcher<T>>,
) -> anyhow::Result<(LayoutRecord, Option<T>)> {
    let (layout, duration) = (plan.layout, plan.duration);
    let exe = std::env::current_exe().context("finding the penelope binary")?;
    let scratch = ScratchDir(std::env::temp_dir().join(format!(
        "penelope-layout-{}-{}",
        layout.name,
        std::process::id()
    )));
    std::fs::create_dir_all(&scratch.0)?;
    let mut hosts = Hosts::create(layout.hosts.len())?;
    let host_of_node = |node: &str| layout.hosts.iter().position(|h| h.contains(&Some(node)));
    let naming_host = layout
        .hosts
        .iter()
        .position(|h| h.contains(&None))
        .context("a layout without a naming service")?;
    let naming = SocketAddr::new(hosts.address(naming_host), NAMING_PORT);
    let file_text = placed(layout.system, &|n| {
        host_of_node(n).map(|h| hosts.address(h))
    })?;
    let file_text = match plan.handoff {
        Some(h) => with_handoff(&file_text, h)?,
        None => file_text,
    };
    let file_text = match plan.extra {
        Some(extra) => with_tables(&file_text, extra)?,
        None => file_text,
    };
    let system_path = scratch.0.join("system.toml");
    std::fs::write(&system_path, &file_text)?;
    let system = SystemFile::parse(&file_text).map_err(|e| anyhow::anyhow!("{e}"))?;
    let secret = scratch.0.join("secret");
    crate::cmd::secret::write_new_secret(&secret)?;
    let launch = Launch {
        exe: &exe,
        system_path: &system_path,
        naming,
        secret: &secret,
        scratch: &scratch.0,
    };

    launch.naming_service(&mut hosts, naming_host)?;
    let task_nodes = system_nodes_of_task(&system)?;
    let recordings = launch.nodes(&mut hosts, layout, task_nodes)?;
    let task_length = duration.unwrap_or(Duration::from_secs(20));
    let watching = match watcher {
        Some((node, watch)) => {
            let host = host_of_node(node)
                .with_context(|| format!("the watcher's node `{node}` is not in the layout"))?;
            let context = WatchContext {
                naming,
                secret_file: secret.clone(),
                task_length,
            };
            Some(hosts.spawn_in(host, move || watch(context)))
        }
        None => None,
    };

    // The raw UDP echo between the joystick's host and the robot's, alongside the task.
    let (echo, echo_addr) = start_echo(&hosts, layout.ends.1)?;
    let options = RunOptions {
        duration,
        clock: ClockMode::RealTime,
        ..RunOptions::default()
    };
    let count = (task_length.as_millis() / 2) as usize;
    let addr_a = hosts.address(layout.ends.0);
    let pinger = hosts.spawn_in(layout.ends.0, move || {
        let socket = UdpSocket::bind(SocketAddr::new(addr_a, 0))?;
        Ok(latency::ping(
            &socket,
            echo_addr,
            count,
            Duration::from_millis(2),
        )?)
    });

    let output = wait_for_recordings(&recordings, &system, &options, task_length)?;
    let (echoes, lost) = pinger
        .join()
        .map_err(|_| anyhow::anyhow!("the echo client's thread panicked"))??;
    let watched = match watching {
        Some(w) => Some(
            w.join()
                .map_err(|_| anyhow::anyhow!("the watcher's thread panicked"))??,
        ),
        None => None,
    };
    drop(echo);
    hosts.stop_all(Duration::from_secs(15))?;
    // The finished recordings (their loss counts are written at the end).
    let read: Vec<_> = recordings
        .iter()
        .map(|p| read_recording(p))
        .collect::<Result<_, _>>()?;
    let output = from_recordings(&system, &options, &read)?.unwrap_or(output);
    Ok((
        layout_record(
            layout,
            &output,
            &read,
            task_nodes,
            Percentiles::of(echoes),
            lost,
        ),
        watched,
    ))
}

/// What every process of a layout run is started with.
struct Launch<'a> {
    /// The penelope binary.
    exe: &'a Path,
    /// The placed system file.
    system_path: &'a Path,
    /// The naming service's address.
    naming: SocketAddr,
    /// The shared secret's file.
    secret: &'a Path,
    /// Where the recordings go.
    scratch: &'a Path,
}

impl Launch<'_> {
    /// Starts the naming service on host `host` and waits until it listens.
    fn naming_service(&self, hosts: &mut Hosts, host: usize) -> anyhow::Result<()> {
        hosts.start(
            host,
            "naming service",
            self.exe,
            &[
                "naming".into(),
                "--listen".into(),
                self.naming.to_string(),
                "--secret-file".into(),
                self.secret.display().to_string(),
            ],
            "naming service on",
            READY,
        )
    }

    /// Starts every node of `layout` on its host (the task's two recording) and returns the
    /// recordings' paths. The robot's side first, the joystick last: the operator starts once
    /// the slave is there (its first sample anchors the slave; the hand's script starts with
    /// the master).
    fn nodes(
        &self,
        hosts: &mut Hosts,
        layout: &Layout,
        task_nodes: (&str, &str),
    ) -> anyhow::Result<Vec<PathBuf>> {
        let s = |p: &Path| p.display().to_string();
        let mut nodes: Vec<(usize, &str)> = Vec::new();
        for (h, roles) in layout.hosts.iter().enumerate() {
            for node in roles.iter().flatten() {
                nodes.push((h, node));
            }
        }
        nodes.sort_by_key(|(_, n)| (*n == task_nodes.0, *n == task_nodes.1));
        let mut recordings = Vec::new();
        for (h, node) in &nodes {
            let record = self.scratch.join(format!("{node}.mcap"));
            let mut node_args = vec![
                "node".into(),
                "--name".into(),
                node.to_string(),
                "--config".into(),
                s(self.system_path),
                "--naming".into(),
                self.naming.to_string(),
                "--listen".into(),
                SocketAddr::new(hosts.address(*h), NODE_PORT).to_string(),
                "--secret-file".into(),
                s(self.secret),
            ];
            if *node == task_nodes.0 || *node == task_nodes.1 {
                node_args.extend(["--record".into(), s(&record)]);
                recordings.push(record);
            }
            hosts.start(
                *h,
                &format!("node {node}"),
                self.exe,
                &node_args,
                "Ctrl-C stops the node",
                READY,
            )?;
        }
        Ok(recordings)
    }
}

/// Starts the UDP echo server on host `host`; returns it and its address.
fn start_echo(hosts: &Hosts, host: usize) -> anyhow::Result<(Echo, SocketAddr)> {
    let addr = hosts.address(host);
    hosts
        .spawn_in(host, move || {
            let socket = UdpSocket::bind(SocketAddr::new(addr, 0))?;
            let addr = socket.local_addr()?;
            Ok((Echo::serve(socket)?, addr))
        })
        .join()
        .map_err(|_| anyhow::anyhow!("the echo server's thread panicked"))?
}

/// Waits until the recordings cover the task (bounded: the task's length and a minute), and
/// returns the run they make.
fn wait_for_recordings(
    recordings: &[PathBuf],
    system: &SystemFile,
    options: &RunOptions,
    task_length: Duration,
) -> anyhow::Result<RunOutput> {
    let deadline = Instant::now() + task_length + Duration::from_secs(60);
    loop {
        std::thread::sleep(Duration::from_millis(250));
        let read: Result<Vec<_>, _> = recordings.iter().map(|p| read_recording(p)).collect();
        if let Ok(read) = read
            && let Some(out) = from_recordings(system, options, &read)?
        {
            return Ok(out);
        }
        if Instant::now() >= deadline {
            bail!("the recordings did not cover the task within {task_length:?} + 60 s");
        }
    }
}
