//! CDR (XCDR1, little-endian) as ROS 2 serializes messages: a 4-byte encapsulation header
//! (`00 01` = CDR little-endian, then two option bytes), then the fields in declaration order,
//! each primitive aligned to its own size counted from the first byte after the header;
//! strings are a `u32` length including the terminating NUL, the bytes, the NUL; sequences a
//! `u32` count then the elements.

use thiserror::Error;

/// The encapsulation header Penelope writes: CDR little-endian, no options.
pub const ENCAPSULATION_CDR_LE: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// The largest string or sequence (in bytes or elements) a decoder accepts: a corrupt length
/// field must not make the reader reserve gigabytes.
pub const MAX_LENGTH: usize = 1 << 20;

/// Why a CDR payload could not be decoded.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum CdrError {
    /// The payload is shorter than the 4-byte encapsulation header.
    #[error("CDR payload of {len} bytes has no 4-byte encapsulation header")]
    NoHeader {
        /// The payload's length.
        len: usize,
    },
    /// The encapsulation is not CDR little-endian (`00 01`).
    #[error("unsupported CDR encapsulation {0:02x} {1:02x} (only 00 01, CDR little-endian)")]
    UnsupportedEncapsulation(u8, u8),
    /// The payload ends before a field (or its alignment padding) does.
    #[error(
        "CDR payload truncated: {needed} bytes needed at offset {offset}, {available} available"
    )]
    Truncated {
        /// Offset after the header where the read started.
        offset: usize,
        /// Bytes the read needed.
        needed: usize,
        /// Bytes left in the payload.
        available: usize,
    },
    /// A string or sequence length over [`MAX_LENGTH`].
    #[error("CDR length {len} at offset {offset} is over the limit of {MAX_LENGTH}")]
    TooLong {
        /// Offset of the length field.
        offset: usize,
        /// The length it holds.
        len: usize,
    },
    /// A string whose length is 0 (it must count its NUL) or whose last byte is not NUL.
    #[error("CDR string at offset {offset} is not NUL-terminated")]
    StringNotTerminated {
        /// Offset of the string's length field.
        offset: usize,
    },
    /// A string that is not UTF-8.
    #[error("CDR string at offset {offset} is not UTF-8")]
    InvalidUtf8 {
        /// Offset of the string's length field.
        offset: usize,
    },
    /// A `bool` byte that is neither 0 nor 1.
    #[error("CDR bool at offset {offset} holds {value}")]
    InvalidBool {
        /// Offset of the byte.
        offset: usize,
        /// The byte.
        value: u8,
    },
    /// Bytes left over after the message beyond the at most 3 bytes of end padding
    /// some middlewares add (the payload is for another type, or corrupt).
    #[error("{count} bytes left over after the CDR message")]
    TrailingBytes {
        /// How many.
        count: usize,
    },
}

/// Writes CDR fields into a buffer that already holds the encapsulation header.
pub struct CdrWriter<'a> {
    out: &'a mut Vec<u8>,
    /// Index in `out` of the first byte after the header: alignment counts from here.
    origin: usize,
}

impl<'a> CdrWriter<'a> {
    /// Appends the encapsulation header to `out` and returns a writer for the body.
    pub fn new(out: &'a mut Vec<u8>) -> Self {
        out.extend_from_slice(&ENCAPSULATION_CDR_LE);
        let origin = out.len();
        Self { out, origin }
    }

    fn align(&mut self, alignment: usize) {
        let position = self.out.len() - self.origin;
        let padding = (alignment - position % alignment) % alignment;
        self.out.resize(self.out.len() + padding, 0);
    }

    /// Writes a primitive's little-endian bytes aligned to their size.
    pub fn write_aligned<const N: usize>(&mut self, bytes: [u8; N]) {
        self.align(N);
        self.out.extend_from_slice(&bytes);
    }

    /// Writes a string or sequence length.
    pub fn write_length(&mut self, len: usize) {
        // Lengths over u32 cannot be represented; the messages Penelope writes are far smaller.
        let len = u32::try_from(len).unwrap_or(u32::MAX);
        self.write_aligned(len.to_le_bytes());
    }

    /// Writes a string: length including NUL, bytes, NUL.
    pub fn write_string(&mut self, value: &str) {
        self.write_length(value.len() + 1);
        self.out.extend_from_slice(value.as_bytes());
        self.out.push(0);
    }
}

/// Reads CDR fields from a payload, checking every length against what is left.
pub struct CdrReader<'a> {
    body: &'a [u8],
    position: usize,
}

impl<'a> CdrReader<'a> {
    /// Checks the encapsulation header and returns a reader for the body.
    pub fn new(payload: &'a [u8]) -> Result<Self, CdrError> {
        let [kind_high, kind_low, _, _] = match payload.get(..4) {
            Some(&[a, b, c, d]) => [a, b, c, d],
            _ => return Err(CdrError::NoHeader { len: payload.len() }),
        };
        if (kind_high, kind_low) != (0x00, 0x01) {
            return Err(CdrError::UnsupportedEncapsulation(kind_high, kind_low));
        }
        Ok(Self {
            body: &payload[4..],
            position: 0,
        })
    }

    /// Offset in the body (after the header) of the next read.
    pub fn position(&self) -> usize {
        self.position
    }

    fn take(&mut self, needed: usize) -> Result<&'a [u8], CdrError> {
        let available = self.body.len() - self.position;
        if needed > available {
            return Err(CdrError::Truncated {
                offset: self.position,
                needed,
                available,
            });
        }
        let bytes = &self.body[self.position..self.position + needed];
        self.position += needed;
        Ok(bytes)
    }

    fn align(&mut self, alignment: usize) -> Result<(), CdrError> {
        let padding = (alignment - self.position % alignment) % alignment;
        self.take(padding).map(|_| ())
    }

    /// Reads a primitive's little-endian bytes aligned to their size.
    pub fn read_aligned<const N: usize>(&mut self) -> Result<[u8; N], CdrError> {
        self.align(N)?;
        let bytes = self.take(N)?;
        let mut array = [0u8; N];
        array.copy_from_slice(bytes);
        Ok(array)
    }

    /// Reads a string or sequence length, refusing one over [`MAX_LENGTH`].
    pub fn read_length(&mut self) -> Result<usize, CdrError> {
        let len = u32::from_le_bytes(self.read_aligned()?) as usize;
        if len > MAX_LENGTH {
            return Err(CdrError::TooLong {
                offset: self.position - 4,
                len,
            });
        }
        Ok(len)
    }

    /// Reads a NUL-terminated UTF-8 string.
    pub fn read_string(&mut self) -> Result<String, CdrError> {
        let len = self.read_length()?;
        let offset = self.position - 4;
        let bytes = self.take(len)?;
        match bytes.split_last() {
            Some((0, text)) => std::str::from_utf8(text)
                .map(str::to_owned)
                .map_err(|_| CdrError::InvalidUtf8 { offset }),
            _ => Err(CdrError::StringNotTerminated { offset }),
        }
    }

    /// Checks that at most 3 bytes of end padding are left.
    pub fn finish(self) -> Result<(), CdrError> {
        let count = self.body.len() - self.position;
        if count > 3 {
            return Err(CdrError::TrailingBytes { count });
        }
        Ok(())
    }
}

/// A value that has a CDR form: a primitive, a string, a sequence, or a message's body.
pub trait CdrField: Sized {
    /// Appends the value (aligned) to the writer.
    fn write_cdr(&self, writer: &mut CdrWriter<'_>);
    /// Reads the value.
    fn read_cdr(reader: &mut CdrReader<'_>) -> Result<Self, CdrError>;
}

macro_rules! primitive_field {
    ($($ty:ty),*) => {$(
        impl CdrField for $ty {
            fn write_cdr(&self, writer: &mut CdrWriter<'_>) {
                writer.write_aligned(self.to_le_bytes());
            }
            fn read_cdr(reader: &mut CdrReader<'_>) -> Result<Self, CdrError> {
                Ok(<$ty>::from_le_bytes(reader.read_aligned()?))
            }
        }
    )*};
}
primitive_field!(u8, i8, u16, i16, u32, i32, u64, i64, f32, f64);

impl CdrField for bool {
    fn write_cdr(&self, writer: &mut CdrWriter<'_>) {
        writer.write_aligned([u8::from(*self)]);
    }
    fn read_cdr(reader: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        let offset = reader.position();
        match reader.read_aligned::<1>()? {
            [0] => Ok(false),
            [1] => Ok(true),
            [value] => Err(CdrError::InvalidBool { offset, value }),
        }
    }
}

impl CdrField for String {
    fn write_cdr(&self, writer: &mut CdrWriter<'_>) {
        writer.write_string(self);
    }
    fn read_cdr(reader: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        reader.read_string()
    }
}

impl<T: CdrField> CdrField for Vec<T> {
    fn write_cdr(&self, writer: &mut CdrWriter<'_>) {
        writer.write_length(self.len());
        for element in self {
            element.write_cdr(writer);
        }
    }
    fn read_cdr(reader: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        let count = reader.read_length()?;
        // Every element takes at least one byte: a count beyond what is left is truncation,
        // found before reserving room for it.
        let available = reader.body.len() - reader.position;
        if count > available {
            return Err(CdrError::Truncated {
                offset: reader.position,
                needed: count,
                available,
            });
        }
        let mut elements = Vec::with_capacity(count);
        for _ in 0..count {
            elements.push(T::read_cdr(reader)?);
        }
        Ok(elements)
    }
}

/// `T[N]`: exactly `N` elements, no length on the wire.
impl<T: CdrField + Default + Copy, const N: usize> CdrField for [T; N] {
    fn write_cdr(&self, writer: &mut CdrWriter<'_>) {
        for element in self {
            element.write_cdr(writer);
        }
    }
    fn read_cdr(reader: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        let mut elements = [T::default(); N];
        for element in &mut elements {
            *element = T::read_cdr(reader)?;
        }
        Ok(elements)
    }
}
