//! What the command line tools and the web server share, all of it protocol-level: usage
//! errors, secret files, configuration text, method text parsed into calls ([`method`]) and
//! replies formatted for people ([`show`]).

pub mod method;
pub mod show;

use std::collections::HashMap;
use std::net::ToSocketAddrs;
use std::path::Path;

use anyhow::Context as _;
use penelope_protocol::client::Client;
use penelope_protocol::net::auth::Secret;
use penelope_protocol::proto::{Call, CreatorCall, NameEntry, Reply};

/// Bad input from the user (unknown robot, wrong joint count, NaN): exit code 2.
#[derive(Debug)]
pub struct UsageError(pub String);

impl std::fmt::Display for UsageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for UsageError {}

/// Shorthand: an `anyhow` error carrying a [`UsageError`].
pub fn usage(message: impl Into<String>) -> anyhow::Error {
    anyhow::Error::new(UsageError(message.into()))
}

/// The secret in `file` (its bytes without a trailing newline), if given: the one reader of
/// secret files for every command (`naming`, `node`, `ctl`).
///
/// Like ssh with private keys, a file that anyone but its owner may read or write is refused,
/// with the command that fixes it.
///
/// A secret under 128 bits ([`Secret::check_strength`]) is refused, saying how to make one
/// (`penelope secret new FILE`).
///
/// # Errors
/// The file cannot be read, others may read or write it, or the secret is empty or too weak
/// (usage errors, exit 2).
pub fn read_secret(file: Option<&Path>) -> anyhow::Result<Option<Secret>> {
    use std::os::unix::fs::PermissionsExt as _;
    let Some(file) = file else {
        return Ok(None);
    };
    let meta = std::fs::metadata(file)
        .with_context(|| format!("reading the secret file {}", file.display()))?;
    let mode = meta.permissions().mode() & 0o777;
    if mode & 0o077 != 0 {
        return Err(usage(format!(
            "the secret file {f} may be read or written by others (mode {mode:03o}); a secret \
             must be readable by its owner only: run `chmod 600 {f}`",
            f = file.display()
        )));
    }
    let mut bytes = std::fs::read(file)
        .with_context(|| format!("reading the secret file {}", file.display()))?;
    while bytes.last().is_some_and(|b| *b == b'\n' || *b == b'\r') {
        bytes.pop();
    }
    if bytes.is_empty() {
        return Err(usage(format!(
            "the secret file {} is empty",
            file.display()
        )));
    }
    let secret = Secret::from(bytes);
    secret
        .check_strength(&format!("the secret in {}", file.display()))
        .map_err(usage)?;
    Ok(Some(secret))
}

/// The lifecycle state of every object in `tree`, by `(node, name)`, from one creator `List`
/// per node (nodes that do not answer are left out).
pub fn object_states(
    client: &Client,
    tree: &[(String, usize, NameEntry)],
) -> HashMap<(String, String), String> {
    let mut nodes: Vec<(String, String)> = tree
        .iter()
        .filter_map(|(_, _, e)| match e {
            NameEntry::Object { reference, .. } => {
                Some((reference.node.clone(), reference.address.clone()))
            }
            NameEntry::Context { .. } => None,
        })
        .collect();
    nodes.sort();
    nodes.dedup();
    let mut states = HashMap::new();
    for (node, address) in nodes {
        let Some(addr) = address.to_socket_addrs().ok().and_then(|mut a| a.next()) else {
            continue;
        };
        if let Ok(Reply::Objects(list)) = client.call_at(addr, Call::Creator(CreatorCall::List)) {
            for o in list {
                states.insert((node.clone(), o.name), o.state.to_string());
            }
        }
    }
    states
}

/// The configuration text of `create`: the key=value settings, then --config or
/// --config-file, checked to be TOML.
pub fn config_text(
    config: Option<String>,
    file: Option<&std::path::Path>,
    settings: &[String],
) -> anyhow::Result<String> {
    let mut text = String::new();
    for s in settings {
        let Some((key, value)) = s.split_once('=') else {
            return Err(usage(format!("`{s}` is not KEY=VALUE")));
        };
        let (key, value) = (key.trim(), value.trim());
        if key.is_empty()
            || !key
                .bytes()
                .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-' | b'.'))
        {
            return Err(usage(format!("`{key}` is not a configuration key")));
        }
        let value = if format!("v = {value}").parse::<toml::Table>().is_ok() {
            value.to_string()
        } else {
            toml::Value::String(value.to_string()).to_string()
        };
        text.push_str(&format!("{key} = {value}\n"));
    }
    match (config, file) {
        (Some(c), _) => text.push_str(&c),
        (None, Some(f)) => text.push_str(
            &std::fs::read_to_string(f)
                .map_err(|e| usage(format!("--config-file {}: {e}", f.display())))?,
        ),
        (None, None) => {}
    }
    text.parse::<toml::Table>().map_err(|e| {
        usage(format!(
            "the configuration is not valid TOML: {}",
            e.message()
        ))
    })?;
    Ok(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_become_toml_and_bad_ones_are_usage_errors() {
        let text = config_text(
            Some("[gains]\nkp = 1.0".into()),
            None,
            &[
                "axes=6".into(),
                "device=/dev/ttyUSB0".into(),
                "q0=[0, 0.5]".into(),
            ],
        )
        .unwrap();
        let t: toml::Table = text.parse().unwrap();
        assert_eq!(t["axes"].as_integer(), Some(6));
        assert_eq!(t["device"].as_str(), Some("/dev/ttyUSB0"));
        assert_eq!(t["q0"].as_array().map(Vec::len), Some(2));
        assert!(t["gains"]["kp"].as_float().is_some());
        for bad in ["novalue", "bad key=1", "=3"] {
            let e = config_text(None, None, &[bad.into()]).unwrap_err();
            assert!(e.downcast_ref::<UsageError>().is_some(), "{bad}");
        }
        let e = config_text(Some("a = [".into()), None, &[]).unwrap_err();
        assert!(e.downcast_ref::<UsageError>().is_some());
    }
}
