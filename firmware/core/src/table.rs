//! The positioning table: uniform cubic segments per approach direction, hold or taper beyond
//! the stroke.
//!
//! # Glossary
//! - **knot**: a segment boundary; knot k sits at `start_counts + k·segment_counts`.
//! - **segment**: the interval between two knots, polynomial `[c0, c1, c2, c3]` in Horner form
//!   evaluated at t = (position − knot)/segment_counts in [0, 1) (the image's form).
//! - **remainder**: r = position − knot, counts, in [0, segment_counts). At load each segment's
//!   coefficients are converted to the remainder, `[c0, c1/L, c2/L², c3/L³]` for L =
//!   segment_counts ([`per_count`]): the cycle evaluates c0 + r·(c1' + r·(c2' + r·c3')) with no
//!   multiply by 1/L (work that depends only on the image, done at load).
//! - **stroke**: `[start_counts, start_counts + n·segment_counts)`; beyond it the end value is
//!   held or tapered to 0 over `taper_length_counts`.
//!
//! The stage is a value: its settings [`TableStage`] (read through `&self`, set by the loader),
//! the segments kept where the axis's [`TableStore`] keeps them (passed in as `store`, with the
//! group's coefficient `pool`), and its state [`TableState`] (the segment cache; through
//! `&mut`), one part of the axis's [`crate::State`]. The direction that selects a segment's half
//! is the counter stage's, passed in.

use crate::counts::Direction;
use crate::hint::cold_path;
use crate::spec::OutsideStroke;
use crate::store::TableStore;

/// The table stage's state: the segment cache (see [`TableStage::refill`]).
///
/// The low 32 bits of the extended position where the last cycle's table segment starts, that
/// segment's length while the cache is valid (0: void, the next lookup is a full one; always 0
/// while the counter stage is not primed), for a rotary axis the segment's start within the turn,
/// a copy of its coefficients in the half of the present direction (a reversal voids the cache)
/// and that direction's flag. `#[repr(C)]` in this order: the start and the length side by side
/// (one paired load).
#[derive(Debug, Clone)]
#[repr(C)]
pub(crate) struct TableState {
    pub(crate) seg_start: u32,
    pub(crate) seg_limit: u32,
    pub(crate) seg_turn_start: u32,
    pub(crate) seg_coef: [f32; 4],
    /// [`crate::Flags::BACKWARD`] if the direction was backward when the cache was filled, else
    /// none: while the cache is valid, the direction's flag as a word (no zero-extension of the
    /// direction's byte per axis and cycle).
    pub(crate) seg_flags: u16,
}

impl TableState {
    /// A void cache (all zero bytes).
    pub(crate) const NEW: TableState = TableState {
        seg_start: 0,
        seg_limit: 0,
        seg_turn_start: 0,
        seg_coef: [0.0; 4],
        seg_flags: 0,
    };

    /// The cache voided: the next lookup is a full one.
    #[inline(always)]
    pub(crate) fn void(&mut self) {
        self.seg_limit = 0;
    }

    /// While the cache is valid: the position within the turn of the extended position whose
    /// low 32 bits are `low` (within the cached segment: its start within the turn + the
    /// distance from its start, no wrap); None for a void cache.
    #[inline(always)]
    pub(crate) fn cached_turn(&self, low: u32) -> Option<u32> {
        (self.seg_limit != 0).then(|| {
            self.seg_turn_start
                .wrapping_add(low.wrapping_sub(self.seg_start))
        })
    }
}

/// The settings of the positioning table (validated at load; the segments themselves are kept
/// by the axis's [`TableStore`]).
#[derive(Debug, Clone, Copy)]
#[repr(C)]
pub(crate) struct TableStage {
    pub(crate) bidirectional: bool,
    pub(crate) taper: bool,
    pub(crate) n_segments: u32,
    pub(crate) start_counts: i64,
    /// Knot spacing; `None` = no table (so the division needs no zero check).
    pub(crate) segment: Option<core::num::NonZeroU32>,
    /// n·segment_counts ≤ u32::MAX (validated).
    pub(crate) span_counts: u32,
    pub(crate) taper_counts: u32,
    pub(crate) inv_taper: f32,
    /// `[direction][0 = low end, 1 = high end]` table value at the stroke ends.
    pub(crate) edge: [[f32; 2]; 2],
}

impl TableStage {
    /// No table (all zero bytes).
    pub(crate) const NONE: TableStage = TableStage {
        bidirectional: false,
        taper: false,
        n_segments: 0,
        start_counts: 0,
        segment: None,
        span_counts: 0,
        taper_counts: 0,
        inv_taper: 0.0,
        edge: [[0.0; 2]; 2],
    };

    /// True if a positioning table is loaded.
    pub(crate) fn has_table(&self) -> bool {
        self.segment.is_some()
    }
    /// Knot spacing (0 without a table).
    pub(crate) fn segment_counts(&self) -> u32 {
        self.segment.map_or(0, |s| s.get())
    }
    /// Behaviour beyond the stroke.
    pub(crate) fn outside(&self) -> OutsideStroke {
        if self.taper {
            OutsideStroke::Taper {
                length_counts: self.taper_counts,
            }
        } else {
            OutsideStroke::Hold
        }
    }
    /// Where `position_counts` falls in the table: the segment and the remainder within it, or
    /// outside the stroke, or no table. The caller takes the segment's coefficients from where
    /// the axis keeps them ([`TableStore::segment`]) and evaluates them with [`cubic`]; beyond the
    /// stroke [`TableStage::outside_um`] gives the value. ([`TableStage::value`] does all three;
    /// the single-axis cycle does them itself so that the segment's address is formed from the
    /// compensator's own field, which folds into the loads' offsets.)
    #[inline(always)]
    pub(crate) fn locate(&self, position_counts: i64) -> Lookup {
        let Some(seg_counts) = self.segment else {
            return Lookup::NoTable;
        };
        // One unsigned compare covers both ends: |start| ≤ 2^62 (validated), so a position below
        // the start wraps to a difference ≥ 2^62 > span.
        let diff = position_counts.wrapping_sub(self.start_counts) as u64;
        // span ≤ u32::MAX is validated: a 32-bit compare of the low word once the high word is 0.
        let offset = diff as u32;
        if (diff >> 32) == 0 && offset < self.span_counts {
            let seg = offset / seg_counts;
            let rem = offset - seg.wrapping_mul(seg_counts.get());
            return Lookup::Inside { seg, rem };
        }
        Lookup::Outside
    }

    /// Positioning-table value (µm) at `position_counts` for `direction`, and whether the position
    /// was outside the stroke. 0 without a table. `store`: where the axis keeps its segments,
    /// `pool`: the group's coefficient pool.
    #[inline(always)]
    pub(crate) fn value<S: TableStore>(
        &self,
        store: &S,
        pool: &[[f32; 4]],
        direction: Direction,
        position_counts: i64,
    ) -> (f32, bool) {
        match self.locate(position_counts) {
            Lookup::Inside { seg, rem } => (cubic(store.segment(pool, direction, seg), rem), false),
            Lookup::NoTable => (0.0, false),
            Lookup::Outside => {
                cold_path();
                self.outside_um(direction, position_counts)
            }
        }
    }

    /// Value of the segment cached in `st` (by [`TableStage::refill`]) at the remainder `rem`
    /// (< the segment length): the cubic of [`TableStage::value`].
    #[inline(always)]
    pub(crate) fn cached_um(&self, st: &TableState, rem: u32) -> f32 {
        cubic(&st.seg_coef, rem)
    }

    /// The full lookup of the cycle ([`TableStage::value`] at `table_pos`: the
    /// extended position, or a rotary axis's position within the turn) when the segment cache
    /// of `st` does not hold it, for the direction `dir`, and the cache refilled: valid (the segment's start as the low
    /// 32 bits of the extended position `pos_low` minus the remainder, its start within the
    /// turn, its length and a copy of its coefficients) when `table_pos` is within the stroke
    /// and the segment length is at most 2^31 counts, void otherwise.
    ///
    /// Why the cache is exact: while valid, the last cycle's extended position p lay in the
    /// cached segment, i.e. p − s ∈ [0, L) for the segment's start s in extended counts (its low
    /// 32 bits stored), for the present direction (a reversal voids the cache). This cycle's
    /// position is p + delta with delta an i32 ([`crate::counter::CounterStage::track`]); with
    /// L ≤ 2^31, p + delta − s lies in (−2^31, L + 2^31) ⊂ (−2^31, 2^32), so the wrapping u32 difference
    /// of the low words is below L exactly when the new position is in the same segment — then
    /// it is the remainder the full lookup computes, and the value is the same bit for bit. For
    /// a rotary axis the segment lies within one turn (its grid spans exactly one turn, checked
    /// at load), so inside it the position within the turn is the segment's start within the
    /// turn + that remainder, no wrap ([`crate::State::turn_in`]); the compensator writes it to
    /// the counter stage's turn position ([`TableState::cached_turn`]) whenever the cache is
    /// voided or refilled.
    /// Everything that moves the position otherwise, or changes the table or the direction
    /// ([`crate::State::home`], [`crate::State::reset`], [`crate::State::on_new_image`], a
    /// reversal, a cycle without an image, a fresh state), voids the cache.
    #[cold]
    #[inline(never)]
    pub(crate) fn refill<S: TableStore>(
        &self,
        store: &S,
        pool: &[[f32; 4]],
        st: &mut TableState,
        table_pos: i64,
        pos_low: u32,
        // Last: with the arguments before it, in the stack area of the caller's own arguments
        // (the cache miss's path calls this as its last step, a tail call).
        dir: Direction,
    ) -> (f32, bool) {
        st.seg_limit = 0;
        if let Some(seg_counts) = self.segment {
            let diff = table_pos.wrapping_sub(self.start_counts) as u64;
            let offset = diff as u32;
            if (diff >> 32) == 0 && offset < self.span_counts && seg_counts.get() <= 1 << 31 {
                let seg = offset / seg_counts;
                st.seg_flags = dir.flag();
                st.seg_coef = *store.segment(pool, dir, seg);
                let rem = offset - seg.wrapping_mul(seg_counts.get());
                st.seg_start = pos_low.wrapping_sub(rem);
                st.seg_turn_start = (table_pos as u32).wrapping_sub(rem);
                st.seg_limit = seg_counts.get();
                // The value from the segment just cached: the same remainder and
                // coefficients as the full lookup's, so the same bits (no second search).
                return (self.cached_um(st, rem), false);
            }
        }
        self.value(store, pool, dir, table_pos)
    }

    /// Table value beyond the stroke (hold or taper), for direction half `dir`.
    #[inline(always)]
    pub(crate) fn outside_um(&self, dir: Direction, position_counts: i64) -> (f32, bool) {
        let dir = dir.half();
        // Compare first, then subtract: exact for every i64 without a saturating subtraction.
        let (end, dist) = if position_counts < self.start_counts {
            (
                self.edge[dir][0],
                self.start_counts.wrapping_sub(position_counts) as u64,
            )
        } else {
            let diff = position_counts.wrapping_sub(self.start_counts) as u64;
            (
                self.edge[dir][1],
                diff.wrapping_sub(self.span_counts as u64),
            )
        };
        let v = if !self.taper {
            end
        } else if dist >= self.taper_counts as u64 {
            0.0
        } else {
            end * (1.0 - dist as u32 as f32 * self.inv_taper)
        };
        (v, true)
    }
}

/// Where a position falls in the table ([`TableStage::locate`]).
pub(crate) enum Lookup {
    /// No table is loaded: the value is 0.
    NoTable,
    /// Within the stroke: segment `seg`, `rem` counts from its knot.
    Inside { seg: u32, rem: u32 },
    /// Beyond the stroke: [`TableStage::outside_um`].
    Outside,
}

/// A segment's value at the remainder `rem` (counts from its knot) from its coefficients in the
/// remainder ([`per_count`]): c0 + r·(c1' + r·(c2' + r·c3')), Horner's scheme. One
/// implementation for the full lookup and the segment cache, so both give the same bits.
#[inline(always)]
pub(crate) fn cubic(c: &[f32; 4], rem: u32) -> f32 {
    let r = rem as f32;
    c[0] + r * (c[1] + r * (c[2] + r * c[3]))
}

/// A segment's coefficients `c` in t = r/L ∈ [0, 1) (the image's form) converted to the
/// remainder r in counts, for a segment of L = `segment_counts` (≥ 1) counts:
/// [c0, c1/L, c2/L/L, c3/L/L/L], f32 divisions (exact L up to 2^24 counts), at load, on host and
/// target alike (the same IEEE operations: the same bits; no f64 arithmetic in the firmware for
/// it).
///
/// Why it is as exact as the t form: |r·c_k'| = |t·c_k| term by term, so Horner's scheme in r
/// adds the same magnitudes as in t; the t form rounded t = r·(1/L) once per cycle, this one
/// rounds c_k' one to three times per load (≤ 2e−7 relative). The scaled coefficients stay
/// normal f32 unless |c_k| < 1.2e−38·L^k µm (L ≤ 2^31: below 1e−10 µm for c3), whose
/// contribution is below any count anyway.
pub fn per_count(c: [f32; 4], segment_counts: u32) -> [f32; 4] {
    let l = segment_counts.max(1) as f32;
    [c[0], c[1] / l, c[2] / l / l, c[3] / l / l / l]
}
