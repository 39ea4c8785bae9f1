//! The forward-kinematics and force pipelines, node by node as the RTL computes them.
//!
//! Every node names its output format, rounding and overflow (the same table is in `SPEC.md`).
//! Products are exact; each dot product is summed exactly and quantized once.
//!
//! **Forward kinematics** (per joint `j = 0..6`, starting from `R = I`, `p = 0`):
//!
//! | node | value | format | rounding | overflow |
//! |---|---|---|---|---|
//! | `theta` | `q_j + offset_j` | [`ANGLE`] `<+-,24,1>` pi-rad | exact | wrap (mod 2 pi) |
//! | `s, c` | [`sin_cos`]`(theta)` | [`ROT`] `<+-,25,2>` | see `sincos` | none possible |
//! | `n0_i` | `c R_i0 + s R_i1` | [`ROT`] | truncate | wrap |
//! | `n1_i` | `c R_i1 - s R_i0` | [`ROT`] | truncate | wrap |
//! | `p_i` | `p_i + a n0_i + d R_i2` | [`POS`] `<+-,32,2>` m | truncate | wrap |
//! | `R` | `[n0, alpha(n1, R_2)]` | [`ROT`] | exact | wrap on negation |
//!
//! with `alpha(n1, r2)` = `(n1, r2)`, `(r2, -n1)`, `(-n1, -r2)`, `(-r2, n1)` for codes 0..3.
//! Before joint `j` the pipeline keeps `z_j = R[:,2]` and `o_j = p` for the force path.
//!
//! **Force** (wrench `[f; m]` in [`WRENCH`] `<+-,25,8>` N and N m):
//!
//! | node | value | format | rounding | overflow |
//! |---|---|---|---|---|
//! | `f0_i, m0_i` | `R_i . f`, `R_i . m` (flange frame in), or `f`, `m` (base frame in) | [`WRENCH`] | truncate | saturate |
//! | `r_i` | `p_i - o_j,i` (lever from joint `j`'s axis origin to the tool) | [`LEVER`] `<+-,25,2>` m | half-even | wrap |
//! | `mj_i` | `m0_i + (r x f0)_i` | [`WRENCH`] | truncate | saturate |
//! | `tau_j` | `z_j . mj` | [`TORQUE`] `<+-,25,8>` N m | half-even | saturate |
//!
//! so `tau = J^T [f0; m0]` with the geometric Jacobian's columns `[z_j x (p - o_j); z_j]`.
//!
//! # Real-time
//! Both pipelines are straight-line code over fixed-size arrays: no allocation, no panic,
//! constant time.

use crate::dh::{DhTable, JOINTS, LENGTH};
use crate::fixed::{Format, Overflow, Rounding, quantize};
use crate::sincos::{ANGLE, SIN_COS, sin_cos};

/// Rotation-matrix entries, `z` axes, `sin` and `cos`: `<+-,25,2>` (LSB `2^-23`).
pub const ROT: Format = SIN_COS;
/// Positions: `<+-,32,2>` metres (LSB `2^-30` m, about 0.93 nm; range +-2 m).
pub const POS: Format = Format::signed(32, 2);
/// Forces and moments, in and between nodes: `<+-,25,8>` N or N m (LSB `2^-17`, about 7.6 uN;
/// range +-128).
pub const WRENCH: Format = Format::signed(25, 8);
/// Lever arms `p - o_j`: `<+-,25,2>` metres (LSB `2^-23` m, about 0.12 um).
pub const LEVER: Format = Format::signed(25, 2);
/// Joint torques: `<+-,25,8>` N m (LSB `2^-17` N m).
pub const TORQUE: Format = Format::signed(25, 8);

const ONE: i64 = 1 << 23; // 1.0 in ROT

// Fraction bits of the exact intermediates (checked against the formats below).
const F_ROT_PRODUCT: i32 = 46; // ROT x ROT
const F_POS_SUM: i32 = 47; // LENGTH x ROT, and POS << 17
const F_WRENCH_PRODUCT: i32 = 40; // ROT x WRENCH, LEVER x WRENCH
const F_LEVER_SUM: i32 = 30; // POS - POS

const _: () = {
    assert!(F_ROT_PRODUCT == ROT.frac_bits() * 2);
    assert!(F_POS_SUM == LENGTH.frac_bits() + ROT.frac_bits());
    assert!(F_POS_SUM - POS.frac_bits() == 17);
    assert!(F_WRENCH_PRODUCT == ROT.frac_bits() + WRENCH.frac_bits());
    assert!(F_WRENCH_PRODUCT == LEVER.frac_bits() + WRENCH.frac_bits());
    assert!(F_LEVER_SUM == POS.frac_bits());
    assert!(ANGLE.word_length() == 24);
};

/// Every raw word of one forward-kinematics result.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct FkWords {
    /// Tool rotation `R[row][col]`, raw [`ROT`] words; the columns are the tool's x, y, z versors
    /// in the base frame.
    pub r: [[i32; 3]; 3],
    /// Tool position, raw [`POS`] words (m).
    pub p: [i32; 3],
    /// `z[j]`: joint `j`'s axis (the z of frame `j`, before joint `j`'s own motion), raw [`ROT`].
    pub z: [[i32; 3]; JOINTS],
    /// `o[j]`: the origin of frame `j`, raw [`POS`] words (m).
    pub o: [[i32; 3]; JOINTS],
}

/// Every raw word of one force transformation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct ForceWords {
    /// The wrench in the base frame about the tool origin `[f0; m0]`, raw [`WRENCH`] words.
    pub base_wrench: [i32; 6],
    /// Joint torques `tau = J^T [f0; m0]`, raw [`TORQUE`] words (N m).
    pub tau: [i32; JOINTS],
}

#[inline(always)]
fn rot(v: i64) -> i64 {
    quantize(
        v as i128,
        F_ROT_PRODUCT,
        ROT,
        Rounding::Truncate,
        Overflow::Wrap,
    )
}

#[inline(always)]
fn neg_rot(v: i64) -> i64 {
    quantize(
        -(v as i128),
        ROT.frac_bits(),
        ROT,
        Rounding::Truncate,
        Overflow::Wrap,
    )
}

/// Forward kinematics of `table` at the binary joint angles `q` (raw [`ANGLE`] words; only the
/// low 24 bits of each are used).
///
/// # Real-time
/// No allocation, no panic, constant time.
pub fn forward(table: &DhTable, q: &[i32; JOINTS]) -> FkWords {
    let mut r = [[0i64; 3]; 3];
    for (i, row) in r.iter_mut().enumerate() {
        row[i] = ONE;
    }
    let mut p = [0i64; 3];
    let mut out = FkWords::default();
    for (j, row) in table.rows().iter().enumerate() {
        for i in 0..3 {
            out.z[j][i] = r[i][2] as i32;
            out.o[j][i] = p[i] as i32;
        }
        // theta: exact sum, wrapped to 24 bits (sin_cos reads the low 24 bits).
        let theta = quantize(
            q[j] as i128 + row.offset as i128,
            ANGLE.frac_bits(),
            ANGLE,
            Rounding::Truncate,
            Overflow::Wrap,
        );
        let (s, c) = sin_cos(theta as i32);
        let (s, c) = (s as i64, c as i64);
        let mut n0 = [0i64; 3];
        let mut n1 = [0i64; 3];
        for i in 0..3 {
            n0[i] = rot(c * r[i][0] + s * r[i][1]);
            n1[i] = rot(c * r[i][1] - s * r[i][0]);
        }
        let (a, d) = (row.a as i64, row.d as i64);
        for i in 0..3 {
            let sum = ((p[i] as i128) << (F_POS_SUM - POS.frac_bits()))
                + (a * n0[i]) as i128
                + (d * r[i][2]) as i128;
            p[i] = quantize(sum, F_POS_SUM, POS, Rounding::Truncate, Overflow::Wrap);
        }
        for i in 0..3 {
            let r2 = r[i][2];
            let (c1, c2) = match row.alpha.code() {
                0 => (n1[i], r2),
                1 => (r2, neg_rot(n1[i])),
                2 => (neg_rot(n1[i]), neg_rot(r2)),
                _ => (neg_rot(r2), n1[i]),
            };
            r[i] = [n0[i], c1, c2];
        }
    }
    out.p = p.map(|x| x as i32);
    out.r = r.map(|row| row.map(|x| x as i32));
    out
}

/// Joint torques balancing the wrench `w = [f; m]` (raw [`WRENCH`] words) applied at the tool of
/// the configuration `fk`. With `flange_frame` the wrench is expressed in the tool (flange) frame
/// and is first rotated to the base by `fk.r`; otherwise it is already in the base frame. The
/// moment is about the tool origin either way.
///
/// # Real-time
/// No allocation, no panic, constant time.
pub fn joint_torques(fk: &FkWords, w: &[i32; 6], flange_frame: bool) -> ForceWords {
    let wq = |sum: i128| {
        quantize(
            sum,
            F_WRENCH_PRODUCT,
            WRENCH,
            Rounding::Truncate,
            Overflow::Saturate,
        )
    };
    let mut base = [0i64; 6];
    for i in 0..3 {
        if flange_frame {
            let row = fk.r[i].map(|x| x as i128);
            base[i] = wq(row[0] * w[0] as i128 + row[1] * w[1] as i128 + row[2] * w[2] as i128);
            base[3 + i] = wq(row[0] * w[3] as i128 + row[1] * w[4] as i128 + row[2] * w[5] as i128);
        } else {
            base[i] = w[i] as i64;
            base[3 + i] = w[3 + i] as i64;
        }
    }
    let f = [base[0] as i128, base[1] as i128, base[2] as i128];
    let mut out = ForceWords {
        base_wrench: base.map(|x| x as i32),
        tau: [0; JOINTS],
    };
    for j in 0..JOINTS {
        let mut lever = [0i128; 3];
        for (i, l) in lever.iter_mut().enumerate() {
            *l = quantize(
                fk.p[i] as i128 - fk.o[j][i] as i128,
                F_LEVER_SUM,
                LEVER,
                Rounding::HalfEven,
                Overflow::Wrap,
            ) as i128;
        }
        let shift = F_WRENCH_PRODUCT - WRENCH.frac_bits();
        let mj = [
            wq(((base[3] as i128) << shift) + lever[1] * f[2] - lever[2] * f[1]),
            wq(((base[4] as i128) << shift) + lever[2] * f[0] - lever[0] * f[2]),
            wq(((base[5] as i128) << shift) + lever[0] * f[1] - lever[1] * f[0]),
        ];
        let z = fk.z[j].map(|x| x as i128);
        let dot = z[0] * mj[0] as i128 + z[1] * mj[1] as i128 + z[2] * mj[2] as i128;
        out.tau[j] = quantize(
            dot,
            F_WRENCH_PRODUCT,
            TORQUE,
            Rounding::HalfEven,
            Overflow::Saturate,
        ) as i32;
    }
    out
}
