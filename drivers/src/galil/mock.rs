//! A scripted link for tests, in the embedded-hal-mock style: a list of expected writes and
//! scripted reads, consumed in order; [`MockLink::done`] asserts every one was consumed.
//!
//! Reads deliver exactly the bytes of one [`Transaction::Read`] (or fewer, if the caller's buffer
//! is smaller), so a script controls how replies are split. A read with no scripted bytes left
//! (or a [`Transaction::Silence`]) times out at once and returns `Ok(0)`.

use std::collections::VecDeque;
use std::time::Duration;

use super::error::GalilError;
use super::link::Link;

/// One step of a script.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Transaction {
    /// The client must write exactly these bytes (several writes may add up to them).
    Write(Vec<u8>),
    /// The next read returns these bytes.
    Read(Vec<u8>),
    /// The next read times out (returns 0 bytes).
    Silence,
    /// The next read or write fails: the device went away.
    Close,
}

impl Transaction {
    /// An expected write.
    pub fn write(bytes: impl AsRef<[u8]>) -> Self {
        Transaction::Write(bytes.as_ref().to_vec())
    }

    /// A scripted read.
    pub fn read(bytes: impl AsRef<[u8]>) -> Self {
        Transaction::Read(bytes.as_ref().to_vec())
    }

    /// One scripted read per byte: the most split a serial line can deliver.
    pub fn read_bytewise(bytes: impl AsRef<[u8]>) -> Vec<Self> {
        bytes
            .as_ref()
            .iter()
            .map(|&b| Transaction::Read(vec![b]))
            .collect()
    }
}

/// What went wrong in a script (kept for [`MockLink::done`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MockMismatch {
    /// What the script expected at that point.
    pub expected: Option<Transaction>,
    /// What the client did.
    pub got: String,
}

/// A scripted link. Panics only in [`MockLink::done`], which is meant for tests.
#[derive(Debug, Default)]
pub struct MockLink {
    script: VecDeque<Transaction>,
    /// Bytes of the current expected write still to come.
    partial_write: Vec<u8>,
    mismatches: Vec<MockMismatch>,
    /// When true, running out of script makes reads time out silently instead of a mismatch.
    lenient_reads: bool,
}

impl MockLink {
    /// A link that will play `script`.
    pub fn new(script: impl IntoIterator<Item = Transaction>) -> Self {
        MockLink {
            script: script.into_iter().collect(),
            ..MockLink::default()
        }
    }

    /// Lets reads past the end of the script time out instead of counting as mismatches (for
    /// fuzzing, where the client may ask for more than the garbage holds).
    pub fn lenient(mut self) -> Self {
        self.lenient_reads = true;
        self
    }

    /// Appends steps.
    pub fn extend(&mut self, more: impl IntoIterator<Item = Transaction>) {
        self.script.extend(more);
    }

    /// True when the whole script was consumed.
    pub fn is_done(&self) -> bool {
        self.script.is_empty() && self.partial_write.is_empty()
    }

    /// The mismatches seen so far.
    pub fn mismatches(&self) -> &[MockMismatch] {
        &self.mismatches
    }

    /// Asserts that the script was consumed exactly and the client did nothing unexpected.
    ///
    /// # Panics
    /// When steps remain or a step did not match (this is a test helper).
    pub fn done(&self) {
        assert!(
            self.mismatches.is_empty(),
            "mock link mismatches: {:#?}",
            self.mismatches
        );
        assert!(
            self.is_done(),
            "mock link script not consumed: partial write {:?}, remaining {:#?}",
            String::from_utf8_lossy(&self.partial_write),
            self.script
        );
    }
}

impl Link for MockLink {
    fn write_all(&mut self, mut bytes: &[u8]) -> Result<(), GalilError> {
        while !bytes.is_empty() {
            if self.partial_write.is_empty() {
                match self.script.front() {
                    Some(Transaction::Write(_)) => {
                        if let Some(Transaction::Write(w)) = self.script.pop_front() {
                            self.partial_write = w;
                        }
                    }
                    Some(Transaction::Close) => {
                        self.script.pop_front();
                        return Err(GalilError::Closed);
                    }
                    other => {
                        self.mismatches.push(MockMismatch {
                            expected: other.cloned(),
                            got: format!("write {:?}", String::from_utf8_lossy(bytes)),
                        });
                        return Ok(());
                    }
                }
            }
            let n = bytes.len().min(self.partial_write.len());
            if bytes[..n] != self.partial_write[..n] {
                self.mismatches.push(MockMismatch {
                    expected: Some(Transaction::Write(self.partial_write.clone())),
                    got: format!("write {:?}", String::from_utf8_lossy(bytes)),
                });
                self.partial_write.clear();
                return Ok(());
            }
            self.partial_write.drain(..n);
            bytes = &bytes[n..];
        }
        Ok(())
    }

    fn read(&mut self, buf: &mut [u8], _timeout: Duration) -> Result<usize, GalilError> {
        match self.script.front_mut() {
            Some(Transaction::Read(data)) => {
                let n = buf.len().min(data.len());
                buf[..n].copy_from_slice(&data[..n]);
                data.drain(..n);
                if data.is_empty() {
                    self.script.pop_front();
                }
                Ok(n)
            }
            Some(Transaction::Silence) => {
                self.script.pop_front();
                Ok(0)
            }
            Some(Transaction::Close) => {
                self.script.pop_front();
                Err(GalilError::Closed)
            }
            None if self.lenient_reads => Ok(0),
            other => {
                let expected = other.map(|t| t.clone());
                self.mismatches.push(MockMismatch {
                    expected,
                    got: "read".into(),
                });
                Ok(0)
            }
        }
    }
}
