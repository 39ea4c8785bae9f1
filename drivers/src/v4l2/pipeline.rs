//! From dequeued buffers to frames: the newest buffer wins (older ones waiting are dropped and
//! counted), a garbled one is dropped and counted, a good one is stamped and made into a JPEG.
//!
//! The buffers come from a [`BufferSource`]: the device's stream, or made-up buffers in tests.

use std::time::Duration;

use super::error::V4l2Error;
use super::format::{NegotiatedFormat, PixelFormat};
use super::mjpeg::mjpeg_to_jpeg;
use super::stamper::FrameStamper;
use super::stats::CaptureStats;
use super::timestamp::{BufferStamp, FLAG_ERROR, TimestampSource};
use super::yuyv::{encode_rgb_jpeg, yuyv_to_rgb};

/// One captured frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CapturedFrame {
    /// The driver's frame counter (`v4l2_buffer.sequence`).
    pub sequence: u32,
    /// The capture instant (middle of the exposure) on the node's monotonic clock, ns.
    pub capture_ns: u64,
    /// When it was dequeued, node monotonic clock, ns.
    pub dequeued_ns: u64,
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// The image as a baseline JPEG file.
    pub jpeg: Vec<u8>,
    /// Where `capture_ns` came from.
    pub timestamp_source: TimestampSource,
    /// The exposure used for the capture instant, ns (`None`: the driver reports none).
    pub exposure_ns: Option<u64>,
}

/// A dequeued buffer, its bytes copied out so that the driver gets the buffer back at once.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RawBuffer {
    /// The used bytes (`bytesused`).
    pub data: Vec<u8>,
    /// Its stamp, flags and sequence number.
    pub stamp: BufferStamp,
    /// When it was dequeued, node monotonic clock, ns.
    pub dequeued_ns: u64,
}

/// Where filled buffers come from.
pub trait BufferSource {
    /// A filled buffer if one is ready within `wait` (`Duration::ZERO`: only one already
    /// filled), its bytes copied into `reuse` (a spare byte buffer); `None` when none came.
    fn dequeue(&mut self, wait: Duration, reuse: Vec<u8>) -> Result<Option<RawBuffer>, V4l2Error>;
}

/// Turns a stream's buffers into frames, with its counters.
pub struct FramePipeline {
    negotiated: NegotiatedFormat,
    jpeg_quality: u8,
    stamper: FrameStamper,
    stats: CaptureStats,
    /// Byte buffers of frames already handled, reused.
    spare: Vec<Vec<u8>>,
    rgb: Vec<u8>,
}

impl FramePipeline {
    /// A pipeline for frames of the negotiated format, stamped by `stamper`.
    pub fn new(negotiated: NegotiatedFormat, jpeg_quality: u8, stamper: FrameStamper) -> Self {
        FramePipeline {
            negotiated,
            jpeg_quality,
            stamper,
            stats: CaptureStats::default(),
            spare: Vec::new(),
            rgb: Vec::new(),
        }
    }

    /// The counters so far.
    pub fn stats(&self) -> CaptureStats {
        self.stats
    }

    /// The next frame: the newest buffer the source has, waiting up to `timeout` when none is
    /// ready. A garbled buffer is dropped, counted and returned as [`V4l2Error::Garbled`].
    pub fn next(
        &mut self,
        source: &mut impl BufferSource,
        timeout: Duration,
        exposure_ns: Option<u64>,
    ) -> Result<CapturedFrame, V4l2Error> {
        let mut raw = self
            .dequeue(source, timeout)?
            .ok_or(V4l2Error::Timeout(timeout))?;
        // The newest frame wins: a buffer already filled is newer than `raw`. Bounded: the
        // driver cannot have more filled than it has buffers.
        for _ in 0..self.negotiated.buffers.max(2) * 2 {
            match self.dequeue(source, Duration::ZERO)? {
                Some(newer) => {
                    self.stats.dropped_behind += 1;
                    let older = std::mem::replace(&mut raw, newer);
                    self.spare.push(older.data);
                }
                None => break,
            }
        }
        let result = self.frame_of(&raw, exposure_ns);
        self.spare.push(raw.data);
        result
    }

    fn dequeue(
        &mut self,
        source: &mut impl BufferSource,
        wait: Duration,
    ) -> Result<Option<RawBuffer>, V4l2Error> {
        let reuse = self.spare.pop().unwrap_or_default();
        let raw = source.dequeue(wait, reuse)?;
        if let Some(raw) = &raw {
            self.stamper.dequeued(&raw.stamp, &mut self.stats);
        }
        Ok(raw)
    }

    /// The frame a buffer holds, stamped; a garbled one is counted.
    fn frame_of(
        &mut self,
        raw: &RawBuffer,
        exposure_ns: Option<u64>,
    ) -> Result<CapturedFrame, V4l2Error> {
        let jpeg = match self.jpeg_of(raw) {
            Ok(jpeg) => jpeg,
            Err(reason) => {
                self.stats.garbled += 1;
                return Err(V4l2Error::Garbled {
                    sequence: raw.stamp.sequence,
                    reason,
                });
            }
        };
        let instant = self
            .stamper
            .stamp(&raw.stamp, raw.dequeued_ns, exposure_ns, &mut self.stats);
        self.stats.frames += 1;
        Ok(CapturedFrame {
            sequence: raw.stamp.sequence,
            capture_ns: instant.capture_ns,
            dequeued_ns: raw.dequeued_ns,
            width: self.negotiated.width,
            height: self.negotiated.height,
            jpeg,
            timestamp_source: instant.source,
            exposure_ns,
        })
    }

    /// The buffer's image as a JPEG file, or why it is garbled.
    fn jpeg_of(&mut self, raw: &RawBuffer) -> Result<Vec<u8>, String> {
        let (width, height) = (self.negotiated.width, self.negotiated.height);
        if raw.stamp.flags & FLAG_ERROR != 0 {
            return Err("the driver flagged the buffer as corrupted".into());
        }
        match self.negotiated.format {
            PixelFormat::Mjpeg => {
                let f = mjpeg_to_jpeg(&raw.data).map_err(|e| e.to_string())?;
                if f.size != (width, height) {
                    return Err(format!(
                        "a {}x{} JPEG, {width}x{height} negotiated",
                        f.size.0, f.size.1
                    ));
                }
                self.stats.huffman_tables_inserted += u64::from(f.tables_inserted);
                Ok(f.bytes)
            }
            PixelFormat::Yuyv => {
                yuyv_to_rgb(
                    &raw.data,
                    width,
                    height,
                    self.negotiated.stride,
                    &mut self.rgb,
                )
                .map_err(|e| e.to_string())?;
                encode_rgb_jpeg(&self.rgb, width, height, self.jpeg_quality)
                    .map_err(|e| e.to_string())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use std::collections::VecDeque;

    use super::super::timestamp::{
        FLAG_TIMESTAMP_MONOTONIC, FLAG_TIMESTAMP_UNKNOWN, FLAG_TSTAMP_SRC_SOE, FallbackReason,
        StampPolicy,
    };
    use super::*;

    const MS: u64 = 1_000_000;
    const SOE: u32 = FLAG_TIMESTAMP_MONOTONIC | FLAG_TSTAMP_SRC_SOE;

    /// Buffers the "driver" has filled, in order; none waits to be filled.
    struct MadeUpSource {
        filled: VecDeque<RawBuffer>,
    }

    impl BufferSource for MadeUpSource {
        fn dequeue(
            &mut self,
            _wait: Duration,
            mut reuse: Vec<u8>,
        ) -> Result<Option<RawBuffer>, V4l2Error> {
            Ok(self.filled.pop_front().map(|mut b| {
                reuse.clear();
                reuse.extend_from_slice(&b.data);
                b.data = reuse;
                b
            }))
        }
    }

    /// A 16x8 JPEG with its Huffman tables cut out, as a UVC camera sends it.
    fn mjpeg_16x8() -> Vec<u8> {
        let rgb = vec![128u8; 16 * 8 * 3];
        let mut jpeg = Vec::new();
        jpeg_encoder::Encoder::new(&mut jpeg, 80)
            .encode(&rgb, 16, 8, jpeg_encoder::ColorType::Rgb)
            .unwrap();
        let mut out = jpeg[..2].to_vec();
        let mut at = 2;
        loop {
            let marker = jpeg[at + 1];
            let len = usize::from(u16::from_be_bytes([jpeg[at + 2], jpeg[at + 3]]));
            if marker == 0xDA {
                out.extend_from_slice(&jpeg[at..]);
                return out;
            }
            if marker != 0xC4 {
                out.extend_from_slice(&jpeg[at..at + 2 + len]);
            }
            at += 2 + len;
        }
    }

    fn buffer(sequence: u32, t_ms: u64, flags: u32, data: Vec<u8>) -> RawBuffer {
        RawBuffer {
            data,
            stamp: BufferStamp {
                timestamp_ns: t_ms * MS,
                flags,
                sequence,
            },
            dequeued_ns: t_ms * MS + 30 * MS,
        }
    }

    fn pipeline(format: PixelFormat) -> FramePipeline {
        let negotiated = NegotiatedFormat {
            format,
            width: 16,
            height: 8,
            stride: 32,
            rate_hz: Some(30.0),
            buffers: 3,
        };
        let policy = StampPolicy {
            readout_ns: 10 * MS,
            fallback_latency_ns: 40 * MS,
            max_age_ns: 500 * MS,
            future_tolerance_ns: MS,
        };
        FramePipeline::new(negotiated, 85, FrameStamper::new(policy))
    }

    fn decoded_size(jpeg: &[u8]) -> Option<(usize, usize)> {
        let mut d = zune_jpeg::JpegDecoder::new(jpeg);
        d.decode().ok()?;
        d.dimensions()
    }

    #[test]
    fn reader_that_fell_behind_gets_the_newest_frame_and_the_older_are_counted_dropped() {
        let mut p = pipeline(PixelFormat::Mjpeg);
        let mut source = MadeUpSource {
            filled: (0..3)
                .map(|i| buffer(i, 1_000 + 33 * u64::from(i), SOE, mjpeg_16x8()))
                .collect(),
        };
        let f = p
            .next(&mut source, Duration::from_secs(1), Some(10 * MS))
            .unwrap();
        assert_eq!(f.sequence, 2);
        assert_eq!(f.capture_ns, 1_066 * MS + 5 * MS);
        assert_eq!(f.timestamp_source, TimestampSource::StartOfExposure);
        assert_eq!(decoded_size(&f.jpeg), Some((16, 8)));
        let s = p.stats();
        assert_eq!((s.frames, s.dropped_behind, s.lost_by_driver), (1, 2, 0));
        assert_eq!(s.huffman_tables_inserted, 1);
    }

    #[test]
    fn garbled_buffers_are_dropped_counted_and_the_next_frame_comes_through() {
        let mut p = pipeline(PixelFormat::Mjpeg);
        let good = mjpeg_16x8();
        let truncated = good[..good.len() / 2].to_vec();
        let mut source = MadeUpSource {
            filled: VecDeque::from([buffer(0, 1_000, SOE, truncated)]),
        };
        let e = p
            .next(&mut source, Duration::from_millis(10), None)
            .unwrap_err();
        assert!(matches!(e, V4l2Error::Garbled { sequence: 0, .. }), "{e}");
        // the driver's own error flag
        source
            .filled
            .push_back(buffer(1, 1_033, SOE | FLAG_ERROR, good.clone()));
        let e = p
            .next(&mut source, Duration::from_millis(10), None)
            .unwrap_err();
        assert!(matches!(e, V4l2Error::Garbled { sequence: 1, .. }), "{e}");
        // a good frame after both, with a gap of 2 the driver lost
        source.filled.push_back(buffer(4, 1_133, SOE, good));
        let f = p
            .next(&mut source, Duration::from_millis(10), None)
            .unwrap();
        assert_eq!(f.sequence, 4);
        let s = p.stats();
        assert_eq!((s.garbled, s.frames, s.lost_by_driver), (2, 1, 2));
    }

    #[test]
    fn no_buffer_in_time_is_a_timeout() {
        let mut p = pipeline(PixelFormat::Mjpeg);
        let mut source = MadeUpSource {
            filled: VecDeque::new(),
        };
        let e = p
            .next(&mut source, Duration::from_millis(5), None)
            .unwrap_err();
        assert!(matches!(e, V4l2Error::Timeout(_)), "{e}");
        assert!(e.is_transient());
    }

    #[test]
    fn yuyv_buffer_becomes_a_jpeg_and_a_short_one_is_garbled() {
        let mut p = pipeline(PixelFormat::Yuyv);
        let frame: Vec<u8> = [200u8, 128].repeat(16 * 8);
        let mut source = MadeUpSource {
            filled: VecDeque::from([
                buffer(0, 1_000, FLAG_TIMESTAMP_UNKNOWN, frame.clone()),
                // a later, short one would win and be garbled: keep them apart
            ]),
        };
        let f = p
            .next(&mut source, Duration::from_millis(10), None)
            .unwrap();
        assert_eq!(decoded_size(&f.jpeg), Some((16, 8)));
        assert_eq!(
            f.timestamp_source,
            TimestampSource::Fallback(FallbackReason::NotMonotonicClock)
        );
        assert_eq!(f.capture_ns, f.dequeued_ns - 40 * MS);
        source
            .filled
            .push_back(buffer(1, 1_033, SOE, frame[..100].to_vec()));
        let e = p
            .next(&mut source, Duration::from_millis(10), None)
            .unwrap_err();
        assert!(matches!(e, V4l2Error::Garbled { sequence: 1, .. }), "{e}");
        assert_eq!(p.stats().fallback_not_monotonic, 1);
    }

    #[test]
    fn mjpeg_of_another_size_than_negotiated_is_garbled() {
        let mut p = pipeline(PixelFormat::Mjpeg);
        p.negotiated.width = 32;
        let mut source = MadeUpSource {
            filled: VecDeque::from([buffer(0, 1_000, SOE, mjpeg_16x8())]),
        };
        let e = p
            .next(&mut source, Duration::from_millis(10), None)
            .unwrap_err();
        assert!(e.to_string().contains("16x8 JPEG, 32x8 negotiated"), "{e}");
    }
}
