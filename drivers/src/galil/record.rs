//! The binary data record (`QR`) and its layout (`QZ`).
//!
//! `QZ` answers four numbers: the axis count and the sizes in bytes of the general block, the
//! coordinated-motion block and each axis block (`6, 52, 26, 36` on a six-axis DMC-40x0). A record
//! is a four-byte header (byte 0: `0x80` plus block bits, byte 1: axis mask, bytes 2-3: the
//! record's length, little-endian), then the general block, the coordinated block and one block
//! per axis: 4 + 52 + 26 + 6 × 36 = 298 bytes.
//!
//! Fields decoded (offsets inside their block, little-endian, as on the DMC-40x0):
//!
//! | block | offset | type | field |
//! |---|---|---|---|
//! | general | 0 | u16 | sample number |
//! | axis | 0 | u16 | status |
//! | axis | 2 | u8 | switches (as `TS`) |
//! | axis | 3 | u8 | stop code (as `SC`) |
//! | axis | 4 | i32 | reference position, counts |
//! | axis | 8 | i32 | motor position, counts (as `TP`) |
//! | axis | 12 | i32 | position error, counts (as `TE`) |
//! | axis | 16 | i32 | auxiliary position, counts |
//! | axis | 20 | i32 | velocity, counts/s |
//! | axis | 24 | i32 | torque, DAC units (±32767 = ±10 V) |
//!
//! # Real-time
//! Decoding allocates nothing and runs in bounded time.

use super::command::MAX_GALIL_AXES;
use super::error::{GalilError, Malformed};
use super::number::parse_exact;

/// The smallest axis block that holds every field decoded here, bytes.
pub const MIN_AXIS_BLOCK: usize = 28;

/// The record layout `QZ` reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct RecordLayout {
    /// Number of axes with a block in the record.
    pub axes: usize,
    /// General block size, bytes (header not included).
    pub general: usize,
    /// Coordinated-motion block size, bytes.
    pub coordinated: usize,
    /// Size of each axis block, bytes.
    pub axis: usize,
}

impl RecordLayout {
    /// The six-axis DMC-40x0 layout: `6, 52, 26, 36`.
    pub const DMC40X0_SIX: RecordLayout = RecordLayout {
        axes: 6,
        general: 52,
        coordinated: 26,
        axis: 36,
    };

    /// Parses a `QZ` reply.
    ///
    /// # Errors
    /// [`Malformed::BadLayout`] unless it is four numbers describing at most eight axes, axis
    /// blocks of at least [`MIN_AXIS_BLOCK`] bytes and a record of at most
    /// [`MAX_RECORD`](super::framing::MAX_RECORD) bytes.
    pub fn parse(payload: &[u8]) -> Result<RecordLayout, GalilError> {
        let bad = GalilError::Malformed(Malformed::BadLayout);
        let mut v = [0.0; 4];
        parse_exact(payload, &mut v).map_err(|_| bad.clone())?;
        let mut n = [0usize; 4];
        for (dst, &src) in n.iter_mut().zip(&v) {
            if !(0.0..=4096.0).contains(&src) || src.fract() != 0.0 {
                return Err(bad);
            }
            *dst = src as usize;
        }
        let layout = RecordLayout {
            axes: n[0],
            general: n[1],
            coordinated: n[2],
            axis: n[3],
        };
        if layout.axes == 0
            || layout.axes > MAX_GALIL_AXES
            || layout.axis < MIN_AXIS_BLOCK
            || layout.general < 2
            || layout.record_len() > super::framing::MAX_RECORD
        {
            return Err(bad);
        }
        Ok(layout)
    }

    /// The length of a whole record, header included, bytes.
    pub const fn record_len(&self) -> usize {
        4 + self.general + self.coordinated + self.axes * self.axis
    }

    /// Where axis `i`'s block starts in the record, bytes.
    pub const fn axis_offset(&self, i: usize) -> usize {
        4 + self.general + self.coordinated + i * self.axis
    }
}

/// One axis as the data record reports it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct AxisRecord {
    /// Axis status word.
    pub status: u16,
    /// Switches, as `TS` (bit 5 motor off, bits 3/2 limits).
    pub switches: u8,
    /// Stop code, as `SC`.
    pub stop_code: u8,
    /// Reference (commanded) position, counts.
    pub reference_position: i32,
    /// Motor position, counts.
    pub position: i32,
    /// Position error, counts.
    pub position_error: i32,
    /// Auxiliary encoder position, counts.
    pub aux_position: i32,
    /// Velocity, counts/s.
    pub velocity: i32,
    /// Torque, DAC units (±32767 = ±10 V).
    pub torque: i32,
}

impl AxisRecord {
    /// True when the amplifier is off (`TS` bit 5).
    pub const fn motor_off(&self) -> bool {
        self.switches & 0x20 != 0
    }
}

/// A decoded data record.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct DataRecord {
    /// Header byte 0 (`0x80` plus block bits).
    pub header: u8,
    /// Header byte 1: which axes are present.
    pub axis_mask: u8,
    /// The controller's sample counter.
    pub sample: u16,
    /// Number of valid entries in `axes`.
    pub axis_count: usize,
    /// Per-axis blocks (the first `axis_count` are valid).
    pub axes: [AxisRecord; MAX_GALIL_AXES],
}

impl DataRecord {
    /// Decodes `bytes` (header included) per `layout`.
    ///
    /// # Errors
    /// [`Malformed::BadRecord`] when the length differs from the layout's or from the header's,
    /// or the header's first byte lacks bit 7.
    pub fn decode(bytes: &[u8], layout: &RecordLayout) -> Result<DataRecord, GalilError> {
        let bad = GalilError::Malformed(Malformed::BadRecord);
        if bytes.len() != layout.record_len() || bytes.len() < 6 || layout.axes > MAX_GALIL_AXES {
            return Err(bad);
        }
        let length = usize::from(u16::from_le_bytes([bytes[2], bytes[3]]));
        if bytes[0] & 0x80 == 0 || length != bytes.len() {
            return Err(bad);
        }
        let mut rec = DataRecord {
            header: bytes[0],
            axis_mask: bytes[1],
            sample: u16::from_le_bytes([bytes[4], bytes[5]]),
            axis_count: layout.axes,
            axes: [AxisRecord::default(); MAX_GALIL_AXES],
        };
        for (i, out) in rec.axes.iter_mut().take(layout.axes).enumerate() {
            let o = layout.axis_offset(i);
            let b = bytes.get(o..o + MIN_AXIS_BLOCK).ok_or(bad.clone())?;
            let i32_at = |k: usize| i32::from_le_bytes([b[k], b[k + 1], b[k + 2], b[k + 3]]);
            *out = AxisRecord {
                status: u16::from_le_bytes([b[0], b[1]]),
                switches: b[2],
                stop_code: b[3],
                reference_position: i32_at(4),
                position: i32_at(8),
                position_error: i32_at(12),
                aux_position: i32_at(16),
                velocity: i32_at(20),
                torque: i32_at(24),
            };
        }
        Ok(rec)
    }

    /// The valid axis blocks.
    pub fn axes(&self) -> &[AxisRecord] {
        &self.axes[..self.axis_count.min(MAX_GALIL_AXES)]
    }
}

/// Encodes a record per `layout` into `out` (the emulator's side, and tests'); returns its length.
///
/// # Errors
/// [`GalilError::InvalidArgument`] when `out` is too short or `axes` has fewer blocks than the
/// layout.
pub fn encode_record(
    layout: &RecordLayout,
    header: u8,
    sample: u16,
    axes: &[AxisRecord],
    out: &mut [u8],
) -> Result<usize, GalilError> {
    let len = layout.record_len();
    if out.len() < len || axes.len() < layout.axes || len > usize::from(u16::MAX) {
        return Err(GalilError::InvalidArgument(
            "record buffer or axes too short",
        ));
    }
    let out = &mut out[..len];
    out.fill(0);
    out[0] = header | 0x80;
    out[1] = (((1u16 << layout.axes) - 1) & 0xFF) as u8;
    out[2..4].copy_from_slice(&(len as u16).to_le_bytes());
    out[4..6].copy_from_slice(&sample.to_le_bytes());
    for (i, a) in axes.iter().take(layout.axes).enumerate() {
        let o = layout.axis_offset(i);
        let b = &mut out[o..o + MIN_AXIS_BLOCK];
        b[0..2].copy_from_slice(&a.status.to_le_bytes());
        b[2] = a.switches;
        b[3] = a.stop_code;
        for (k, v) in [
            a.reference_position,
            a.position,
            a.position_error,
            a.aux_position,
            a.velocity,
            a.torque,
        ]
        .into_iter()
        .enumerate()
        {
            b[4 + 4 * k..8 + 4 * k].copy_from_slice(&v.to_le_bytes());
        }
    }
    Ok(len)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn six_axis_layout() {
        let l = RecordLayout::parse(b" 6, 52, 26, 36\r\n").unwrap();
        assert_eq!(l, RecordLayout::DMC40X0_SIX);
        assert_eq!(l.record_len(), 298);
        assert!(RecordLayout::parse(b"6, 52, 26").is_err());
        assert!(RecordLayout::parse(b"9, 52, 26, 36").is_err());
        assert!(RecordLayout::parse(b"6, 52, 26, 4").is_err());
        assert!(RecordLayout::parse(b"6, 52.5, 26, 36").is_err());
    }

    #[test]
    fn round_trip() {
        let l = RecordLayout::DMC40X0_SIX;
        let mut axes = [AxisRecord::default(); 6];
        for (i, a) in axes.iter_mut().enumerate() {
            a.position = -1000 * i as i32 - 7;
            a.position_error = i as i32;
            a.switches = 0x20;
            a.stop_code = 8;
            a.torque = -32767;
        }
        let mut buf = [0u8; 400];
        let n = encode_record(&l, 0x07, 513, &axes, &mut buf).unwrap();
        assert_eq!(n, 298);
        let rec = DataRecord::decode(&buf[..n], &l).unwrap();
        assert_eq!(rec.sample, 513);
        assert_eq!(rec.axis_mask, 0x3F);
        assert_eq!(rec.axes(), &axes[..]);
        assert!(rec.axes()[0].motor_off());
        assert!(DataRecord::decode(&buf[..n - 1], &l).is_err());
        buf[2] = 0;
        assert!(DataRecord::decode(&buf[..n], &l).is_err());
    }
}
