//! Sine and cosine of a binary angle by a quarter-wave table with linear interpolation.
//!
//! The algorithm (also in `SPEC.md`, node by node, and in `rtl/kin_sincos.v`):
//!
//! 1. The angle is a [`ANGLE`] word `<+-,24,1>` in units of pi radians: raw `a` stands for
//!    `a * pi / 2^23` rad. Its top two bits are the quadrant `k`, the low 22 bits the offset
//!    `phi` inside the quadrant: `theta = k * pi/2 + phi * (pi/2) / 2^22`.
//! 2. `g(u)`, for `0 <= u <= 2^22`, approximates `sin(u * (pi/2) / 2^22)`:
//!    `i = u >> 10`, `f = u & 1023`, `g = T[i] + floor(D[i] * f / 2^10)` with the committed table
//!    `T[i] = round(sin(i * (pi/2) / 4096) * 2^28)`, `D[i] = T[i+1] - T[i]`
//!    (`rtl/sincos_table.hex`, made once by `rtl/gen_sincos_table.py` in exact decimal
//!    arithmetic). `g` is [`G`] `<+,29,1>`; the sum cannot overflow.
//! 3. `r1 = g(phi)`, `r2 = g(2^22 - phi)`, each rounded half-up from 28 to 23 fraction bits into
//!    [`SIN_COS`] `<+-,25,2>` (cannot overflow: `0 <= r <= 1`).
//! 4. Quadrant unfold: `k = 0: (sin, cos) = (r1, r2)`; `1: (r2, -r1)`; `2: (-r1, -r2)`;
//!    `3: (-r2, r1)`. Negation is exact.
//!
//! So `sin(0) = 0`, `cos(0) = 1` and `sin(pi/2) = 1` exactly, and every output is within 0.7
//! LSB (`2^-23`) of the true value of the quantized angle (tested: `tests/accuracy.rs`).
//! Cost in hardware: one dual-port ROM of 4096 x 46 bits with registered read (Yosys maps it
//! onto ten of the XC2V1000's forty 18 Kb block RAMs, as 2048 x 9 halves: `T[28]` is zero in
//! every stored row) and two 17x10 multipliers; three pipeline stages (ROM read, products,
//! interpolation and unfold).
//!
//! # Real-time
//! No allocation, no panic, constant time.

use crate::fixed::{Format, Overflow, Rounding, quantize};

/// Joint and binary angles: `<+-,24,1>` in units of pi radians (LSB `pi * 2^-23` rad).
pub const ANGLE: Format = Format::signed(24, 1);
/// Table values `T[i]`: `<+,29,1>` (LSB `2^-28`).
pub const TABLE_T: Format = Format::unsigned(29, 1);
/// Table slopes `D[i]`: `<+,17,-11>` (LSB `2^-28`).
pub const TABLE_D: Format = Format::unsigned(17, -11);
/// Interpolated quarter-wave value `g`: `<+,29,1>` (LSB `2^-28`).
pub const G: Format = Format::unsigned(29, 1);
/// Sine and cosine: `<+-,25,2>` (LSB `2^-23`).
pub const SIN_COS: Format = Format::signed(25, 2);

/// Number of table intervals in a quarter wave.
pub const TABLE_INTERVALS: usize = 4096;

/// The committed table, one `{T (29 bits), D (17 bits)}` word per line in hex, rows `0..4096`
/// (`T[4096] = 2^28`, `D[4096] = 0` are constants, not rows).
const TABLE_HEX: &[u8] = include_bytes!("../rtl/sincos_table.hex");

/// The committed quarter-wave table, parsed at compile time: `T[i]` raw words of [`TABLE_T`],
/// `i = 0..=4096`.
pub static TABLE: Table = Table::parse(TABLE_HEX);

/// The quarter-wave table: values and slopes.
#[derive(Debug)]
pub struct Table {
    /// `T[i]`, raw [`TABLE_T`] words.
    pub t: [u32; TABLE_INTERVALS + 1],
    /// `D[i] = T[i+1] - T[i]` (`D[4096] = 0`), raw [`TABLE_D`] words.
    pub d: [u32; TABLE_INTERVALS + 1],
}

impl Table {
    const fn parse(hex: &[u8]) -> Table {
        let mut t = [0u32; TABLE_INTERVALS + 1];
        let mut d = [0u32; TABLE_INTERVALS + 1];
        let (mut i, mut k, mut acc, mut digits) = (0usize, 0usize, 0u64, 0u32);
        while i <= hex.len() {
            let c = if i < hex.len() { hex[i] } else { b'\n' };
            let v = match c {
                b'0'..=b'9' => Some((c - b'0') as u64),
                b'a'..=b'f' => Some((c - b'a' + 10) as u64),
                b'A'..=b'F' => Some((c - b'A' + 10) as u64),
                _ => None,
            };
            match v {
                Some(v) => {
                    acc = (acc << 4) | v;
                    digits += 1;
                }
                None if digits > 0 => {
                    assert!(k < TABLE_INTERVALS, "sincos_table.hex: too many lines");
                    t[k] = (acc >> 17) as u32;
                    d[k] = (acc & 0x1_ffff) as u32;
                    k += 1;
                    acc = 0;
                    digits = 0;
                }
                None => {}
            }
            i += 1;
        }
        assert!(k == TABLE_INTERVALS, "sincos_table.hex: wrong line count");
        // The last point is a constant, not a ROM row (the ROM stays 4096 rows deep):
        // sin(pi/2) = 1 exactly, and no slope after it.
        t[TABLE_INTERVALS] = 1 << 28;
        d[TABLE_INTERVALS] = 0;
        Table { t, d }
    }
}

/// `g(u)`: the interpolated quarter wave, raw [`G`] word; `u` in `0..=2^22`.
#[inline(always)]
fn g(u: u32) -> i64 {
    let i = (u >> 10) as usize & 0x1fff;
    let f = (u & 0x3ff) as i128;
    let (t, d) = match (TABLE.t.get(i), TABLE.d.get(i)) {
        (Some(&t), Some(&d)) => (t as i128, d as i128),
        _ => (0, 0), // unreachable for u <= 2^22
    };
    // D * f: exact product, LSB 2^-38; truncated once to the table's LSB 2^-28.
    let step = quantize(d * f, 38, G, Rounding::Truncate, Overflow::Wrap) as i128;
    // T + step: exact, and at most T[i+1] <= 2^28, so the wrap never acts.
    quantize(t + step, 28, G, Rounding::Truncate, Overflow::Wrap)
}

/// Sine and cosine of the binary angle `angle` (raw [`ANGLE`] word; only its low 24 bits are
/// used), as raw [`SIN_COS`] words `(sin, cos)`.
///
/// ```
/// use penelope_fpga::sincos::sin_cos;
/// assert_eq!(sin_cos(0), (0, 1 << 23));          // sin 0 = 0, cos 0 = 1
/// assert_eq!(sin_cos(1 << 22), (1 << 23, 0));    // pi/2
/// assert_eq!(sin_cos(-(1 << 23)), (0, -(1 << 23))); // -pi
/// ```
///
/// # Real-time
/// No allocation, no panic, constant time.
#[inline]
pub fn sin_cos(angle: i32) -> (i32, i32) {
    let a = angle as u32 & 0x00ff_ffff;
    let quadrant = a >> 22;
    let phi = a & 0x003f_ffff;
    let out = |g: i64| quantize(g as i128, 28, SIN_COS, Rounding::HalfUp, Overflow::Wrap) as i32;
    let r1 = out(g(phi));
    let r2 = out(g((1 << 22) - phi));
    match quadrant {
        0 => (r1, r2),
        1 => (r2, -r1),
        2 => (-r1, -r2),
        _ => (-r2, r1),
    }
}

/// The nearest binary angle to `radians` (round half-even, wrapped into `[-pi, pi)`), raw
/// [`ANGLE`] word. This is the host-side input quantization (at most `pi * 2^-24` rad).
///
/// # Errors
/// [`crate::fixed::FixedError::NonFinite`] for NaN or infinity.
pub fn angle_from_radians(radians: f64) -> Result<i32, crate::fixed::FixedError> {
    // radians / pi loses at most half an ulp of the quotient, far below 2^-23.
    let x = radians / core::f64::consts::PI;
    crate::fixed::Fx::from_f64(x, ANGLE, Rounding::HalfEven, Overflow::Wrap).map(|f| f.raw() as i32)
}

/// The angle a raw [`ANGLE`] word stands for, rad.
pub fn angle_to_radians(raw: i32) -> f64 {
    raw as f64 * core::f64::consts::PI / (1u32 << 23) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_committed_table_is_a_rounded_sine() {
        for i in 0..=TABLE_INTERVALS {
            let exact = libm::sin(i as f64 * core::f64::consts::FRAC_PI_2 / 4096.0) * 268_435_456.0;
            assert!(
                (TABLE.t[i] as f64 - exact).abs() <= 0.5 + 1e-6,
                "T[{i}] = {} vs {exact}",
                TABLE.t[i]
            );
            let next = if i < TABLE_INTERVALS {
                TABLE.t[i + 1] - TABLE.t[i]
            } else {
                0
            };
            assert_eq!(TABLE.d[i], next, "D[{i}]");
            assert!(TABLE_T.contains_raw(TABLE.t[i] as i64));
            assert!(TABLE_D.contains_raw(TABLE.d[i] as i64));
        }
    }

    #[test]
    fn quadrant_edges() {
        let one = 1 << 23;
        assert_eq!(sin_cos(0), (0, one));
        assert_eq!(sin_cos(1 << 22), (one, 0));
        assert_eq!(sin_cos(-(1 << 22)), (-one, 0));
        assert_eq!(sin_cos(-(1 << 23)), (0, -one));
        // Only the low 24 bits count: +pi wraps to -pi.
        assert_eq!(sin_cos(1 << 23), sin_cos(-(1 << 23)));
        assert_eq!(angle_from_radians(core::f64::consts::PI), Ok(-(1 << 23)));
        assert_eq!(
            angle_from_radians(-core::f64::consts::FRAC_PI_2),
            Ok(-(1 << 22))
        );
        assert!(angle_from_radians(f64::NAN).is_err());
    }
}
