//! `penelope recording` of a crafted MCAP file: an error exit that says why, never an abort
//! (it was "memory allocation of 4702111234474983754 bytes failed", exit 134).

use std::process::{Command, Stdio};

/// 111 bytes: the MCAP magic, a header record, and a zstd chunk (one raw block) holding a
/// record header whose length field is 0x4141_4141_4141_4141.
fn crafted() -> Vec<u8> {
    fn record(file: &mut Vec<u8>, opcode: u8, body: &[u8]) {
        file.push(opcode);
        file.extend((body.len() as u64).to_le_bytes());
        file.extend(body);
    }
    fn string(out: &mut Vec<u8>, s: &[u8]) {
        out.extend((s.len() as u32).to_le_bytes());
        out.extend(s);
    }
    let mut file = b"\x89MCAP0\r\n".to_vec();
    let mut header = Vec::new();
    string(&mut header, b"penelope");
    string(&mut header, b"crafted");
    record(&mut file, 0x01, &header);
    let mut inner = vec![0x05];
    inner.extend(0x4141_4141_4141_4141u64.to_le_bytes());
    let mut zstd = vec![0x28, 0xb5, 0x2f, 0xfd, 0x20, inner.len() as u8];
    zstd.extend(&(((inner.len() as u32) << 3) | 1).to_le_bytes()[..3]);
    zstd.extend(&inner);
    let mut chunk = Vec::new();
    chunk.extend(0u64.to_le_bytes());
    chunk.extend(0u64.to_le_bytes());
    chunk.extend((inner.len() as u64).to_le_bytes());
    chunk.extend(0u32.to_le_bytes());
    string(&mut chunk, b"zstd");
    chunk.extend((zstd.len() as u64).to_le_bytes());
    chunk.extend(&zstd);
    record(&mut file, 0x06, &chunk);
    file
}

#[test]
fn a_crafted_mcap_is_an_error_exit_of_penelope_recording_not_an_abort() {
    let path = std::env::temp_dir().join(format!("penelope-crafted-{}.mcap", std::process::id()));
    std::fs::write(&path, crafted()).unwrap();
    for (command, extra) in [
        ("info", &[][..]),
        ("info", &["--json"][..]),
        ("rerun", &[][..]),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_penelope"))
            .args(["recording", command])
            .arg(&path)
            .args(extra)
            .stdin(Stdio::null())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        println!("recording {command} {extra:?}: {:?}, {stderr}", out.status);
        // Exited (not killed by SIGABRT), with an error code, saying what is wrong.
        assert!(
            out.status.code().is_some_and(|c| c != 0),
            "{:?}",
            out.status
        );
        assert!(stderr.contains("exceeds limit"), "{stderr}");
        assert!(!stderr.contains("memory allocation"), "{stderr}");
    }
    let _ = std::fs::remove_file(path);
}
