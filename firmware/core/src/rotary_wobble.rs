//! The rotary stage's wobble ([`RotaryWobble`]): what it adds to the first-order model of
//! [`crate::rotary`], evaluated when a commanded angle changes (with the location errors' terms,
//! in the stage's cache), never on a cycle without a change.
//!
//! # Model (first order)
//! A small rotation w (rad) and translation r (µm) of what C carries, in the frame C turns in,
//! and w', r' of what the tilt axis carries, in the machine frame at zero angles:
//! - trunnion: the workpiece point meant to be at q moves by R_T r + r' + (R_T w + w') × q (the
//!   table turns about lines through the pivot; the displacement e of the location errors gains
//!   W = R_T w + w' in ω and T = R_T r + r' in its constant part); the deviation, s(q) − e,
//!   gains −T − W × q;
//! - head: the tool tip (tool vector v = R_C R_B (0, 0, −L) from the pivot) moves by
//!   r + R_C r' + (w + R_C w') × v, which the deviation, s(q) + δ, gains: W = w + R_C w',
//!   T = r + R_C r'.
//!
//! These are the host's signatures (`axcomp_rtest::effects`: `c_carried_rotation`,
//! `tilt_carried_translation`, …) with the opposite sign: the R-test displacement is sphere minus
//! tool point, the deviation tool tip relative to the workpiece.
//!
//! # Evaluation
//! cos kc and sin kc of C's harmonics from the stage's sin c and cos c by the Chebyshev recurrence
//! x_{k+1} = 2 cos c · x_k − x_{k−1} (k ≤ 4: the f32 roundings grow with k, a few 1e-7 of the
//! coefficients); the tilt axis's powers t^d from its signed angle t (rad, in (−π, π]: a tilt axis
//! commanded at −30° is at −π/6, as the host's polynomial takes it). Only `+ − ×` in f32: the
//! same bits on the host and the target.

use crate::rotary_spec::{RotaryWobble, WOBBLE_HARMONICS, WOBBLE_TILT_DEGREE};

/// Rows of four coefficients: C's cos and sin rows per harmonic, then the tilt axis's per power.
const ROWS: usize = 2 * WOBBLE_HARMONICS + WOBBLE_TILT_DEGREE;

/// The wobble as the stage holds it: [`RotaryWobble`]'s coefficients (µrad, µm) as rows of four,
/// C's [w_x, r_x, w_y, r_y] times cos kc, then times sin kc, for k = 1…4, then the tilt axis's
/// [w_1, r_1, w_z, r_z] times t^d, d = 1…3.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub(crate) struct WobbleTerms {
    rows: [[f32; 4]; ROWS],
    /// True when any coefficient is non-zero (the stage then adds the terms at each refresh).
    pub(crate) on: bool,
}

impl WobbleTerms {
    /// All zero bytes (the zero stage).
    pub(crate) const ZERO: WobbleTerms = WobbleTerms {
        rows: [[0.0; 4]; ROWS],
        on: false,
    };

    /// From a validated wobble (at load).
    pub(crate) fn new(w: &RotaryWobble) -> WobbleTerms {
        let mut t = WobbleTerms::ZERO;
        let (c, tilt) = t.rows.as_flattened_mut().split_at_mut(8 * WOBBLE_HARMONICS);
        c.copy_from_slice(w.c.as_flattened());
        tilt.copy_from_slice(w.tilt.as_flattened());
        t.on = !w.is_none();
        t
    }

    /// The rotation W (rad) and translation T (µm) of the module's model, machine frame, for the
    /// angles `a` and the frame factors `p` of [`frame`] (the stage's machine kind).
    #[inline(never)]
    pub(crate) fn terms(&self, a: &WobbleAngles, p: &[f32; 6]) -> ([f32; 3], [f32; 3]) {
        // Each row's weight: cos kc and sin kc (Chebyshev), then t^d.
        let mut weight = [0.0f32; ROWS];
        let (mut c0, mut s0, mut ck, mut sk) = (1.0f32, 0.0f32, a.cc, a.sc);
        let two_c = a.cc + a.cc;
        for pair in weight[..2 * WOBBLE_HARMONICS].chunks_exact_mut(2) {
            pair[0] = ck;
            pair[1] = sk;
            (c0, s0, ck, sk) = (ck, sk, two_c * ck - c0, two_c * sk - s0);
        }
        let mut td = 1.0f32;
        for v in &mut weight[2 * WOBBLE_HARMONICS..] {
            td *= a.t;
            *v = td;
        }
        // [w_x, r_x, w_y, r_y] of C, [w_1, r_1, w_z, r_z] of the tilt axis (one row per call: code
        // flash, the loops are not unrolled into eleven copies of the row's arithmetic).
        let mut acc = [[0.0f32; 4]; 2];
        for (j, (row, &wj)) in self.rows.iter().zip(&weight).enumerate() {
            add_row(&mut acc[(j >= 2 * WOBBLE_HARMONICS) as usize], row, wj);
        }
        let [[wx, rx, wy, ry], [w1, r1, wz, rz]] = acc;
        let w = frame(p, wx, wy, w1, wz).map(|v| v * 1.0e-6);
        (w, frame(p, rx, ry, r1, rz))
    }
}

/// `acc` += `row`·`w`.
#[inline(never)]
fn add_row(acc: &mut [f32; 4], row: &[f32; 4], w: f32) {
    for (a, r) in acc.iter_mut().zip(row) {
        *a += r * w;
    }
}

/// The angles the wobble is evaluated at: sin and cos of C's angle, the tilt axis's signed angle
/// (rad).
#[derive(Debug, Clone, Copy)]
pub(crate) struct WobbleAngles {
    pub(crate) sc: f32,
    pub(crate) cc: f32,
    pub(crate) t: f32,
}

/// The frame factors p of the stage's kind for sin θ `st`, cos θ `ct` of the tilt axis and
/// sin c `sc`, cos c `cc`: a vector's parts (x, y) of C and 1, z of the tilt axis combine as
/// (p0·x + p1·v1, p2·y + p3·v1, p4·x + p5·y + z) — the trunnion's R_T (x, y, 0) + v_T (A about X:
/// v_T = (0, v1, z); B about Y: (v1, 0, z)), the head's (x, y, 0) + R_C (v1, 0, z).
pub(crate) fn frame_factors(
    head: bool,
    about_x: bool,
    st: f32,
    ct: f32,
    sc: f32,
    cc: f32,
) -> [f32; 6] {
    if head {
        [1.0, cc, 1.0, sc, 0.0, 0.0]
    } else if about_x {
        [1.0, 0.0, ct, 1.0, 0.0, st]
    } else {
        [ct, 1.0, 1.0, 0.0, -st, 0.0]
    }
}

/// (p0·x + p1·v1, p2·y + p3·v1, p4·x + p5·y + z) (see [`frame_factors`]).
#[inline(always)]
fn frame(p: &[f32; 6], x: f32, y: f32, v1: f32, z: f32) -> [f32; 3] {
    [
        p[0] * x + p[1] * v1,
        p[2] * y + p[3] * v1,
        p[4] * x + p[5] * y + z,
    ]
}
