//! MJPEG buffers checked cheaply and made into JPEG files a browser shows: start and end markers
//! present, the header's segments well formed up to the scan, and the standard Huffman tables
//! (ITU T.81 Annex K.3) inserted when the camera left them out, as UVC cameras commonly do (the
//! AVI1 MJPEG convention; every MJPEG player inserts them the same way).

use thiserror::Error;

/// Why a buffer is not a JPEG image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Error)]
pub enum MjpegError {
    /// It does not start with the start-of-image marker (FFD8).
    #[error("no start-of-image marker")]
    NoStartOfImage,
    /// It does not end with the end-of-image marker (FFD9), after any zero padding.
    #[error("no end-of-image marker (truncated frame)")]
    NoEndOfImage,
    /// A header segment is malformed or runs past the buffer before the scan.
    #[error("malformed header segment at byte {0}")]
    BadSegment(usize),
    /// The header has no start-of-frame (SOF) or no start-of-scan (SOS).
    #[error("no frame or scan header")]
    NoScan,
}

/// An MJPEG buffer as a JPEG file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct JpegFrame {
    /// The file's bytes.
    pub bytes: Vec<u8>,
    /// Width and height from the frame header.
    pub size: (u32, u32),
    /// Whether the standard Huffman tables were inserted.
    pub tables_inserted: bool,
}

const SOI: u8 = 0xD8;
const EOI: u8 = 0xD9;
const SOS: u8 = 0xDA;
const DHT: u8 = 0xC4;

/// Checks an MJPEG buffer and returns it as a JPEG file, with the standard Huffman tables
/// inserted before the scan when it has none. Trailing zero padding (some drivers report the
/// whole buffer as used) is cut.
pub fn mjpeg_to_jpeg(buffer: &[u8]) -> Result<JpegFrame, MjpegError> {
    if buffer.len() < 4 || buffer[0] != 0xFF || buffer[1] != SOI {
        return Err(MjpegError::NoStartOfImage);
    }
    let end = buffer.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1);
    if end < 4 || buffer[end - 2] != 0xFF || buffer[end - 1] != EOI {
        return Err(MjpegError::NoEndOfImage);
    }
    let data = &buffer[..end];
    // Walk the header's segments (marker, 2-byte length) up to the scan.
    let mut at = 2;
    let mut has_tables = false;
    let mut size = None;
    let sos_at = loop {
        if at + 4 > data.len() || data[at] != 0xFF {
            return Err(MjpegError::BadSegment(at));
        }
        let marker = data[at + 1];
        if marker == 0xFF {
            at += 1; // fill byte
            continue;
        }
        let len = usize::from(u16::from_be_bytes([data[at + 2], data[at + 3]]));
        if len < 2 || at + 2 + len > data.len() {
            return Err(MjpegError::BadSegment(at));
        }
        match marker {
            SOS => break at,
            DHT => has_tables = true,
            // SOF0..SOF15 less DHT (C4), JPG (C8) and DAC (CC): height, width after precision
            0xC0..=0xCF if marker != 0xC8 && marker != 0xCC => {
                if len < 7 {
                    return Err(MjpegError::BadSegment(at));
                }
                let h = u16::from_be_bytes([data[at + 5], data[at + 6]]);
                let w = u16::from_be_bytes([data[at + 7], data[at + 8]]);
                size = Some((u32::from(w), u32::from(h)));
            }
            EOI => return Err(MjpegError::NoScan),
            _ => {}
        }
        at += 2 + len;
    };
    let size = size.ok_or(MjpegError::NoScan)?;
    if has_tables {
        return Ok(JpegFrame {
            bytes: data.to_vec(),
            size,
            tables_inserted: false,
        });
    }
    let dht = standard_dht_segment();
    let mut bytes = Vec::with_capacity(data.len() + dht.len());
    bytes.extend_from_slice(&data[..sos_at]);
    bytes.extend_from_slice(&dht);
    bytes.extend_from_slice(&data[sos_at..]);
    Ok(JpegFrame {
        bytes,
        size,
        tables_inserted: true,
    })
}

/// One Huffman table of ITU T.81 Annex K.3: class and id (`Tc << 4 | Th`), the number of codes
/// of each length 1..=16, and the symbols.
struct HuffmanTable {
    class_id: u8,
    counts: [u8; 16],
    symbols: &'static [u8],
}

/// The four standard tables: luminance DC, chrominance DC, luminance AC, chrominance AC.
const STANDARD_TABLES: [HuffmanTable; 4] = [
    HuffmanTable {
        class_id: 0x00,
        counts: [0, 1, 5, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0],
        symbols: &[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11],
    },
    HuffmanTable {
        class_id: 0x01,
        counts: [0, 3, 1, 1, 1, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0],
        symbols: &[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11],
    },
    HuffmanTable {
        class_id: 0x10,
        counts: [0, 2, 1, 3, 3, 2, 4, 3, 5, 5, 4, 4, 0, 0, 1, 0x7d],
        symbols: &[
            0x01, 0x02, 0x03, 0x00, 0x04, 0x11, 0x05, 0x12, 0x21, 0x31, 0x41, 0x06, 0x13, 0x51,
            0x61, 0x07, 0x22, 0x71, 0x14, 0x32, 0x81, 0x91, 0xa1, 0x08, 0x23, 0x42, 0xb1, 0xc1,
            0x15, 0x52, 0xd1, 0xf0, 0x24, 0x33, 0x62, 0x72, 0x82, 0x09, 0x0a, 0x16, 0x17, 0x18,
            0x19, 0x1a, 0x25, 0x26, 0x27, 0x28, 0x29, 0x2a, 0x34, 0x35, 0x36, 0x37, 0x38, 0x39,
            0x3a, 0x43, 0x44, 0x45, 0x46, 0x47, 0x48, 0x49, 0x4a, 0x53, 0x54, 0x55, 0x56, 0x57,
            0x58, 0x59, 0x5a, 0x63, 0x64, 0x65, 0x66, 0x67, 0x68, 0x69, 0x6a, 0x73, 0x74, 0x75,
            0x76, 0x77, 0x78, 0x79, 0x7a, 0x83, 0x84, 0x85, 0x86, 0x87, 0x88, 0x89, 0x8a, 0x92,
            0x93, 0x94, 0x95, 0x96, 0x97, 0x98, 0x99, 0x9a, 0xa2, 0xa3, 0xa4, 0xa5, 0xa6, 0xa7,
            0xa8, 0xa9, 0xaa, 0xb2, 0xb3, 0xb4, 0xb5, 0xb6, 0xb7, 0xb8, 0xb9, 0xba, 0xc2, 0xc3,
            0xc4, 0xc5, 0xc6, 0xc7, 0xc8, 0xc9, 0xca, 0xd2, 0xd3, 0xd4, 0xd5, 0xd6, 0xd7, 0xd8,
            0xd9, 0xda, 0xe1, 0xe2, 0xe3, 0xe4, 0xe5, 0xe6, 0xe7, 0xe8, 0xe9, 0xea, 0xf1, 0xf2,
            0xf3, 0xf4, 0xf5, 0xf6, 0xf7, 0xf8, 0xf9, 0xfa,
        ],
    },
    HuffmanTable {
        class_id: 0x11,
        counts: [0, 2, 1, 2, 4, 4, 3, 4, 7, 5, 4, 4, 0, 1, 2, 0x77],
        symbols: &[
            0x00, 0x01, 0x02, 0x03, 0x11, 0x04, 0x05, 0x21, 0x31, 0x06, 0x12, 0x41, 0x51, 0x07,
            0x61, 0x71, 0x13, 0x22, 0x32, 0x81, 0x08, 0x14, 0x42, 0x91, 0xa1, 0xb1, 0xc1, 0x09,
            0x23, 0x33, 0x52, 0xf0, 0x15, 0x62, 0x72, 0xd1, 0x0a, 0x16, 0x24, 0x34, 0xe1, 0x25,
            0xf1, 0x17, 0x18, 0x19, 0x1a, 0x26, 0x27, 0x28, 0x29, 0x2a, 0x35, 0x36, 0x37, 0x38,
            0x39, 0x3a, 0x43, 0x44, 0x45, 0x46, 0x47, 0x48, 0x49, 0x4a, 0x53, 0x54, 0x55, 0x56,
            0x57, 0x58, 0x59, 0x5a, 0x63, 0x64, 0x65, 0x66, 0x67, 0x68, 0x69, 0x6a, 0x73, 0x74,
            0x75, 0x76, 0x77, 0x78, 0x79, 0x7a, 0x82, 0x83, 0x84, 0x85, 0x86, 0x87, 0x88, 0x89,
            0x8a, 0x92, 0x93, 0x94, 0x95, 0x96, 0x97, 0x98, 0x99, 0x9a, 0xa2, 0xa3, 0xa4, 0xa5,
            0xa6, 0xa7, 0xa8, 0xa9, 0xaa, 0xb2, 0xb3, 0xb4, 0xb5, 0xb6, 0xb7, 0xb8, 0xb9, 0xba,
            0xc2, 0xc3, 0xc4, 0xc5, 0xc6, 0xc7, 0xc8, 0xc9, 0xca, 0xd2, 0xd3, 0xd4, 0xd5, 0xd6,
            0xd7, 0xd8, 0xd9, 0xda, 0xe2, 0xe3, 0xe4, 0xe5, 0xe6, 0xe7, 0xe8, 0xe9, 0xea, 0xf2,
            0xf3, 0xf4, 0xf5, 0xf6, 0xf7, 0xf8, 0xf9, 0xfa,
        ],
    },
];

/// The DHT segment (marker, length, the four standard tables): 420 bytes.
pub fn standard_dht_segment() -> Vec<u8> {
    let body: usize = STANDARD_TABLES
        .iter()
        .map(|t| 1 + 16 + t.symbols.len())
        .sum();
    let mut seg = Vec::with_capacity(4 + body);
    seg.extend_from_slice(&[0xFF, DHT]);
    seg.extend_from_slice(&((2 + body) as u16).to_be_bytes());
    for t in &STANDARD_TABLES {
        seg.push(t.class_id);
        seg.extend_from_slice(&t.counts);
        seg.extend_from_slice(t.symbols);
    }
    seg
}

#[cfg(test)]
mod tests {
    use super::*;
    use jpeg_encoder::{ColorType, Encoder};

    /// A 64x48 gradient, JPEG-encoded with the standard tables (the encoder's default).
    fn encoded() -> (Vec<u8>, Vec<u8>) {
        let (w, h) = (64usize, 48usize);
        let mut rgb = Vec::with_capacity(w * h * 3);
        for y in 0..h {
            for x in 0..w {
                rgb.extend_from_slice(&[(x * 4) as u8, (y * 5) as u8, ((x + y) * 2) as u8]);
            }
        }
        let mut jpeg = Vec::new();
        Encoder::new(&mut jpeg, 85)
            .encode(&rgb, w as u16, h as u16, ColorType::Rgb)
            .unwrap();
        (jpeg, rgb)
    }

    /// The same file with every DHT segment cut out, as a UVC camera sends it.
    fn without_tables(jpeg: &[u8]) -> Vec<u8> {
        let mut out = jpeg[..2].to_vec();
        let mut at = 2;
        loop {
            let marker = jpeg[at + 1];
            let len = usize::from(u16::from_be_bytes([jpeg[at + 2], jpeg[at + 3]]));
            if marker == SOS {
                out.extend_from_slice(&jpeg[at..]);
                return out;
            }
            if marker != DHT {
                out.extend_from_slice(&jpeg[at..at + 2 + len]);
            }
            at += 2 + len;
        }
    }

    fn decode(jpeg: &[u8]) -> (Vec<u8>, (usize, usize)) {
        let mut d = zune_jpeg::JpegDecoder::new(jpeg);
        let pixels = d.decode().expect("decodes");
        (pixels, d.dimensions().unwrap())
    }

    fn has_marker_before_scan(jpeg: &[u8], wanted: u8) -> bool {
        let mut at = 2;
        while jpeg[at + 1] != SOS {
            if jpeg[at + 1] == wanted {
                return true;
            }
            at += 2 + usize::from(u16::from_be_bytes([jpeg[at + 2], jpeg[at + 3]]));
        }
        false
    }

    #[test]
    fn standard_tables_have_as_many_symbols_as_their_counts_and_420_bytes() {
        for t in &STANDARD_TABLES {
            let n: usize = t.counts.iter().map(|&c| usize::from(c)).sum();
            assert_eq!(n, t.symbols.len(), "table {:#x}", t.class_id);
        }
        let seg = standard_dht_segment();
        assert_eq!(seg.len(), 420);
        assert_eq!(usize::from(u16::from_be_bytes([seg[2], seg[3]])), 418);
    }

    #[test]
    fn mjpeg_without_huffman_tables_gets_the_standard_ones_and_decodes_as_the_original() {
        let (jpeg, _) = encoded();
        assert!(has_marker_before_scan(&jpeg, DHT));
        let stripped = without_tables(&jpeg);
        assert!(!has_marker_before_scan(&stripped, DHT));
        let frame = mjpeg_to_jpeg(&stripped).unwrap();
        assert!(frame.tables_inserted);
        assert_eq!(frame.size, (64, 48));
        assert!(has_marker_before_scan(&frame.bytes, DHT));
        assert_eq!(frame.bytes.len(), stripped.len() + 420);
        // The inserted tables are the ones the encoder coded with: the same pixels come out.
        let (original, dims) = decode(&jpeg);
        let (repaired, repaired_dims) = decode(&frame.bytes);
        assert_eq!(dims, (64, 48));
        assert_eq!(repaired_dims, dims);
        assert_eq!(repaired, original);
    }

    #[test]
    fn mjpeg_with_tables_passes_through_and_zero_padding_is_cut() {
        let (jpeg, _) = encoded();
        let mut padded = jpeg.clone();
        padded.extend_from_slice(&[0; 100]);
        let frame = mjpeg_to_jpeg(&padded).unwrap();
        assert!(!frame.tables_inserted);
        assert_eq!(frame.bytes, jpeg);
    }

    #[test]
    fn truncated_or_foreign_buffers_are_garbled() {
        let (jpeg, _) = encoded();
        assert_eq!(
            mjpeg_to_jpeg(&jpeg[..jpeg.len() / 2]),
            Err(MjpegError::NoEndOfImage)
        );
        assert_eq!(mjpeg_to_jpeg(&jpeg[2..]), Err(MjpegError::NoStartOfImage));
        assert_eq!(mjpeg_to_jpeg(&[]), Err(MjpegError::NoStartOfImage));
        // a segment length running past the buffer
        let mut bad = jpeg.clone();
        bad[4] = 0xFF;
        bad[5] = 0xFF;
        assert!(matches!(
            mjpeg_to_jpeg(&bad),
            Err(MjpegError::BadSegment(_))
        ));
        // markers but no scan
        assert_eq!(
            mjpeg_to_jpeg(&[0xFF, 0xD8, 0xFF, 0xD9]),
            Err(MjpegError::BadSegment(2))
        );
    }
}
