//! Scratch directories.

use std::path::PathBuf;

/// A fresh, empty directory `penelope-TAG-PID-NAME` under the temporary directory: the process
/// id keeps concurrent test binaries apart, `name` the tests of one binary.
pub fn scratch_dir(tag: &str, name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("penelope-{tag}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create a scratch directory");
    dir
}

/// Writes `body` to the file `name` in the scratch directory `penelope-TAG-PID` (shared by the
/// tests of one binary, kept as it is) and returns its path.
pub fn scratch_file(tag: &str, name: &str, body: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("penelope-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("create a scratch directory");
    let path = dir.join(name);
    std::fs::write(&path, body).expect("write a scratch file");
    path
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scratch_dir_starts_empty() {
        let d = scratch_dir("testkit", "empty");
        std::fs::write(d.join("x"), "1").unwrap();
        let again = scratch_dir("testkit", "empty");
        assert_eq!(d, again);
        assert_eq!(std::fs::read_dir(&again).unwrap().count(), 0);
        let f = scratch_file("testkit", "f.txt", "body");
        assert_eq!(std::fs::read_to_string(f).unwrap(), "body");
    }
}
