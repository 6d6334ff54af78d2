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

/// The wobble as the stage holds it: angles in rad, offsets in µm, in [`RotaryWobble`]'s order.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub(crate) struct WobbleTerms {
    c: [[f32; 8]; WOBBLE_HARMONICS],
    tilt: [[f32; 4]; WOBBLE_TILT_DEGREE],
    /// True when any coefficient is non-zero (the stage then adds the terms at each refresh).
    pub(crate) on: bool,
}

/// The angles the wobble is evaluated at: sin and cos of the tilt axis's and C's angles, the tilt
/// axis's signed angle (rad).
#[derive(Debug, Clone, Copy)]
pub(crate) struct WobbleAngles {
    pub(crate) st: f32,
    pub(crate) ct: f32,
    pub(crate) sc: f32,
    pub(crate) cc: f32,
    pub(crate) t: f32,
}

impl WobbleTerms {
    /// All zero bytes (the zero stage).
    pub(crate) const ZERO: WobbleTerms = WobbleTerms {
        c: [[0.0; 8]; WOBBLE_HARMONICS],
        tilt: [[0.0; 4]; WOBBLE_TILT_DEGREE],
        on: false,
    };

    /// From a validated wobble (at load): the rotations (even entries) from µrad to rad.
    pub(crate) fn new(w: &RotaryWobble) -> WobbleTerms {
        let rad = |row: &[f32]| -> [f32; 8] {
            core::array::from_fn(|i| {
                let v = row.get(i).copied().unwrap_or(0.0);
                if i % 2 == 0 { v * 1.0e-6 } else { v }
            })
        };
        WobbleTerms {
            c: w.c.map(|h| rad(&h)),
            tilt: w.tilt.map(|p| {
                let v = rad(&p);
                [v[0], v[1], v[2], v[3]]
            }),
            on: !w.is_none(),
        }
    }

    /// The rotation W (rad) and translation T (µm) of the module's model, machine frame, for a
    /// trunnion (`head` false; the tilt axis about X if `about_x`, else about Y) or the head.
    #[inline(never)]
    pub(crate) fn terms(&self, head: bool, about_x: bool, a: WobbleAngles) -> ([f32; 3], [f32; 3]) {
        // C: Σ_k c[k]·(cos kc, sin kc) → [wx, rx, wy, ry].
        let mut cs = [0.0f32; 4];
        let (mut c0, mut s0, mut ck, mut sk) = (1.0f32, 0.0f32, a.cc, a.sc);
        for h in &self.c {
            for (i, v) in cs.iter_mut().enumerate() {
                *v += h[i] * ck + h[i + 4] * sk;
            }
            let two_c = a.cc + a.cc;
            (c0, s0, ck, sk) = (ck, sk, two_c * ck - c0, two_c * sk - s0);
        }
        // The tilt axis: Σ_d tilt[d]·t^(d+1) → [w1, r1, wz, rz].
        let mut ts = [0.0f32; 4];
        let mut td = 1.0f32;
        for p in &self.tilt {
            td *= a.t;
            for (i, v) in ts.iter_mut().enumerate() {
                *v += p[i] * td;
            }
        }
        let (w_c, r_c) = ([cs[0], cs[2], 0.0], [cs[1], cs[3], 0.0]);
        let p = if about_x { 1 } else { 0 };
        let mut w_t = [0.0, 0.0, ts[2]];
        let mut r_t = [0.0, 0.0, ts[3]];
        w_t[p] = ts[0];
        r_t[p] = ts[1];
        if head {
            // C turns the tilt axis's terms (about Z).
            let turn = |v: [f32; 3]| rotate(v, 2, a.sc, a.cc);
            (add(w_c, turn(w_t)), add(r_c, turn(r_t)))
        } else {
            let tilt = |v: [f32; 3]| rotate(v, 1 - p, a.st, a.ct);
            (add(tilt(w_c), w_t), add(tilt(r_c), r_t))
        }
    }
}

/// `v` turned by the angle of sin `s`, cos `c` about the machine axis `axis` (0 X, 1 Y, 2 Z).
#[inline(always)]
fn rotate(v: [f32; 3], axis: usize, s: f32, c: f32) -> [f32; 3] {
    let (i, j) = ((axis + 1) % 3, (axis + 2) % 3);
    let mut out = v;
    out[i] = c * v[i] - s * v[j];
    out[j] = s * v[i] + c * v[j];
    out
}

#[inline(always)]
fn add(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
