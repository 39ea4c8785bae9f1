//! `penelope secret new FILE`: makes a shared secret strong enough for every server of the system
//! (32 random bytes from the operating system, written as 64 hex digits and a newline, mode 600,
//! never over an existing file).

use std::io::{Read as _, Write as _};
use std::os::unix::fs::OpenOptionsExt as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context as _;
use clap::Subcommand;

/// What `penelope secret` does.
#[derive(Subcommand, Debug)]
pub enum SecretCommand {
    /// Writes a new secret (32 random bytes, hex) to FILE, readable by its owner only; refuses to
    /// overwrite an existing file.
    New {
        /// Where to write it (must not exist).
        file: PathBuf,
    },
}

/// Bytes of randomness in a new secret (256 bits; 128 are required).
pub const SECRET_BYTES: usize = 32;

/// Runs `penelope secret`.
pub fn run(command: SecretCommand) -> anyhow::Result<ExitCode> {
    match command {
        SecretCommand::New { file } => {
            write_new_secret(&file)?;
            println!(
                "wrote a new secret ({} bits) to {}; give it to every node, naming service and \
                 tool of the system with --secret-file",
                SECRET_BYTES * 8,
                file.display()
            );
            Ok(ExitCode::SUCCESS)
        }
    }
}

/// Writes 32 random bytes as hex and a newline to `file` (created with mode 600; an existing
/// file is an error).
///
/// # Errors
/// The file exists (a usage error) or cannot be written, or the random generator fails.
pub fn write_new_secret(file: &Path) -> anyhow::Result<()> {
    let mut bytes = [0u8; SECRET_BYTES];
    std::fs::File::open("/dev/urandom")
        .and_then(|mut r| r.read_exact(&mut bytes))
        .context("reading the operating system's random generator")?;
    let mut text: String = bytes.iter().map(|b| format!("{b:02x}")).collect();
    text.push('\n');
    let mut out = match std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(file)
    {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
            return Err(crate::cmd::usage(format!(
                "{} exists; a secret is never overwritten (remove it first if you mean to \
                 replace the system's secret)",
                file.display()
            )));
        }
        Err(e) => {
            return Err(e).with_context(|| format!("creating the secret file {}", file.display()));
        }
    };
    out.write_all(text.as_bytes())
        .and_then(|()| out.sync_all())
        .with_context(|| format!("writing the secret file {}", file.display()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::PermissionsExt as _;

    #[test]
    fn a_new_secret_is_strong_private_and_never_overwritten() {
        let dir = std::env::temp_dir().join(format!("penelope-secret-new-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("lab.secret");
        write_new_secret(&file).unwrap();
        let mode = std::fs::metadata(&file).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600);
        let secret = crate::cmd::naming::read_secret(Some(&file))
            .unwrap()
            .unwrap();
        assert_eq!(secret.bytes().len(), 2 * SECRET_BYTES);
        assert!(
            secret.estimated_bits() >= 256,
            "{}",
            secret.estimated_bits()
        );
        let before = std::fs::read(&file).unwrap();
        let e = write_new_secret(&file).unwrap_err().to_string();
        assert!(e.contains("never overwritten"), "{e}");
        assert_eq!(std::fs::read(&file).unwrap(), before);
        // Two secrets differ.
        let other = dir.join("other.secret");
        write_new_secret(&other).unwrap();
        assert_ne!(std::fs::read(&other).unwrap(), before);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
