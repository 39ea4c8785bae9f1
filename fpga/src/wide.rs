//! A 256-bit two's-complement integer: just enough to hold every exact intermediate of
//! [`crate::fixed`] (aligned sums need at most 193 bits, products 130 bits).

use core::cmp::Ordering;

/// A signed 256-bit integer, `hi * 2^128 + lo` (two's complement).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct I256 {
    hi: i128,
    lo: u128,
}

impl I256 {
    pub(crate) const ZERO: I256 = I256 { hi: 0, lo: 0 };
    pub(crate) const ONE: I256 = I256 { hi: 0, lo: 1 };

    pub(crate) const fn from_i128(v: i128) -> I256 {
        I256 {
            hi: v >> 127,
            lo: v as u128,
        }
    }

    pub(crate) const fn from_u128(v: u128) -> I256 {
        I256 { hi: 0, lo: v }
    }

    pub(crate) fn is_negative(self) -> bool {
        self.hi < 0
    }

    pub(crate) fn is_zero(self) -> bool {
        self.hi == 0 && self.lo == 0
    }

    pub(crate) fn wrapping_add(self, rhs: I256) -> I256 {
        let (lo, carry) = self.lo.overflowing_add(rhs.lo);
        I256 {
            hi: self.hi.wrapping_add(rhs.hi).wrapping_add(carry as i128),
            lo,
        }
    }

    pub(crate) fn wrapping_neg(self) -> I256 {
        I256 {
            hi: !self.hi,
            lo: !self.lo,
        }
        .wrapping_add(I256::ONE)
    }

    /// Exact product of two values of at most 65 significant bits each (any `i64` or `u64`).
    pub(crate) fn mul_i128(a: i128, b: i128) -> I256 {
        let negative = (a < 0) != (b < 0);
        let magnitude = a.unsigned_abs() * b.unsigned_abs(); // both <= 2^64: product < 2^128
        let m = I256::from_u128(magnitude);
        if negative { m.wrapping_neg() } else { m }
    }

    /// Shift left by `s` bits, dropping bits shifted past bit 255 (`s` may exceed 255).
    pub(crate) fn wrapping_shl(self, s: u32) -> I256 {
        match s {
            0 => self,
            1..=127 => I256 {
                hi: (self.hi << s) | (self.lo >> (128 - s)) as i128,
                lo: self.lo << s,
            },
            128..=255 => I256 {
                hi: (self.lo << (s - 128)) as i128,
                lo: 0,
            },
            _ => I256::ZERO,
        }
    }

    /// Arithmetic shift right by `s` bits (floor division by `2^s`; `s` may exceed 255).
    pub(crate) fn sar(self, s: u32) -> I256 {
        match s {
            0 => self,
            1..=127 => I256 {
                hi: self.hi >> s,
                lo: (self.lo >> s) | ((self.hi as u128) << (128 - s)),
            },
            128..=254 => I256 {
                hi: self.hi >> 127,
                lo: (self.hi >> (s - 128)) as u128,
            },
            _ => I256 {
                hi: self.hi >> 127,
                lo: (self.hi >> 127) as u128,
            },
        }
    }

    /// Bit `k` (bits past 255 repeat the sign).
    pub(crate) fn bit(self, k: u32) -> bool {
        match k {
            0..=127 => (self.lo >> k) & 1 == 1,
            128..=255 => (self.hi >> (k - 128)) & 1 == 1,
            _ => self.is_negative(),
        }
    }

    /// True when any of the low `k` bits is set.
    pub(crate) fn any_low_bits(self, k: u32) -> bool {
        match k {
            0 => false,
            1..=127 => self.lo & ((1u128 << k) - 1) != 0,
            128 => self.lo != 0,
            129..=255 => self.lo != 0 || (self.hi as u128) & ((1u128 << (k - 128)) - 1) != 0,
            _ => !self.is_zero(),
        }
    }

    /// The low 64 bits.
    pub(crate) fn low_u64(self) -> u64 {
        self.lo as u64
    }

    /// The value when it fits in an `i128`.
    pub(crate) fn to_i128(self) -> Option<i128> {
        let v = self.lo as i128;
        if (v >> 127) == self.hi { Some(v) } else { None }
    }

    pub(crate) fn cmp_i128(self, rhs: i128) -> Ordering {
        match self.to_i128() {
            Some(v) => v.cmp(&rhs),
            None if self.is_negative() => Ordering::Less,
            None => Ordering::Greater,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shifts_agree_with_i128_where_they_fit() {
        for v in [
            0i128,
            1,
            -1,
            12345,
            -98765,
            i64::MIN as i128,
            u64::MAX as i128,
        ] {
            let w = I256::from_i128(v);
            for s in 0..60u32 {
                assert_eq!(w.wrapping_shl(s).to_i128(), Some(v << s));
                assert_eq!(w.sar(s).to_i128(), Some(v >> s));
                assert_eq!(w.bit(s), (v >> s) & 1 == 1);
                assert_eq!(w.any_low_bits(s), v & ((1i128 << s) - 1) != 0);
            }
            for s in [200u32, 255, 256, 300] {
                assert_eq!(w.sar(s).to_i128(), Some(if v < 0 { -1 } else { 0 }));
            }
        }
    }

    #[test]
    fn wide_shift_round_trips() {
        let v = I256::from_i128(-0x1234_5678_9abc_def0_1234_5678);
        for s in [1u32, 63, 64, 100, 127, 128, 129, 150] {
            assert_eq!(v.wrapping_shl(s).sar(s), v, "s = {s}");
        }
        assert_eq!(v.wrapping_shl(256), I256::ZERO);
    }

    #[test]
    fn products_are_exact() {
        let p = I256::mul_i128(u64::MAX as i128, u64::MAX as i128);
        assert_eq!(p.cmp_i128(i128::MAX), Ordering::Greater);
        assert_eq!(p.sar(64).to_i128(), Some((u64::MAX - 1) as i128));
        let n = I256::mul_i128(i64::MIN as i128, u64::MAX as i128);
        assert_eq!(n.to_i128(), Some(i64::MIN as i128 * u64::MAX as i128));
        assert_eq!(I256::mul_i128(-3, 5).to_i128(), Some(-15));
    }
}
