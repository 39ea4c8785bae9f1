//! Program download (`DL`): the one exchange that is not a line of commands.

use std::time::Instant;

use super::super::error::{GalilError, Malformed};
use super::super::framing::ReplyFrame;
use super::super::link::Link;
use super::Client;

impl<L: Link> Client<L> {
    /// `DL`: downloads a program (replacing the board's program memory), then waits up to the
    /// slow timeout for the board's `:`. Lines may end with CR, LF or both; each goes out with CR.
    ///
    /// # Errors
    /// [`GalilError::InvalidArgument`] for text with `\\`, Ctrl-Z or non-ASCII bytes, or a line
    /// over 80 characters; link errors and timeouts (the client resynchronises); a rejection
    /// (the board refused the program, or a program is running) with `TC1`'s explanation.
    pub fn download(&mut self, program: &str) -> Result<(), GalilError> {
        if program
            .bytes()
            .any(|b| b == b'\\' || b == 0x1A || !b.is_ascii())
        {
            return Err(GalilError::InvalidArgument(
                "program text with a backslash, Ctrl-Z or non-ASCII",
            ));
        }
        let mut bytes = Vec::with_capacity(program.len() + 8);
        bytes.extend_from_slice(b"DL\r");
        for line in program.split(['\r', '\n']) {
            if line.len() > super::super::command::MAX_LINE {
                return Err(GalilError::LineTooLong);
            }
            if !line.is_empty() {
                bytes.extend_from_slice(line.as_bytes());
                bytes.push(b'\r');
            }
        }
        bytes.push(b'\\');
        if self.needs_resync {
            self.resync()?;
        }
        self.discard_leftovers();
        let result = self.download_inner(&bytes);
        match &result {
            Err(GalilError::Timeout(_)) => {
                self.stats.timeouts += 1;
                let _ = self.resync();
            }
            Err(e) if e.is_link_fault() => self.needs_resync = true,
            _ => {}
        }
        result
    }

    fn download_inner(&mut self, bytes: &[u8]) -> Result<(), GalilError> {
        self.link.write_all(bytes)?;
        self.stats.bytes_out += bytes.len() as u64;
        let deadline = Instant::now() + self.config.slow_timeout;
        match self.next_frame(deadline)? {
            ReplyFrame::Rejected => {
                self.stats.rejections += 1;
                Err(self.explain_rejection())
            }
            ReplyFrame::Accepted => {
                self.stats.exchanges += 1;
                Ok(())
            }
            _ => Err(GalilError::Malformed(Malformed::UnexpectedReply)),
        }
    }
}
