//! Raw YUYV (YUV 4:2:2, `Y0 U Y1 V` per two pixels) frames to RGB and to JPEG.
//!
//! Webcams send BT.601 limited range (Y 16..235, Cb/Cr 16..240), the usual for SD/HD YUYV.

use jpeg_encoder::{ColorType, Encoder, EncodingError};
use thiserror::Error;

/// Why a raw frame could not be encoded.
#[derive(Debug, Error)]
pub enum YuyvError {
    /// Odd width, zero size or more than 65535 pixels a side (JPEG's limit).
    #[error("unusable YUYV size {width}x{height}")]
    BadSize {
        /// Width, pixels.
        width: u32,
        /// Height, pixels.
        height: u32,
    },
    /// The buffer holds fewer bytes than the size needs (a short frame).
    #[error("YUYV frame of {got} bytes, {needed} needed for its size")]
    Short {
        /// Bytes in the buffer.
        got: usize,
        /// Bytes the size needs.
        needed: usize,
    },
    /// The encoder failed.
    #[error("JPEG encoder: {0}")]
    Encoder(#[from] EncodingError),
}

/// One BT.601 limited-range YCbCr sample as RGB (integer arithmetic, 8 fractional bits).
pub fn ycbcr_to_rgb(y: u8, cb: u8, cr: u8) -> [u8; 3] {
    let c = (i32::from(y) - 16) * 298;
    let d = i32::from(cb) - 128;
    let e = i32::from(cr) - 128;
    let clamp = |v: i32| ((v + 128) >> 8).clamp(0, 255) as u8;
    [
        clamp(c + 409 * e),
        clamp(c - 100 * d - 208 * e),
        clamp(c + 516 * d),
    ]
}

/// Converts a YUYV frame of `width` x `height` with `stride` bytes a line into `rgb` (cleared
/// and refilled, so that a camera reuses one buffer).
pub fn yuyv_to_rgb(
    yuyv: &[u8],
    width: u32,
    height: u32,
    stride: u32,
    rgb: &mut Vec<u8>,
) -> Result<(), YuyvError> {
    if width == 0 || height == 0 || !width.is_multiple_of(2) || width > 65535 || height > 65535 {
        return Err(YuyvError::BadSize { width, height });
    }
    let (w, h) = (width as usize, height as usize);
    let stride = (stride as usize).max(w * 2);
    let needed = stride * (h - 1) + w * 2;
    if yuyv.len() < needed {
        return Err(YuyvError::Short {
            got: yuyv.len(),
            needed,
        });
    }
    rgb.clear();
    rgb.reserve(w * h * 3);
    for line in 0..h {
        let row = &yuyv[line * stride..line * stride + w * 2];
        for quad in row.chunks_exact(4) {
            let (y0, cb, y1, cr) = (quad[0], quad[1], quad[2], quad[3]);
            rgb.extend_from_slice(&ycbcr_to_rgb(y0, cb, cr));
            rgb.extend_from_slice(&ycbcr_to_rgb(y1, cb, cr));
        }
    }
    Ok(())
}

/// Encodes an RGB image (3 bytes a pixel) as a baseline JPEG of `quality` (1..=100).
pub fn encode_rgb_jpeg(
    rgb: &[u8],
    width: u32,
    height: u32,
    quality: u8,
) -> Result<Vec<u8>, YuyvError> {
    if width == 0 || height == 0 || width > 65535 || height > 65535 {
        return Err(YuyvError::BadSize { width, height });
    }
    let needed = width as usize * height as usize * 3;
    if rgb.len() < needed {
        return Err(YuyvError::Short {
            got: rgb.len(),
            needed,
        });
    }
    let mut jpeg = Vec::with_capacity(needed / 8);
    Encoder::new(&mut jpeg, quality.clamp(1, 100)).encode(
        &rgb[..needed],
        width as u16,
        height as u16,
        ColorType::Rgb,
    )?;
    Ok(jpeg)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limited_range_black_white_and_red_convert_to_rgb() {
        assert_eq!(ycbcr_to_rgb(16, 128, 128), [0, 0, 0]);
        assert_eq!(ycbcr_to_rgb(235, 128, 128), [255, 255, 255]);
        // BT.601 red (255, 0, 0) is Y 81, Cb 90, Cr 240
        let [r, g, b] = ycbcr_to_rgb(81, 90, 240);
        assert!(r >= 253 && g <= 2 && b <= 2, "{r} {g} {b}");
    }

    #[test]
    fn yuyv_frame_with_stride_padding_converts_pixel_by_pixel() {
        // 4x2: left half white, right half black; 4 bytes of padding a line
        let line = [235, 128, 235, 128, 16, 128, 16, 128, 0xAA, 0xAA, 0xAA, 0xAA];
        let frame = [line, line].concat();
        let mut rgb = vec![1, 2, 3];
        yuyv_to_rgb(&frame, 4, 2, 12, &mut rgb).unwrap();
        assert_eq!(rgb.len(), 4 * 2 * 3);
        for row in rgb.chunks(12) {
            assert_eq!(&row[..6], &[255; 6]);
            assert_eq!(&row[6..], &[0; 6]);
        }
    }

    #[test]
    fn short_or_odd_yuyv_frames_are_errors() {
        let mut rgb = Vec::new();
        assert!(matches!(
            yuyv_to_rgb(&[0; 15], 4, 2, 8, &mut rgb),
            Err(YuyvError::Short {
                got: 15,
                needed: 16
            })
        ));
        assert!(matches!(
            yuyv_to_rgb(&[0; 64], 3, 2, 0, &mut rgb),
            Err(YuyvError::BadSize { .. })
        ));
    }

    #[test]
    fn yuyv_frame_encodes_to_a_jpeg_of_its_size() {
        let (w, h) = (32u32, 16u32);
        // a horizontal luma ramp, neutral chroma
        let mut frame = Vec::new();
        for _ in 0..h {
            for x in (0..w).step_by(2) {
                frame.extend_from_slice(&[16 + (x * 6) as u8, 128, 16 + (x * 6 + 6) as u8, 128]);
            }
        }
        let mut rgb = Vec::new();
        yuyv_to_rgb(&frame, w, h, w * 2, &mut rgb).unwrap();
        let jpeg = encode_rgb_jpeg(&rgb, w, h, 90).unwrap();
        let mut d = zune_jpeg::JpegDecoder::new(&jpeg);
        let pixels = d.decode().unwrap();
        assert_eq!(d.dimensions(), Some((32, 16)));
        // dark on the left, bright on the right
        let row = 8 * 32 * 3;
        assert!(pixels[row] < 40, "{}", pixels[row]);
        assert!(pixels[row + 31 * 3] > 180, "{}", pixels[row + 31 * 3]);
    }
}
