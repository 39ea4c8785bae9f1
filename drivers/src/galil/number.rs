//! Tolerant parsing of the numbers in Galil replies.
//!
//! Galil prints multi-axis values separated by `, ` (or `,` alone when a value fills its field),
//! with leading spaces, with leading zeros under `LZ0` (`-0000000009`), as integers or with four
//! decimals (`MG` always, other queries on some firmware). Lines end with `\r\n`. This module
//! accepts all of those and nothing else: no exponents, no hexadecimal, no empty fields.
//!
//! # Real-time
//! No allocation, no locks; time linear in the input.

use super::error::{GalilError, Malformed};

/// Parses one number: optional surrounding whitespace, optional sign, digits with an optional
/// decimal point (`12`, `-0000000009`, ` 1000.0000`, `.5`).
///
/// # Errors
/// [`Malformed::BadNumber`] for anything else (empty, two signs, letters, exponents).
pub fn parse_number(field: &[u8]) -> Result<f64, GalilError> {
    let bad = GalilError::Malformed(Malformed::BadNumber);
    let field = trim(field);
    let digits = match field.first() {
        Some(b'-' | b'+') => &field[1..],
        _ => field,
    };
    let mut seen_digit = false;
    let mut seen_point = false;
    for &b in digits {
        match b {
            b'0'..=b'9' => seen_digit = true,
            b'.' if !seen_point => seen_point = true,
            _ => return Err(bad),
        }
    }
    if !seen_digit {
        return Err(bad);
    }
    // Only ASCII digits, one sign and one point remain: valid UTF-8 and a valid f64 literal.
    let text = core::str::from_utf8(field).map_err(|_| bad.clone())?;
    text.parse::<f64>().map_err(|_| bad)
}

/// Parses a reply holding comma-separated numbers (possibly over several `\r\n`-separated lines,
/// which count as separators too) into `out`, and returns how many there were.
///
/// # Errors
/// [`Malformed::BadNumber`] when a field is not a number (an empty reply gives zero values, not
/// an error); [`Malformed::WrongCount`] when there are more values than `out` holds.
pub fn parse_numbers(payload: &[u8], out: &mut [f64]) -> Result<usize, GalilError> {
    let payload = trim(payload);
    if payload.is_empty() {
        return Ok(0);
    }
    let mut count = 0;
    for field in payload.split(|&b| b == b',' || b == b'\n') {
        let slot = out
            .get_mut(count)
            .ok_or(GalilError::Malformed(Malformed::WrongCount))?;
        *slot = parse_number(field)?;
        count += 1;
    }
    Ok(count)
}

/// Parses exactly `out.len()` numbers.
///
/// # Errors
/// As [`parse_numbers`], and [`Malformed::WrongCount`] when there are fewer values.
pub fn parse_exact(payload: &[u8], out: &mut [f64]) -> Result<(), GalilError> {
    let n = parse_numbers(payload, out)?;
    if n == out.len() {
        Ok(())
    } else {
        Err(GalilError::Malformed(Malformed::WrongCount))
    }
}

/// Converts a parsed value to encoder counts (rounded to the nearest integer).
///
/// # Errors
/// [`Malformed::BadNumber`] when the value is not finite or beyond Galil's 32-bit range.
pub fn to_counts(value: f64) -> Result<i64, GalilError> {
    if value.is_finite() && value.abs() <= 2_147_483_648.0 {
        // Rounding half away from zero, without std: the range check above keeps the cast exact.
        let r = if value >= 0.0 {
            (value + 0.5) as i64
        } else {
            -((-value + 0.5) as i64)
        };
        Ok(r)
    } else {
        Err(GalilError::Malformed(Malformed::BadNumber))
    }
}

/// The slice without leading and trailing ASCII whitespace (space, tab, CR, LF).
pub(crate) fn trim(mut s: &[u8]) -> &[u8] {
    while let [first, rest @ ..] = s {
        if first.is_ascii_whitespace() {
            s = rest;
        } else {
            break;
        }
    }
    while let [rest @ .., last] = s {
        if last.is_ascii_whitespace() {
            s = rest;
        } else {
            break;
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_format_galil_prints() {
        assert_eq!(parse_number(b" 1000").unwrap(), 1000.0);
        assert_eq!(parse_number(b"-0000000009").unwrap(), -9.0);
        assert_eq!(parse_number(b" 0000001000").unwrap(), 1000.0);
        assert_eq!(parse_number(b" 1000.0000").unwrap(), 1000.0);
        assert_eq!(parse_number(b"-2.5000\r\n").unwrap(), -2.5);
        assert_eq!(parse_number(b".5").unwrap(), 0.5);
        assert_eq!(parse_number(b"+7").unwrap(), 7.0);
    }

    #[test]
    fn garbage_is_refused() {
        for bad in [
            &b""[..],
            b" ",
            b"-",
            b"1e5",
            b"1.2.3",
            b"--1",
            b"0x10",
            b"1 2",
            b"$FF",
        ] {
            assert!(parse_number(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn lists_in_lz0_and_lz1() {
        let mut out = [0.0; 8];
        let n = parse_numbers(b" 0000001000,-0000000009, 0000000000\r\n", &mut out).unwrap();
        assert_eq!(&out[..n], &[1000.0, -9.0, 0.0]);
        let n = parse_numbers(b" 1000, -9, 0\r\n", &mut out).unwrap();
        assert_eq!(&out[..n], &[1000.0, -9.0, 0.0]);
        assert_eq!(parse_numbers(b"\r\n", &mut out).unwrap(), 0);
        assert!(parse_numbers(b"1,,2", &mut out).is_err());
        let mut two = [0.0; 2];
        assert_eq!(
            parse_numbers(b"1,2,3", &mut two),
            Err(GalilError::Malformed(Malformed::WrongCount))
        );
        assert!(parse_exact(b"1", &mut two).is_err());
    }

    #[test]
    fn counts_round_half_away_from_zero() {
        assert_eq!(to_counts(2.5).unwrap(), 3);
        assert_eq!(to_counts(-2.5).unwrap(), -3);
        assert_eq!(to_counts(-0.4).unwrap(), 0);
        assert!(to_counts(f64::NAN).is_err());
        assert!(to_counts(1e12).is_err());
    }
}
