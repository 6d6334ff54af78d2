//! The volumetric geometric stage: the tool point's error relative to the workpiece from the 21
//! ISO 230-1 geometric errors of a three-axis machine, evaluated every cycle at the commanded
//! X, Y, Z (and the configured tool offset); the group subtracts it from the three commands.
//!
//! # Glossary (signs and conventions as `axcomp-kinematics`, ISO 230-1 names)
//! - **components**: of axis X, functions of its commanded position x: `EXX` positioning, `EYX`,
//!   `EZX` straightness (µm), `EAX` roll (about X), `EBX` pitch (about Y), `ECX` yaw (about Z)
//!   (µrad, positive right-handed about +X, +Y, +Z); likewise of Y and Z; the squareness constants
//!   `EC0Y` (Y to X, about Z), `EB0Z` (Z to X, about Y), `EA0Z` (Z to Y, about X), µrad. Each is
//!   stated as its effect on the tool point relative to the workpiece (for an axis that carries
//!   the workpiece, the negative of the table's own error motion).
//! - **error** e (µm): reached − commanded position of the tool point relative to the workpiece,
//!   along X, Y, Z (the crate's deviation convention). The stage's deviation is e; like every
//!   error it is subtracted from the command: the correction of X, Y, Z is −e.
//! - **stacking** (chain): the axes from the workpiece to the tool — the work axes outermost first
//!   (`--work-axes YX`: X, then Y), then the tool axes from the bed outward (`--tool-axes Z`).
//! - **tool offset** t (µm): the tool point's offset from the tool reference point; the Abbe arm
//!   of every angular error.
//! - **lever arm** of an axis's angular errors: t plus the nominal travel of every axis after it in
//!   the chain, arm_k = t + Σ_{j after k} q_j·u_j (its own travel is in its straightness).
//! - **model** (small angles, first order, the `axcomp-kinematics` `sensitivities` /
//!   `linear_error`): e = Σ_k δ_k(q_k) + Σ_k ε_k(q_k) × arm_k + (−y·EC0Y + z·EB0Z, −z·EA0Z, 0),
//!   δ_k = (EXk, EYk, EZk), ε_k = (EAk, EBk, ECk) in rad, positions in µm.
//! - **grid**: each axis's 6 functions are cubic segments over one uniform knot grid of that axis
//!   (`start_counts`, `segment_counts`, `n_segments`), in Horner form in t = (q − knot)/segment
//!   ∈ [0, 1), as the positioning table.
//! - **beyond the grid**: the model says nothing beyond its volume (the host's `predict` refuses
//!   such positions); the stage evaluates it at the nearest point of the volume, each axis's
//!   position clamped to its grid: functions, squareness terms and lever arms alike hold their
//!   values at the grid's end (nothing is extrapolated).
//!
//! # What the cycle computes (work that depends only on the image is done at load)
//! At load, in the **chain frame** (coordinates renamed so that the chain is 0, 1, 2: x'_i =
//! x_{chain[i]}; an angular vector also takes the permutation's sign, so that ε'×b' = P(ε×b)):
//! - ε_k × t is a cubic of q_k: folded into δ_k;
//! - the squareness terms are linear in y or z: folded into `EXY`, `EXZ`, `EYZ`;
//! - each polynomial is rescaled to r = t·segment (counts into the segment), so the cycle needs
//!   no division or scaling for t;
//! - an axis's angular errors only matter through the travel of the axes after it, so the pool
//!   keeps per segment: chain axis 0: δ' (3) and ε' (3); chain axis 1: δ' (3) and ε'_0, ε'_1; chain
//!   axis 2: δ' (3) — 14 functions instead of 18 + 3 constants.
//!
//! Each cycle: one segment search per axis (shared by that axis's functions), 14 Horner
//! evaluations, and with p1, p2 the commanded positions (µm) of chain axes 1 and 2:
//! e'_0 = Σδ'_0 + p2·(ε'_{0,1} + ε'_{1,1}) − p1·ε'_{0,2}, e'_1 = Σδ'_1 − p2·(ε'_{0,0} + ε'_{1,0}),
//! e'_2 = Σδ'_2 + p1·ε'_{0,0}; e of axis chain[i] is e'_i. The f32 sums run axis by axis from
//! the workpiece end of the chain (chain axis 0, then 1, then 2; see `error_chain_um`).
//!
//! The stage is a value: its settings `GeometricStage` (read through `&self`, built at load,
//! its functions in the group's coefficient pool); it keeps no state (the error is a function of
//! the commands of the cycle).

use core::num::NonZeroU32;

use crate::axis::MAX_AXES;
use crate::hint::cold_path;
use crate::le::f32_at;

/// Most segments of one axis's geometric grid.
pub const MAX_GEOMETRIC_SEGMENTS: u32 = 1024;
/// Functions per axis (positioning, 2 straightness, 3 angular).
pub const FUNCTIONS_PER_AXIS: usize = 6;
/// Largest |value| of a tool-offset coordinate, µm (10 m).
pub const MAX_TOOL_OFFSET_UM: f32 = 1.0e7;
/// Largest |squareness|, µrad (the model is first order).
pub const MAX_SQUARENESS_URAD: f32 = 1.0e4;
/// Largest |polynomial coefficient| of a geometric function (µm or µrad).
pub const MAX_GEOMETRIC_COEFFICIENT: f32 = 1.0e6;
/// The 21 ISO 230-1 names in the order of the section's identified mask and of the functions
/// (axis X's six, Y's, Z's, then the squareness constants).
pub const COMPONENT_NAMES: [&str; 21] = [
    "EXX", "EYX", "EZX", "EAX", "EBX", "ECX", "EXY", "EYY", "EZY", "EAY", "EBY", "ECY", "EXZ",
    "EYZ", "EZZ", "EAZ", "EBZ", "ECZ", "EC0Y", "EB0Z", "EA0Z",
];

/// Functions the pool keeps per segment for chain positions 0, 1, 2.
pub(crate) const STRIDE: [u32; 3] = [6, 5, 3];

/// Why a geometric model was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GeometricError {
    /// The chain is not X, Y, Z each once, or more work axes than axes.
    Stacking,
    /// The identified mask has bits beyond the 21 components.
    IdentifiedMask,
    /// A tool-offset coordinate (0..3) is not finite or beyond [`MAX_TOOL_OFFSET_UM`].
    ToolOffset {
        /// Coordinate (0 = x).
        index: u8,
    },
    /// A squareness constant (0 = EC0Y, 1 = EB0Z, 2 = EA0Z) is not finite or beyond
    /// [`MAX_SQUARENESS_URAD`].
    Squareness {
        /// Which.
        index: u8,
    },
    /// An axis's grid: 1..=[`MAX_GEOMETRIC_SEGMENTS`] segments of ≥ 1 count, |start| ≤ 2^62,
    /// span ≤ u32::MAX counts.
    Grid {
        /// Axis code (0 = X).
        axis: u8,
    },
    /// The coefficient block does not hold 6 functions × 4 coefficients per segment.
    CoefficientCount,
    /// A coefficient is not finite or beyond [`MAX_GEOMETRIC_COEFFICIENT`].
    Coefficient {
        /// Axis code (0 = X).
        axis: u8,
        /// Function of the axis (0..6: EX?, EY?, EZ?, EA?, EB?, EC?).
        function: u8,
        /// Segment.
        segment: u16,
    },
}

impl core::fmt::Display for GeometricError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let axis = |a: u8| ['X', 'Y', 'Z'].get(a as usize).copied().unwrap_or('?');
        match *self {
            GeometricError::Stacking => f.write_str("geometric: stacking must name X, Y, Z once"),
            GeometricError::IdentifiedMask => f.write_str("geometric: identified mask > 21 bits"),
            GeometricError::ToolOffset { index } => {
                write!(f, "geometric: tool offset [{index}] not finite or > 10 m")
            }
            GeometricError::Squareness { index } => write!(
                f,
                "geometric: {} not finite or > 10 mrad",
                COMPONENT_NAMES.get(18 + index as usize).unwrap_or(&"?")
            ),
            GeometricError::Grid { axis: a } => write!(
                f,
                "geometric: grid of {} needs 1..=1024 segments in range",
                axis(a)
            ),
            GeometricError::CoefficientCount => {
                f.write_str("geometric: coefficient block length does not match the grids")
            }
            GeometricError::Coefficient {
                axis: a,
                function,
                segment,
            } => write!(
                f,
                "geometric: {} segment {segment}: coefficient not finite or out of range",
                COMPONENT_NAMES
                    .get(6 * (a as usize) + function as usize)
                    .unwrap_or(&"?")
            ),
        }
    }
}

impl core::error::Error for GeometricError {}

/// The knot grid of one axis's geometric functions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GeometricGrid {
    /// Position of knot 0, counts.
    pub start_counts: i64,
    /// Knot spacing, counts.
    pub segment_counts: u32,
    /// Segments.
    pub n_segments: u32,
}

impl GeometricGrid {
    /// `start + n·segment`, counts.
    pub fn end_counts(&self) -> i128 {
        self.start_counts as i128 + self.segment_counts as i128 * self.n_segments as i128
    }
}

/// The coefficients, axis X's segments first, then Y's, then Z's; per segment the axis's 6
/// functions (EX?, EY?, EZ?, EA?, EB?, EC?), each `[c0, c1, c2, c3]` (µm or µrad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GeometricCoefficients<'a> {
    /// As values.
    Values(&'a [[f32; 4]]),
    /// As little-endian f32 bytes (16 per function and segment), e.g. an image section.
    Bytes(&'a [u8]),
}

impl GeometricCoefficients<'_> {
    /// Number of `[c0..c3]` entries.
    pub fn len(&self) -> usize {
        match self {
            GeometricCoefficients::Values(v) => v.len(),
            GeometricCoefficients::Bytes(b) => b.len() / 16,
        }
    }
    /// True if there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Entry `i` (zeros beyond the end). Out of line: it is called at load only, and inlined
    /// into every loop it would cost flash.
    #[inline(never)]
    pub fn get(&self, i: usize) -> [f32; 4] {
        match self {
            GeometricCoefficients::Values(v) => v.get(i).copied().unwrap_or([0.0; 4]),
            GeometricCoefficients::Bytes(b) => core::array::from_fn(|k| f32_at(b, 16 * i + 4 * k)),
        }
    }
}

/// A three-axis geometric model as an image holds it (see the module's glossary).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeometricSpec<'a> {
    /// Axis indices (0 = X, 1 = Y, 2 = Z) from the workpiece to the tool: the work axes outermost
    /// first, then the tool axes from the bed outward.
    pub chain: [u8; 3],
    /// How many of `chain` (the first ones) carry the workpiece (for display: `YX/Z` is chain
    /// X, Y, Z with 2 work axes).
    pub work_axes: u8,
    /// Bit i set: component i of [`COMPONENT_NAMES`] was identified by the fit (a component not
    /// identified is stored as the model gives it: a not-separable one at its minimum-norm share of
    /// the combination the fit measured, one without data as zero; the stage applies both alike).
    pub identified: u32,
    /// Tool offset from the tool reference point, µm (x, y, z).
    pub tool_offset_um: [f32; 3],
    /// EC0Y, EB0Z, EA0Z, µrad.
    pub squareness_urad: [f32; 3],
    /// Grids of X, Y, Z.
    pub grids: [GeometricGrid; 3],
    /// The 18 functions' segments.
    pub coefficients: GeometricCoefficients<'a>,
}

impl GeometricSpec<'_> {
    /// Entry of axis `axis`, segment `s`, function `f` in [`GeometricSpec::coefficients`].
    pub fn index(&self, axis: usize, s: usize, f: usize) -> usize {
        let before: usize = self.grids[..axis.min(3)]
            .iter()
            .map(|g| g.n_segments as usize)
            .sum();
        (before + s) * FUNCTIONS_PER_AXIS + f
    }

    /// `[c0..c3]` of axis `axis`'s function `f` in segment `s`.
    pub fn segment(&self, axis: usize, s: usize, f: usize) -> [f32; 4] {
        self.coefficients.get(self.index(axis, s, f))
    }

    /// `"YX/Z"`-style stacking label.
    pub fn stacking_label(&self) -> [u8; 4] {
        let l = |a: u8| b"XYZ".get(a as usize).copied().unwrap_or(b'?');
        let w = (self.work_axes as usize).min(3);
        let mut out = [b'/'; 4];
        let mut k = 0;
        for i in (0..w).rev() {
            out[k] = l(self.chain[i]);
            k += 1;
        }
        out[k] = b'/';
        k += 1;
        for i in w..3 {
            out[k] = l(self.chain[i]);
            k += 1;
        }
        out
    }

    /// Pool entries the stage needs (14 functions per segment position, see the module docs).
    pub fn pool_entries(&self) -> u32 {
        let mut n = 0u32;
        for (i, &a) in self.chain.iter().enumerate() {
            let g = self.grids[(a as usize).min(2)];
            n = n.saturating_add(STRIDE[i].saturating_mul(g.n_segments));
        }
        n
    }

    /// Every check of the model on its own (the group checks the axes and strokes).
    pub fn validate(&self) -> Result<(), GeometricError> {
        let mut seen = [false; 3];
        for &a in &self.chain {
            match seen.get_mut(a as usize) {
                Some(s) if !*s => *s = true,
                _ => return Err(GeometricError::Stacking),
            }
        }
        if self.work_axes > 3 {
            return Err(GeometricError::Stacking);
        }
        if self.identified >> 21 != 0 {
            return Err(GeometricError::IdentifiedMask);
        }
        for (i, v) in self.tool_offset_um.iter().enumerate() {
            if !(v.is_finite() && libm::fabsf(*v) <= MAX_TOOL_OFFSET_UM) {
                return Err(GeometricError::ToolOffset { index: i as u8 });
            }
        }
        for (i, v) in self.squareness_urad.iter().enumerate() {
            if !(v.is_finite() && libm::fabsf(*v) <= MAX_SQUARENESS_URAD) {
                return Err(GeometricError::Squareness { index: i as u8 });
            }
        }
        let mut total = 0usize;
        for (a, g) in self.grids.iter().enumerate() {
            let span = g.segment_counts as u64 * g.n_segments as u64;
            if !(1..=MAX_GEOMETRIC_SEGMENTS).contains(&g.n_segments)
                || g.segment_counts == 0
                || span > u32::MAX as u64
                || !(-(1i64 << 62)..=(1i64 << 62)).contains(&g.start_counts)
            {
                return Err(GeometricError::Grid { axis: a as u8 });
            }
            total += g.n_segments as usize * FUNCTIONS_PER_AXIS;
        }
        let exact = match self.coefficients {
            GeometricCoefficients::Values(v) => v.len() == total,
            GeometricCoefficients::Bytes(b) => b.len() == total * 16,
        };
        if !exact {
            return Err(GeometricError::CoefficientCount);
        }
        for i in 0..total {
            let c = self.coefficients.get(i);
            if c.iter()
                .any(|v| !(v.is_finite() && libm::fabsf(*v) <= MAX_GEOMETRIC_COEFFICIENT))
            {
                // Which axis, segment and function entry i is.
                let mut seg = i / FUNCTIONS_PER_AXIS;
                let mut axis = 0;
                while axis < 2 && seg >= self.grids[axis].n_segments as usize {
                    seg -= self.grids[axis].n_segments as usize;
                    axis += 1;
                }
                return Err(GeometricError::Coefficient {
                    axis: axis as u8,
                    function: (i % FUNCTIONS_PER_AXIS) as u8,
                    segment: seg as u16,
                });
            }
        }
        Ok(())
    }
}

/// A polynomial plus `k` times another.
#[inline(never)]
fn add_scaled(p: &mut [f32; 4], q: &[f32; 4], k: f32) {
    for (a, b) in p.iter_mut().zip(q.iter()) {
        *a += k * b;
    }
}

/// The stage as the group runs it (chain frame; see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct GeometricStage {
    /// Per chain position: pool index of segment 0.
    base: [u32; 3],
    start: [i64; 3],
    segment: [NonZeroU32; 3],
    span: [u32; 3],
    last: [u32; 3],
    /// r at the grid's end (the segment length, counts) for the last segment.
    end_r: [f32; 3],
    /// µm per count of chain axes 1 and 2 (the lever arms).
    um_per_count: [f32; 2],
    /// Position (µm) of the grid start of chain axes 1 and 2.
    start_um: [f32; 2],
    /// Group slot of each chain position (slot of the axis chain[i]).
    pub(crate) slot: [u8; 3],
}

impl GeometricStage {
    /// The start of [`GeometricStage::load`] (segment lengths 1, never 0: the cycle divides by
    /// them without a zero test). A group without the stage holds `None` instead, which is all
    /// zero bytes (this niche).
    const ZERO: GeometricStage = GeometricStage {
        base: [0; 3],
        start: [0; 3],
        segment: [NonZeroU32::MIN; 3],
        span: [0; 3],
        last: [0; 3],
        end_r: [0.0; 3],
        um_per_count: [0.0; 2],
        start_um: [0.0; 2],
        slot: [0; 3],
    };

    /// Build the stage from a validated `spec` and write its folded functions into
    /// `pool[base..base + spec.pool_entries()]`. `um_per_count` and `slot` of X, Y, Z.
    pub(crate) fn load(
        spec: &GeometricSpec,
        um_per_count: [f32; 3],
        slot: [u8; 3],
        pool: &mut [[f32; 4]],
        base: u32,
    ) -> GeometricStage {
        const URAD: f32 = 1.0e-6;
        let chain = spec.chain.map(|a| (a as usize).min(2));
        // Sign of the permutation x'_i = x_{chain[i]} (an angular vector takes it).
        let inversions = (chain[0] > chain[1]) as u32
            + (chain[0] > chain[2]) as u32
            + (chain[1] > chain[2]) as u32;
        let parity = if inversions % 2 == 0 { 1.0f32 } else { -1.0 };
        let t = spec.tool_offset_um;
        let [c0y, b0z, a0z] = spec.squareness_urad.map(|v| v * URAD);
        let mut g = GeometricStage::ZERO;
        let mut next = base;
        // Entry of segment 0 of each axis in the spec's coefficients.
        let first = [
            0,
            spec.grids[0].n_segments as usize * FUNCTIONS_PER_AXIS,
            (spec.grids[0].n_segments as usize + spec.grids[1].n_segments as usize)
                * FUNCTIONS_PER_AXIS,
        ];
        for (i, &a) in chain.iter().enumerate() {
            let grid = spec.grids[a];
            let seg = grid.segment_counts.max(1);
            g.base[i] = next;
            g.start[i] = grid.start_counts;
            g.segment[i] = NonZeroU32::new(seg).unwrap_or(NonZeroU32::MIN);
            g.span[i] = seg.wrapping_mul(grid.n_segments);
            g.last[i] = grid.n_segments.saturating_sub(1);
            g.end_r[i] = seg as f32;
            g.slot[i] = slot[a];
            let upc = um_per_count[a];
            let h_um = seg as f32 * upc;
            // 1/segment, 1/segment², 1/segment³ (f64 arithmetic, then rounded once).
            let inv = 1.0 / seg as f64;
            let inv_seg = [inv as f32, (inv * inv) as f32, (inv * inv * inv) as f32];
            for s in 0..grid.n_segments as usize {
                let at0 = first[a] + s * FUNCTIONS_PER_AXIS;
                let f = |k: usize| spec.coefficients.get(at0 + k);
                let mut delta = [f(0), f(1), f(2)];
                let eps = [f(3), f(4), f(5)].map(|p| p.map(|c| c * URAD));
                // ε × t (t constant): a cubic of this axis's position; component d gets
                // ε_{d+1}·t_{d+2} − ε_{d+2}·t_{d+1} (indices mod 3).
                #[allow(clippy::needless_range_loop)] // d, j, k index the same arrays
                for d in 0..3 {
                    let (j, k) = ((d + 1) % 3, (d + 2) % 3);
                    add_scaled(&mut delta[d], &eps[j], t[k]);
                    add_scaled(&mut delta[d], &eps[k], -t[j]);
                }
                // Squareness: −y·EC0Y, +z·EB0Z along x, −z·EA0Z along y; position = knot + t·h.
                let knot_um =
                    (grid.start_counts as f32 + (s as u32).wrapping_mul(seg) as f32) * upc;
                let line = [knot_um, h_um, 0.0, 0.0];
                if a == 1 {
                    add_scaled(&mut delta[0], &line, -c0y);
                }
                if a == 2 {
                    add_scaled(&mut delta[0], &line, b0z);
                    add_scaled(&mut delta[1], &line, -a0z);
                }
                let stride = STRIDE[i] as usize;
                let at = next as usize + s * stride;
                // In the chain frame (δ'_k = δ_{chain[k]}, ε'_k = ±ε_{chain[k]}); in the pool
                // each polynomial is in r = t·segment (counts into the segment): c_k / segment^k,
                // so the cycle needs no t.
                for k in 0..stride {
                    let (src, sign) = if k < 3 {
                        (&delta[chain[k]], 1.0)
                    } else {
                        (&eps[chain[(k - 3) % 3]], parity)
                    };
                    if let Some(dst) = pool.get_mut(at + k) {
                        *dst = [
                            sign * src[0],
                            sign * src[1] * inv_seg[0],
                            sign * src[2] * inv_seg[1],
                            sign * src[3] * inv_seg[2],
                        ];
                    }
                }
            }
            next = next.saturating_add(STRIDE[i].saturating_mul(grid.n_segments));
        }
        g.um_per_count = [um_per_count[chain[1]], um_per_count[chain[2]]];
        g.start_um = [1, 2].map(|i| g.start[i] as f32 * um_per_count[chain[i]]);
        g
    }

    /// The `N` functions' segment of chain position `i` at `command` (counts), r (counts into
    /// the segment, as f32) and the offset from the grid start (counts); beyond the grid the
    /// position is clamped to it.
    #[inline(always)]
    fn segment_at<'p, const N: usize>(
        &self,
        pool: &'p [[f32; 4]],
        i: usize,
        command: i64,
    ) -> (&'p [[f32; 4]; N], f32, u32) {
        const ZEROS: [[f32; 4]; 6] = [[0.0; 4]; 6];
        let diff = command.wrapping_sub(self.start[i]) as u64;
        let mut offset = diff as u32;
        let (seg, r) = if (diff >> 32) == 0 && offset < self.span[i] {
            let seg = offset / self.segment[i];
            let rem = offset - seg.wrapping_mul(self.segment[i].get());
            (seg, rem as f32)
        } else {
            cold_path();
            if command < self.start[i] {
                offset = 0;
                (0, 0.0)
            } else {
                offset = self.span[i];
                (self.last[i], self.end_r[i])
            }
        };
        // In range for a loaded stage (checked at load); the clamp keeps the path panic-free
        // and, with the pool's length known at the call, costs one compare.
        let at = (self.base[i] as usize + seg as usize * N).min(pool.len().saturating_sub(N));
        match pool
            .get(at..at + N)
            .and_then(|c| <&[[f32; 4]; N]>::try_from(c).ok())
        {
            Some(c) => (c, r, offset),
            None => {
                cold_path();
                (
                    <&[[f32; 4]; N]>::try_from(&ZEROS[..N]).unwrap_or(&[[0.0; 4]; N]),
                    r,
                    offset,
                )
            }
        }
    }

    /// The model error e (µm) of X, Y, Z at the commanded positions `commands` (counts, by chain
    /// position), in the chain frame: entry i belongs to the axis at chain position i. Summed
    /// axis by axis from the workpiece end of the chain (chain axis 0, then 1, then 2).
    #[inline(always)]
    pub(crate) fn error_chain_um(&self, pool: &[[f32; 4]], commands: [i64; 3]) -> [f32; 3] {
        // A pool polynomial at r counts into its segment.
        #[inline(always)]
        fn h(p: &[f32; 4], r: f32) -> f32 {
            p[0] + r * (p[1] + r * (p[2] + r * p[3]))
        }
        // The three segment searches, then the positions of chain axes 1 and 2 (µm, within
        // their grids): the lever arms.
        let (c0, t0, _) = self.segment_at::<6>(pool, 0, commands[0]);
        let (c1, t1, off1) = self.segment_at::<5>(pool, 1, commands[1]);
        let (c2, t2, off2) = self.segment_at::<3>(pool, 2, commands[2]);
        let p1 = self.start_um[0] + off1 as f32 * self.um_per_count[0];
        let p2 = self.start_um[1] + off2 as f32 * self.um_per_count[1];
        // Chain axis 0: δ', and ε' × (0, p1, p2).
        let ex = h(&c0[3], t0);
        let mut e = [
            h(&c0[0], t0) + p2 * h(&c0[4], t0) - p1 * h(&c0[5], t0),
            h(&c0[1], t0) - p2 * ex,
            h(&c0[2], t0) + p1 * ex,
        ];
        // Chain axis 1: δ', and ε' × (0, 0, p2).
        e[0] += h(&c1[0], t1) + p2 * h(&c1[4], t1);
        e[1] += h(&c1[1], t1) - p2 * h(&c1[3], t1);
        e[2] += h(&c1[2], t1);
        // Chain axis 2: δ' only (its angles act through the tool offset, folded in δ').
        e[0] += h(&c2[0], t2);
        e[1] += h(&c2[1], t2);
        e[2] += h(&c2[2], t2);
        e
    }

    /// [`GeometricStage::deviation_by_slot`] for a group of exactly X, Y, Z (slots 0..3): the
    /// deviation of slots 0, 1, 2 (and 0 in entry 3).
    #[inline(always)]
    pub(crate) fn deviation_xyz_slots(
        &self,
        pool: &[[f32; 4]],
        inputs: &[crate::CycleInput; MAX_AXES],
    ) -> [f32; 4] {
        let slot = |i: usize| self.slot[i] as usize & 3;
        let e = self.error_chain_um(
            pool,
            [
                inputs[slot(0)].command_counts,
                inputs[slot(1)].command_counts,
                inputs[slot(2)].command_counts,
            ],
        );
        let mut d = [0.0f32; 4];
        d[slot(0)] = e[0];
        d[slot(1)] = e[1];
        d[slot(2)] = e[2];
        d
    }

    /// The stage's deviation by group slot (X, Y, Z: the model error; others 0) for the group's
    /// commanded positions by slot.
    #[inline(always)]
    pub(crate) fn deviation_by_slot(
        &self,
        pool: &[[f32; 4]],
        command_by_slot: impl Fn(usize) -> i64,
    ) -> [f32; MAX_AXES] {
        let slot = |i: usize| (self.slot[i] as usize).min(MAX_AXES - 1);
        let e = self.error_chain_um(
            pool,
            [
                command_by_slot(slot(0)),
                command_by_slot(slot(1)),
                command_by_slot(slot(2)),
            ],
        );
        let mut by_slot = [0.0f32; MAX_AXES];
        for (i, ei) in e.into_iter().enumerate() {
            by_slot[slot(i)] = ei;
        }
        by_slot
    }
}
