//! The positioning table: uniform cubic segments per approach direction, hold or taper beyond
//! the stroke.
//!
//! # Glossary
//! - **knot**: a segment boundary; knot k sits at `start_counts + k·segment_counts`.
//! - **segment**: the interval between two knots, polynomial `[c0, c1, c2, c3]` in Horner form
//!   evaluated at t = (position − knot)/segment_counts in [0, 1).
//! - **stroke**: `[start_counts, start_counts + n·segment_counts)`; beyond it the end value is
//!   held or tapered to 0 over `taper_length_counts`.

use crate::MAX_SEGMENTS;
use crate::compensator::{AxisCompensator, Compensator, TableStore};
use crate::counter::Direction;
use crate::limits::cold_path;
use crate::spec::OutsideStroke;

impl<S: TableStore> AxisCompensator<S> {
    /// True if a positioning table is loaded.
    pub fn has_table(&self) -> bool {
        self.segment.is_some()
    }
    /// Position of knot 0.
    pub fn table_start_counts(&self) -> i64 {
        self.start_counts
    }
    /// Knot spacing.
    pub fn segment_counts(&self) -> u32 {
        self.segment.map_or(0, |s| s.get())
    }
    /// Behaviour beyond the stroke.
    pub fn outside(&self) -> OutsideStroke {
        if self.taper {
            OutsideStroke::Taper {
                length_counts: self.taper_counts,
            }
        } else {
            OutsideStroke::Hold
        }
    }
    /// Positioning-table value (µm) at `position_counts` for `direction`, and whether the position
    /// was outside the stroke. 0 without a table. `pool`: the group's coefficient pool.
    #[inline(always)]
    pub fn table_um_in(
        &self,
        pool: &[[f32; 4]],
        direction: Direction,
        position_counts: i64,
    ) -> (f32, bool) {
        let Some(seg_counts) = self.segment else {
            return (0.0, false);
        };
        // A unidirectional table has its forward segments in the backward half too (see `load`).
        let dir = (direction == Direction::Backward) as usize;
        // One unsigned compare covers both ends: |start| ≤ 2^62 (validated), so a position below
        // the start wraps to a difference ≥ 2^62 > span.
        let diff = position_counts.wrapping_sub(self.start_counts) as u64;
        // span ≤ u32::MAX is validated: a 32-bit compare of the low word once the high word is 0.
        let offset = diff as u32;
        if (diff >> 32) == 0 && offset < self.span_counts {
            let seg = offset / seg_counts;
            let rem = offset - seg.wrapping_mul(seg_counts.get());
            let t = rem as f32 * self.inv_segment;
            let c = self.table.segment(pool, dir, seg);
            return (c[0] + t * (c[1] + t * (c[2] + t * c[3])), false);
        }
        cold_path();
        self.outside_um(dir, position_counts)
    }

    /// [`AxisCompensator::table_um_in`] at the position within the turn `turn` of a rotary group
    /// axis. Its table grid starts at 0 (validated at load: a rotary axis's knot 0 is at 0 and its
    /// stroke is one turn), so the 64-bit difference to the start and the test of its high word
    /// are not needed: the same segment, the same arithmetic, the same value.
    #[inline(always)]
    pub(crate) fn table_um_turn(
        &self,
        pool: &[[f32; 4]],
        direction: Direction,
        turn: u32,
    ) -> (f32, bool) {
        let Some(seg_counts) = self.segment else {
            return (0.0, false);
        };
        let dir = (direction == Direction::Backward) as usize;
        if turn < self.span_counts {
            let seg = turn / seg_counts;
            let rem = turn - seg.wrapping_mul(seg_counts.get());
            let t = rem as f32 * self.inv_segment;
            let c = self.table.segment(pool, dir, seg);
            return (c[0] + t * (c[1] + t * (c[2] + t * c[3])), false);
        }
        // Only after a misuse (a turn position of another turn length); the general rules.
        cold_path();
        self.table_um_in(pool, direction, turn as i64)
    }

    /// Table value beyond the stroke (hold or taper), for direction half `dir`.
    #[inline(always)]
    fn outside_um(&self, dir: usize, position_counts: i64) -> (f32, bool) {
        let dir = dir & 1;
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

impl Compensator {
    /// Forward segments (empty without a table).
    pub fn forward_segments(&self) -> &[[f32; 4]] {
        let n = (self.n_segments as usize).min(MAX_SEGMENTS);
        self.table.0.get(..n).unwrap_or(&[])
    }
    /// Backward segments (empty for a unidirectional table).
    pub fn backward_segments(&self) -> &[[f32; 4]] {
        let n = if self.bidirectional {
            (self.n_segments as usize).min(MAX_SEGMENTS)
        } else {
            0
        };
        self.table
            .0
            .get(MAX_SEGMENTS..MAX_SEGMENTS + n)
            .unwrap_or(&[])
    }
}
