//! Fixed-point numbers with LabVIEW FPGA semantics.
//!
//! A [`Format`] `<sign, WL, IWL>` holds a word length `WL` (1..=64 bits) and an integer word
//! length `IWL` (sign bit included, -64..=64; it may exceed `WL` or be negative). A word's value is
//! `raw * 2^(IWL - WL)`: the LSB is `2^(IWL - WL)`.
//!
//! Every operation computes the **exact** result first (no intermediate is ever rounded or
//! wrapped), then quantizes it once into the output format the caller names, with the caller's
//! [`Rounding`] and then [`Overflow`] rule. Nothing is implied: there is no default format, no
//! default rounding and no hidden growth.
//!
//! - [`Rounding::Truncate`]: toward minus infinity (floor), LabVIEW's "truncate".
//! - [`Rounding::HalfUp`]: add half an LSB, then floor (ties go toward plus infinity).
//! - [`Rounding::HalfEven`]: to nearest, ties to the even output word.
//! - [`Overflow::Wrap`]: keep the low `WL` bits (two's complement for signed formats).
//! - [`Overflow::Saturate`]: clamp to the format's range.
//!
//! [`quantize`] is the one primitive; [`Fx`] wraps it into arithmetic on tagged words.
//!
//! # Real-time
//! Nothing here allocates, locks or panics; every function runs in bounded time.

use core::cmp::Ordering;
use core::fmt;

use crate::wide::I256;

/// Why a fixed-point format or word was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FixedError {
    /// Word length outside 1..=64 bits.
    WordLength(u32),
    /// Integer word length outside -64..=64 bits.
    IntegerWordLength(i32),
    /// A raw word outside its format's range.
    RawOutOfRange,
    /// A NaN or infinite float was converted.
    NonFinite,
}

impl fmt::Display for FixedError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FixedError::WordLength(wl) => write!(f, "word length {wl} is outside 1..=64"),
            FixedError::IntegerWordLength(iwl) => {
                write!(f, "integer word length {iwl} is outside -64..=64")
            }
            FixedError::RawOutOfRange => f.write_str("raw word outside its format's range"),
            FixedError::NonFinite => f.write_str("NaN or infinite value"),
        }
    }
}

impl core::error::Error for FixedError {}

/// What happens to bits below the output LSB.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Rounding {
    /// Floor (toward minus infinity). Free in hardware.
    Truncate,
    /// Add half an LSB, then floor. One adder.
    HalfUp,
    /// Nearest; exact ties go to the even word (LabVIEW's default).
    HalfEven,
}

/// What happens to values outside the output range.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Overflow {
    /// Keep the low `WL` bits (two's-complement wrap). No logic.
    Wrap,
    /// Clamp to the nearest representable value.
    Saturate,
}

/// A fixed-point format `<sign, WL, IWL>`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Format {
    signed: bool,
    wl: u8,
    iwl: i8,
}

impl Format {
    /// A format; `signed` is two's complement.
    ///
    /// # Errors
    /// [`FixedError::WordLength`] unless `1 <= wl <= 64`; [`FixedError::IntegerWordLength`]
    /// unless `-64 <= iwl <= 64`.
    pub const fn new(signed: bool, wl: u32, iwl: i32) -> Result<Format, FixedError> {
        if wl < 1 || wl > 64 {
            return Err(FixedError::WordLength(wl));
        }
        if iwl < -64 || iwl > 64 {
            return Err(FixedError::IntegerWordLength(iwl));
        }
        Ok(Format {
            signed,
            wl: wl as u8,
            iwl: iwl as i8,
        })
    }

    /// A signed format `<+-, wl, iwl>` known at compile time.
    ///
    /// # Panics
    /// On an invalid format; use it in `const` items, where that is a build error, and
    /// [`Format::new`] for formats that come from data.
    pub const fn signed(wl: u32, iwl: i32) -> Format {
        match Format::new(true, wl, iwl) {
            Ok(f) => f,
            Err(_) => panic!("invalid fixed-point format"),
        }
    }

    /// An unsigned format `<+, wl, iwl>` known at compile time.
    ///
    /// # Panics
    /// As [`Format::signed`].
    pub const fn unsigned(wl: u32, iwl: i32) -> Format {
        match Format::new(false, wl, iwl) {
            Ok(f) => f,
            Err(_) => panic!("invalid fixed-point format"),
        }
    }

    /// True for two's-complement formats.
    pub const fn is_signed(self) -> bool {
        self.signed
    }

    /// Word length, bits.
    pub const fn word_length(self) -> u32 {
        self.wl as u32
    }

    /// Integer word length, bits (sign included).
    pub const fn integer_word_length(self) -> i32 {
        self.iwl as i32
    }

    /// Fraction bits `WL - IWL`: the LSB is `2^-frac_bits()`.
    pub const fn frac_bits(self) -> i32 {
        self.wl as i32 - self.iwl as i32
    }

    /// The smallest raw word.
    pub const fn min_raw(self) -> i64 {
        if self.signed {
            (-1i64) << (self.wl - 1)
        } else {
            0
        }
    }

    /// The largest raw word (for unsigned 64-bit words, `i64` cannot hold it: see
    /// [`max_raw_i128`](Format::max_raw_i128)).
    pub const fn max_raw_i128(self) -> i128 {
        if self.signed {
            (1i128 << (self.wl - 1)) - 1
        } else {
            (1i128 << self.wl) - 1
        }
    }

    /// The LSB as a float.
    pub fn lsb(self) -> f64 {
        libm::exp2(-(self.frac_bits() as f64))
    }

    /// True when `raw` is a word of this format. Unsigned words are stored in `i64` as their bit
    /// pattern, so an unsigned 64-bit word with the top bit set reads negative.
    pub const fn contains_raw(self, raw: i64) -> bool {
        if !self.signed && self.wl == 64 {
            return true;
        }
        let r = raw as i128;
        r >= self.min_raw() as i128 && r <= self.max_raw_i128()
    }

    /// The mathematical integer a raw word stands for (unsigned 64-bit words reinterpreted).
    pub const fn raw_value(self, raw: i64) -> i128 {
        if !self.signed && self.wl == 64 {
            raw as u64 as i128
        } else {
            raw as i128
        }
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = if self.signed { "+-" } else { "+" };
        write!(f, "<{s},{},{}>", self.wl, self.iwl)
    }
}

/// Quantizes the exact value `v * 2^-frac` into `out`: rounding first, then overflow.
///
/// The result is the raw word (unsigned 64-bit words as their bit pattern). Any `frac` is
/// accepted; the computation is exact for every `i128` input.
///
/// # Real-time
/// No allocation, no panic, bounded time.
#[inline]
pub fn quantize(v: i128, frac: i32, out: Format, rounding: Rounding, overflow: Overflow) -> i64 {
    // The fast path: the rounded value fits in an i128 and shifts are in range.
    let d = frac - out.frac_bits();
    if (0..=126).contains(&d) {
        let q = round_shift_i128(v, d as u32, rounding);
        return overflow_i128(q, out, overflow);
    }
    if (-63..0).contains(&d) {
        let s = (-d) as u32;
        // Exact when no significant bit is shifted out of the i128.
        if v.unsigned_abs() < (1u128 << (126 - s)) {
            return overflow_i128(v << s, out, overflow);
        }
    }
    quantize_wide(I256::from_i128(v), frac, out, rounding, overflow)
}

/// `v * 2^-d` rounded to an integer; `d <= 126`.
#[inline(always)]
fn round_shift_i128(v: i128, d: u32, rounding: Rounding) -> i128 {
    if d == 0 {
        return v;
    }
    let q = v >> d;
    match rounding {
        Rounding::Truncate => q,
        Rounding::HalfUp => q + ((v >> (d - 1)) & 1),
        Rounding::HalfEven => {
            let half = (v >> (d - 1)) & 1 == 1;
            let sticky = v & ((1i128 << (d - 1)) - 1) != 0;
            if half && (sticky || q & 1 == 1) {
                q + 1
            } else {
                q
            }
        }
    }
}

#[inline(always)]
fn overflow_i128(q: i128, out: Format, overflow: Overflow) -> i64 {
    let wl = out.word_length();
    match overflow {
        Overflow::Wrap => {
            let sh = 128 - wl;
            if out.is_signed() {
                ((q << sh) >> sh) as i64
            } else {
                (((q as u128) << sh) >> sh) as i64
            }
        }
        Overflow::Saturate => q.clamp(out.min_raw() as i128, out.max_raw_i128()) as i64,
    }
}

/// The general path of [`quantize`] over a 256-bit exact value.
pub(crate) fn quantize_wide(
    v: I256,
    frac: i32,
    out: Format,
    rounding: Rounding,
    overflow: Overflow,
) -> i64 {
    let d = frac - out.frac_bits();
    // `q` is the rounded value on the output grid; `lost` says the left shift dropped bits.
    let (q, lost) = if d > 0 {
        let d = d as u32;
        let q = v.sar(d);
        let half = v.bit(d - 1);
        let round_up = match rounding {
            Rounding::Truncate => false,
            Rounding::HalfUp => half,
            Rounding::HalfEven => half && (v.any_low_bits(d - 1) || q.bit(0)),
        };
        (
            if round_up {
                q.wrapping_add(I256::ONE)
            } else {
                q
            },
            false,
        )
    } else {
        let s = (-d) as u32;
        let q = v.wrapping_shl(s);
        let lost = s > 0 && (s >= 256 || q.sar(s) != v);
        (q, lost && !v.is_zero())
    };
    match overflow {
        Overflow::Wrap => {
            let wl = out.word_length();
            let bits = q.low_u64();
            if wl == 64 {
                bits as i64
            } else if out.is_signed() {
                let sh = 64 - wl;
                ((bits << sh) as i64) >> sh
            } else {
                (bits & ((1u64 << wl) - 1)) as i64
            }
        }
        Overflow::Saturate => {
            let (lo, hi) = (out.min_raw() as i128, out.max_raw_i128());
            let clamped = if lost {
                if v.is_negative() { lo } else { hi }
            } else if q.cmp_i128(lo) == Ordering::Less {
                lo
            } else if q.cmp_i128(hi) == Ordering::Greater {
                hi
            } else {
                q.to_i128().unwrap_or(0)
            };
            clamped as i64
        }
    }
}

/// A fixed-point word tagged with its format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Fx {
    raw: i64,
    format: Format,
}

impl Fx {
    /// A word from its raw bits.
    ///
    /// # Errors
    /// [`FixedError::RawOutOfRange`] when `raw` is not a word of `format`.
    pub const fn from_raw(raw: i64, format: Format) -> Result<Fx, FixedError> {
        if format.contains_raw(raw) {
            Ok(Fx { raw, format })
        } else {
            Err(FixedError::RawOutOfRange)
        }
    }

    /// The nearest word to a float under `rounding` and `overflow` (the float is exact in
    /// binary, so this is an exact quantization of its value).
    ///
    /// # Errors
    /// [`FixedError::NonFinite`] for NaN or infinity.
    pub fn from_f64(
        x: f64,
        format: Format,
        rounding: Rounding,
        overflow: Overflow,
    ) -> Result<Fx, FixedError> {
        if !x.is_finite() {
            return Err(FixedError::NonFinite);
        }
        // x = m * 2^e exactly, |m| < 2^53.
        let bits = x.to_bits();
        let exp = ((bits >> 52) & 0x7ff) as i32;
        let mant = (bits & ((1u64 << 52) - 1)) as i128;
        let (m, e) = if exp == 0 {
            (mant, -1074)
        } else {
            (mant | (1i128 << 52), exp - 1075)
        };
        let m = if x.is_sign_negative() { -m } else { m };
        let raw = if e > 64 {
            // Far beyond any format's range (IWL <= 64): only the sign matters unless wrapping,
            // where every bit at or below the LSB is zero.
            match overflow {
                Overflow::Wrap => 0,
                Overflow::Saturate if m < 0 => format.min_raw(),
                Overflow::Saturate if m > 0 => format.max_raw_i128() as i64,
                Overflow::Saturate => 0,
            }
        } else {
            quantize(m, -e, format, rounding, overflow)
        };
        Ok(Fx { raw, format })
    }

    /// The raw word (unsigned 64-bit words as their bit pattern).
    pub const fn raw(self) -> i64 {
        self.raw
    }

    /// The format.
    pub const fn format(self) -> Format {
        self.format
    }

    /// The value as a float (exact up to 53 significant bits).
    pub fn to_f64(self) -> f64 {
        self.format.raw_value(self.raw) as f64 * self.format.lsb()
    }

    fn exact(self) -> I256 {
        I256::from_i128(self.format.raw_value(self.raw))
    }

    /// `self` converted into `out`.
    pub fn convert(self, out: Format, rounding: Rounding, overflow: Overflow) -> Fx {
        let raw = quantize_wide(
            self.exact(),
            self.format.frac_bits(),
            out,
            rounding,
            overflow,
        );
        Fx { raw, format: out }
    }

    /// `self * 2^k` into `out` (LabVIEW's "scale by power of 2"; exact before quantization).
    pub fn scale(self, k: i32, out: Format, rounding: Rounding, overflow: Overflow) -> Fx {
        let raw = quantize_wide(
            self.exact(),
            self.format.frac_bits() - k,
            out,
            rounding,
            overflow,
        );
        Fx { raw, format: out }
    }

    /// `-self` into `out`.
    pub fn neg(self, out: Format, rounding: Rounding, overflow: Overflow) -> Fx {
        let raw = quantize_wide(
            self.exact().wrapping_neg(),
            self.format.frac_bits(),
            out,
            rounding,
            overflow,
        );
        Fx { raw, format: out }
    }

    /// `self + rhs` into `out`.
    pub fn add(self, rhs: Fx, out: Format, rounding: Rounding, overflow: Overflow) -> Fx {
        self.add_signed(rhs, false, out, rounding, overflow)
    }

    /// `self - rhs` into `out`.
    pub fn sub(self, rhs: Fx, out: Format, rounding: Rounding, overflow: Overflow) -> Fx {
        self.add_signed(rhs, true, out, rounding, overflow)
    }

    fn add_signed(
        self,
        rhs: Fx,
        negate: bool,
        out: Format,
        rounding: Rounding,
        overflow: Overflow,
    ) -> Fx {
        let (fa, fb) = (self.format.frac_bits(), rhs.format.frac_bits());
        let f = fa.max(fb);
        // Alignment shifts are at most 191 bits and the operands at most 64 bits: exact in 256.
        let a = self.exact().wrapping_shl((f - fa) as u32);
        let mut b = rhs.exact().wrapping_shl((f - fb) as u32);
        if negate {
            b = b.wrapping_neg();
        }
        let raw = quantize_wide(a.wrapping_add(b), f, out, rounding, overflow);
        Fx { raw, format: out }
    }

    /// `self * rhs` into `out`.
    pub fn mul(self, rhs: Fx, out: Format, rounding: Rounding, overflow: Overflow) -> Fx {
        let p = I256::mul_i128(
            self.format.raw_value(self.raw),
            rhs.format.raw_value(rhs.raw),
        );
        let raw = quantize_wide(
            p,
            self.format.frac_bits() + rhs.format.frac_bits(),
            out,
            rounding,
            overflow,
        );
        Fx { raw, format: out }
    }

    /// The exact product's format (`WL1 + WL2`, `IWL1 + IWL2`), when it is at most 64 bits.
    pub fn product_format(a: Format, b: Format) -> Option<Format> {
        Format::new(
            a.is_signed() || b.is_signed(),
            a.word_length() + b.word_length(),
            a.integer_word_length() + b.integer_word_length(),
        )
        .ok()
    }
}

impl fmt::Display for Fx {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {}", self.to_f64(), self.format)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The straightforward reference: exact value `num / 2^den_bits` (small), rounded with
    /// integer division and remainders, overflow by modular arithmetic or clamping.
    fn reference(num: i128, den_bits: i32, out: Format, r: Rounding, o: Overflow) -> i64 {
        // value on the output grid = num * 2^(out.frac - den_bits) = n / d
        let shift = out.frac_bits() - den_bits;
        let (n, d) = if shift >= 0 {
            (num * (1i128 << shift), 1i128)
        } else {
            (num, 1i128 << (-shift))
        };
        let floor = n.div_euclid(d);
        let rem = n.rem_euclid(d); // 0 <= rem < d
        let q = match r {
            Rounding::Truncate => floor,
            Rounding::HalfUp => {
                if 2 * rem >= d {
                    floor + 1
                } else {
                    floor
                }
            }
            Rounding::HalfEven => match (2 * rem).cmp(&d) {
                Ordering::Less => floor,
                Ordering::Greater => floor + 1,
                Ordering::Equal => floor + (floor.rem_euclid(2)),
            },
        };
        let (lo, hi) = (out.min_raw() as i128, out.max_raw_i128());
        match o {
            Overflow::Saturate => q.clamp(lo, hi) as i64,
            Overflow::Wrap => {
                let m = 1i128 << out.word_length();
                let w = q.rem_euclid(m);
                if out.is_signed() && w > hi {
                    (w - m) as i64
                } else {
                    w as i64
                }
            }
        }
    }

    fn small_formats() -> impl Iterator<Item = Format> {
        [false, true].into_iter().flat_map(|s| {
            [1u32, 2, 3, 4].into_iter().flat_map(move |wl| {
                [-2i32, 0, 1, 3, 6]
                    .into_iter()
                    .map(move |iwl| Format::new(s, wl, iwl).unwrap())
            })
        })
    }

    fn words(f: Format) -> impl Iterator<Item = Fx> {
        (f.min_raw()..=f.max_raw_i128() as i64).map(move |r| Fx::from_raw(r, f).unwrap())
    }

    const MODES: [(Rounding, Overflow); 6] = [
        (Rounding::Truncate, Overflow::Wrap),
        (Rounding::Truncate, Overflow::Saturate),
        (Rounding::HalfUp, Overflow::Wrap),
        (Rounding::HalfUp, Overflow::Saturate),
        (Rounding::HalfEven, Overflow::Wrap),
        (Rounding::HalfEven, Overflow::Saturate),
    ];

    fn out_formats() -> [Format; 8] {
        [
            Format::signed(3, 1),
            Format::signed(4, 3),
            Format::signed(5, -1),
            Format::unsigned(3, 2),
            Format::unsigned(4, 0),
            Format::signed(2, 5),
            Format::unsigned(1, -2),
            Format::signed(6, 4),
        ]
    }

    #[test]
    fn exhaustive_small_add_sub_mul_against_the_reference() {
        let mut checked = 0u64;
        for fa in small_formats() {
            for fb in small_formats() {
                for a in words(fa) {
                    for b in words(fb) {
                        let (na, nb) = (a.raw() as i128, b.raw() as i128);
                        let (ea, eb) = (fa.frac_bits(), fb.frac_bits());
                        let f = ea.max(eb);
                        let sa = na << (f - ea);
                        let sb = nb << (f - eb);
                        for out in out_formats() {
                            for (r, o) in MODES {
                                assert_eq!(
                                    a.add(b, out, r, o).raw(),
                                    reference(sa + sb, f, out, r, o),
                                    "{a} + {b} -> {out} {r:?} {o:?}"
                                );
                                assert_eq!(
                                    a.sub(b, out, r, o).raw(),
                                    reference(sa - sb, f, out, r, o),
                                    "{a} - {b} -> {out} {r:?} {o:?}"
                                );
                                assert_eq!(
                                    a.mul(b, out, r, o).raw(),
                                    reference(na * nb, ea + eb, out, r, o),
                                    "{a} * {b} -> {out} {r:?} {o:?}"
                                );
                                checked += 3;
                            }
                        }
                    }
                }
            }
        }
        assert!(checked > 1_000_000, "{checked}");
    }

    #[test]
    fn exhaustive_small_convert_neg_scale_against_the_reference() {
        for fa in small_formats() {
            for a in words(fa) {
                let n = a.raw() as i128;
                let e = fa.frac_bits();
                for out in out_formats() {
                    for (r, o) in MODES {
                        assert_eq!(a.convert(out, r, o).raw(), reference(n, e, out, r, o));
                        assert_eq!(a.neg(out, r, o).raw(), reference(-n, e, out, r, o));
                        for k in -3..=3 {
                            assert_eq!(
                                a.scale(k, out, r, o).raw(),
                                reference(n, e - k, out, r, o),
                                "{a} * 2^{k} -> {out}"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn fast_path_equals_the_wide_path() {
        // A small deterministic generator (xorshift) keeps this test free of dev-dependencies.
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        let outs = [
            Format::signed(25, 2),
            Format::signed(32, 2),
            Format::signed(64, 10),
            Format::unsigned(64, 0),
            Format::unsigned(7, -3),
            Format::signed(1, 1),
        ];
        for i in 0..200_000 {
            let width = (next() % 127) as u32;
            let v = ((next() as i128) << 64 | next() as i128) >> (127 - width);
            let frac = (next() % 200) as i32 - 70;
            let out = outs[i % outs.len()];
            for (r, o) in MODES {
                assert_eq!(
                    quantize(v, frac, out, r, o),
                    quantize_wide(I256::from_i128(v), frac, out, r, o),
                    "v={v} frac={frac} out={out} {r:?} {o:?}"
                );
            }
        }
    }

    #[test]
    fn rounding_ties_and_most_negative_code() {
        let f = Format::signed(4, 4); // integers -8..=7
        let half = |n: i128| (n, 1); // n / 2
        for (n, t, u, e) in [
            (5, 2, 3, 2),     // 2.5
            (7, 3, 4, 4),     // 3.5
            (-5, -3, -2, -2), // -2.5
            (-7, -4, -3, -4), // -3.5
            (15, 7, 8, 8),    // 7.5: half-up overflows
        ] {
            let (v, fr) = half(n);
            assert_eq!(quantize(v, fr, f, Rounding::Truncate, Overflow::Wrap), t);
            assert_eq!(
                quantize(v, fr, f, Rounding::HalfUp, Overflow::Saturate),
                u.min(7)
            );
            assert_eq!(
                quantize(v, fr, f, Rounding::HalfEven, Overflow::Saturate),
                e.min(7)
            );
        }
        assert_eq!(quantize(8, 0, f, Rounding::Truncate, Overflow::Wrap), -8);
        let m = Fx::from_raw(-8, f).unwrap();
        assert_eq!(m.neg(f, Rounding::Truncate, Overflow::Wrap).raw(), -8);
        assert_eq!(m.neg(f, Rounding::Truncate, Overflow::Saturate).raw(), 7);
    }

    #[test]
    fn wide_formats_are_exact() {
        let u64f = Format::unsigned(64, 64);
        let a = Fx::from_raw(-1, u64f).unwrap(); // 2^64 - 1
        assert_eq!(a.to_f64(), u64::MAX as f64);
        let sq = a.mul(a, u64f, Rounding::Truncate, Overflow::Saturate);
        assert_eq!(sq.raw(), -1); // saturated at 2^64 - 1
        let tiny = Format::signed(64, -64);
        let big = Format::signed(64, 64);
        let x = Fx::from_raw(1, big).unwrap();
        let y = Fx::from_raw(1, tiny).unwrap();
        // 1 + 2^-128: exact sum, then truncated back into the coarse format.
        assert_eq!(x.add(y, big, Rounding::Truncate, Overflow::Wrap).raw(), 1);
        assert_eq!(x.add(y, big, Rounding::HalfEven, Overflow::Wrap).raw(), 1);
        assert_eq!(
            x.neg(big, Rounding::Truncate, Overflow::Wrap)
                .add(y, big, Rounding::HalfUp, Overflow::Wrap)
                .raw(),
            -1
        );
    }

    #[test]
    fn floats_convert_exactly() {
        let f = Format::signed(25, 2);
        let x = Fx::from_f64(0.5 + 2f64.powi(-24), f, Rounding::HalfEven, Overflow::Wrap).unwrap();
        assert_eq!(x.raw(), 1 << 22); // tie to even
        let x = Fx::from_f64(0.5 + 2f64.powi(-24), f, Rounding::HalfUp, Overflow::Wrap).unwrap();
        assert_eq!(x.raw(), (1 << 22) + 1);
        let x = Fx::from_f64(-1.0e300, f, Rounding::HalfUp, Overflow::Saturate).unwrap();
        assert_eq!(x.raw(), f.min_raw());
        assert_eq!(
            Fx::from_f64(f64::NAN, f, Rounding::HalfUp, Overflow::Wrap),
            Err(FixedError::NonFinite)
        );
        assert_eq!(Format::new(true, 65, 0), Err(FixedError::WordLength(65)));
        assert_eq!(
            Format::new(true, 8, 65),
            Err(FixedError::IntegerWordLength(65))
        );
        assert_eq!(
            Fx::from_raw(128, Format::signed(8, 8)),
            Err(FixedError::RawOutOfRange)
        );
    }
}
