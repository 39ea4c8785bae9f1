//! The DH table as fixed-point data: what the FPGA's registers hold.
//!
//! Standard (distal) DH, `A_j = Rz(theta_j) Tz(d_j) Tx(a_j) Rx(alpha_j)`,
//! `theta_j = q_j + offset_j`. The hardware supports `alpha` in {0, +90, 180, -90} degrees (an
//! exact column swap and sign: no multiplier), lengths in [`LENGTH`] and offsets in
//! [`ANGLE`](crate::sincos::ANGLE). Up to [`JOINTS`] joints; unused rows are identity
//! transforms (`a = d = 0`, `alpha = 0`, `offset = 0`, `q = 0`), which the pipeline passes through
//! exactly.

use core::f64::consts::FRAC_PI_2;
use core::fmt;

use crate::fixed::{Format, Fx, Overflow, Rounding};
use crate::sincos::angle_from_radians;

/// Joints the pipeline computes (rows of the table).
pub const JOINTS: usize = 6;

/// Link lengths `a` and `d`: `<+-,25,1>` metres (LSB `2^-24` m, about 0.06 um; range +-1 m).
pub const LENGTH: Format = Format::signed(25, 1);

/// A link twist the hardware supports: a multiple of 90 degrees (2-bit code `alpha / 90deg mod 4`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Alpha {
    /// 0 rad (code 0).
    Zero = 0,
    /// +pi/2 (code 1).
    Plus90 = 1,
    /// pi (code 2).
    Pi = 2,
    /// -pi/2 (code 3).
    Minus90 = 3,
}

impl Alpha {
    /// The 2-bit code the RTL's `alpha` port takes.
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// The twist, rad.
    pub fn radians(self) -> f64 {
        match self {
            Alpha::Zero => 0.0,
            Alpha::Plus90 => FRAC_PI_2,
            Alpha::Pi => core::f64::consts::PI,
            Alpha::Minus90 => -FRAC_PI_2,
        }
    }

    /// The supported twist within 1e-9 rad of `radians`, if any.
    pub fn from_radians(radians: f64) -> Option<Alpha> {
        if !radians.is_finite() {
            return None;
        }
        let k = libm::round(radians / FRAC_PI_2);
        if (radians - k * FRAC_PI_2).abs() > 1e-9 {
            return None;
        }
        Some(match (k as i64).rem_euclid(4) {
            0 => Alpha::Zero,
            1 => Alpha::Plus90,
            2 => Alpha::Pi,
            _ => Alpha::Minus90,
        })
    }
}

/// One DH row in floating point: metres and radians.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct DhParams {
    /// Offset along the previous z, m.
    pub d: f64,
    /// Length along the new x, m.
    pub a: f64,
    /// Twist about the new x, rad.
    pub alpha: f64,
    /// Joint offset added to `q`, rad.
    pub offset: f64,
}

/// One DH row as the hardware holds it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct DhRow {
    /// `d`, raw [`LENGTH`] word.
    pub d: i32,
    /// `a`, raw [`LENGTH`] word.
    pub a: i32,
    /// The twist.
    pub alpha: Alpha,
    /// The joint offset, raw [`ANGLE`](crate::sincos::ANGLE) word.
    pub offset: i32,
}

impl DhRow {
    /// The identity row (padding for unused joints).
    pub const IDENTITY: DhRow = DhRow {
        d: 0,
        a: 0,
        alpha: Alpha::Zero,
        offset: 0,
    };
}

/// Why a DH table cannot go into the hardware.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TableError {
    /// More than [`JOINTS`] rows, or none.
    JointCount(usize),
    /// Row `joint` has a NaN or infinite entry.
    NonFinite {
        /// Row index (0-based).
        joint: usize,
    },
    /// Row `joint` has a twist that is not a multiple of 90 degrees.
    UnsupportedAlpha {
        /// Row index (0-based).
        joint: usize,
    },
    /// Row `joint` has a length outside [`LENGTH`]'s range (+-1 m).
    LengthOutOfRange {
        /// Row index (0-based).
        joint: usize,
    },
}

impl fmt::Display for TableError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TableError::JointCount(n) => write!(f, "{n} joints: the pipeline takes 1 to {JOINTS}"),
            TableError::NonFinite { joint } => write!(f, "DH row {joint}: NaN or infinite entry"),
            TableError::UnsupportedAlpha { joint } => write!(
                f,
                "DH row {joint}: alpha must be a multiple of 90 degrees on the FPGA"
            ),
            TableError::LengthOutOfRange { joint } => {
                write!(f, "DH row {joint}: length outside +-1 m")
            }
        }
    }
}

impl core::error::Error for TableError {}

/// A DH table in hardware words: [`JOINTS`] rows, the first `joints` of them used.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct DhTable {
    rows: [DhRow; JOINTS],
    joints: usize,
}

impl DhTable {
    /// The FRHC working model of `reference/kinematics.md` (an assumption: the real link
    /// lengths were never published): `d4 = a2 = 0.25` m, alpha `+90, 0, -90, +90, -90, 0`,
    /// joint 5 offset `+pi/2`. Every entry is exact in hardware words.
    pub const fn frhc() -> DhTable {
        const QUARTER_M: i32 = 1 << 22; // 0.25 m in LENGTH
        const HALF_PI: i32 = 1 << 22; // pi/2 in ANGLE
        const fn r(d: i32, a: i32, alpha: Alpha, offset: i32) -> DhRow {
            DhRow {
                d,
                a,
                alpha,
                offset,
            }
        }
        DhTable {
            rows: [
                r(0, 0, Alpha::Plus90, 0),
                r(0, QUARTER_M, Alpha::Zero, 0),
                r(0, 0, Alpha::Minus90, 0),
                r(QUARTER_M, 0, Alpha::Plus90, 0),
                r(0, 0, Alpha::Minus90, HALF_PI),
                r(0, 0, Alpha::Zero, 0),
            ],
            joints: 6,
        }
    }

    /// The floating-point rows of the FRHC working model (what [`DhTable::frhc`] quantizes).
    pub fn frhc_params() -> [DhParams; JOINTS] {
        let row = |d, a, alpha, offset| DhParams {
            d,
            a,
            alpha,
            offset,
        };
        [
            row(0.0, 0.0, FRAC_PI_2, 0.0),
            row(0.0, 0.25, 0.0, 0.0),
            row(0.0, 0.0, -FRAC_PI_2, 0.0),
            row(0.25, 0.0, FRAC_PI_2, 0.0),
            row(0.0, 0.0, -FRAC_PI_2, FRAC_PI_2),
            row(0.0, 0.0, 0.0, 0.0),
        ]
    }

    /// A table from hardware rows (unused rows past `joints` are replaced by identity rows).
    ///
    /// # Errors
    /// [`TableError::JointCount`] unless `1 <= joints <= 6`.
    pub fn from_rows(rows: [DhRow; JOINTS], joints: usize) -> Result<DhTable, TableError> {
        if !(1..=JOINTS).contains(&joints) {
            return Err(TableError::JointCount(joints));
        }
        let mut rows = rows;
        for row in rows.iter_mut().skip(joints) {
            *row = DhRow::IDENTITY;
        }
        Ok(DhTable { rows, joints })
    }

    /// Quantizes floating-point rows: lengths and offsets rounded half-even to the nearest word.
    ///
    /// # Errors
    /// See [`TableError`].
    pub fn from_params(params: &[DhParams]) -> Result<DhTable, TableError> {
        if params.is_empty() || params.len() > JOINTS {
            return Err(TableError::JointCount(params.len()));
        }
        let mut rows = [DhRow::IDENTITY; JOINTS];
        for (joint, (p, row)) in params.iter().zip(rows.iter_mut()).enumerate() {
            let length = |x: f64| -> Result<i32, TableError> {
                let w = Fx::from_f64(x, LENGTH, Rounding::HalfEven, Overflow::Saturate)
                    .map_err(|_| TableError::NonFinite { joint })?;
                // Saturation means out of range: refuse rather than clamp a geometry.
                if (w.to_f64() - x).abs() > LENGTH.lsb() {
                    return Err(TableError::LengthOutOfRange { joint });
                }
                Ok(w.raw() as i32)
            };
            let offset =
                angle_from_radians(p.offset).map_err(|_| TableError::NonFinite { joint })?;
            if !p.alpha.is_finite() {
                return Err(TableError::NonFinite { joint });
            }
            *row = DhRow {
                d: length(p.d)?,
                a: length(p.a)?,
                alpha: Alpha::from_radians(p.alpha)
                    .ok_or(TableError::UnsupportedAlpha { joint })?,
                offset,
            };
        }
        Ok(DhTable {
            rows,
            joints: params.len(),
        })
    }

    /// All [`JOINTS`] rows (identity past [`joints`](DhTable::joints)).
    pub const fn rows(&self) -> &[DhRow; JOINTS] {
        &self.rows
    }

    /// Rows actually used.
    pub const fn joints(&self) -> usize {
        self.joints
    }

    /// The table back in floating point (exact values of the words).
    pub fn to_params(&self) -> [DhParams; JOINTS] {
        let lsb = LENGTH.lsb();
        self.rows.map(|r| DhParams {
            d: r.d as f64 * lsb,
            a: r.a as f64 * lsb,
            alpha: r.alpha.radians(),
            offset: crate::sincos::angle_to_radians(r.offset),
        })
    }
}

impl Default for DhTable {
    fn default() -> Self {
        DhTable::frhc()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frhc_words_match_the_float_table() {
        assert_eq!(
            DhTable::from_params(&DhTable::frhc_params()),
            Ok(DhTable::frhc())
        );
        assert_eq!(DhTable::frhc().to_params(), DhTable::frhc_params());
        assert!(crate::sincos::ANGLE.contains_raw(DhTable::frhc().rows()[4].offset as i64));
    }

    #[test]
    fn bad_tables_are_refused() {
        let mut p = DhTable::frhc_params();
        p[2].alpha = 0.3;
        assert_eq!(
            DhTable::from_params(&p),
            Err(TableError::UnsupportedAlpha { joint: 2 })
        );
        p[2].alpha = 0.0;
        p[3].d = 1.5;
        assert_eq!(
            DhTable::from_params(&p),
            Err(TableError::LengthOutOfRange { joint: 3 })
        );
        p[3].d = f64::NAN;
        assert_eq!(
            DhTable::from_params(&p),
            Err(TableError::NonFinite { joint: 3 })
        );
        assert_eq!(DhTable::from_params(&[]), Err(TableError::JointCount(0)));
        assert_eq!(
            DhTable::from_rows([DhRow::IDENTITY; JOINTS], 7),
            Err(TableError::JointCount(7))
        );
        assert_eq!(Alpha::from_radians(-core::f64::consts::PI), Some(Alpha::Pi));
        assert_eq!(Alpha::from_radians(3.0 * FRAC_PI_2), Some(Alpha::Minus90));
    }
}
