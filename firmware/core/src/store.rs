//! Where an axis keeps its table segments ([`TableStore`]): in the axis itself ([`OwnTable`], the
//! single-axis compensator) or in the coefficient pool of an axis group ([`PoolTable`]), and where
//! a group pipeline finds that pool ([`PoolSource`]).

use crate::MAX_SEGMENTS;
use crate::MAX_SENSORS;
use crate::counts::Direction;
use crate::sensor::SensorRt;

/// Where a pipeline finds its group's coefficient pool: the pool itself, or the group it is a
/// field of (then its address is formed where it is used, on the cache miss's cold path, and
/// is not held in a register across the inlined pipelines).
pub(crate) trait PoolSource: Copy {
    /// The pool.
    fn pool(&self) -> &[[f32; 4]];
}

impl PoolSource for &[[f32; 4]] {
    #[inline(always)]
    fn pool(&self) -> &[[f32; 4]] {
        self
    }
}

impl<const N: usize> PoolSource for &[[f32; 4]; N] {
    #[inline(always)]
    fn pool(&self) -> &[[f32; 4]] {
        &self[..]
    }
}

/// Where an axis keeps its table segments: `[c0, c1, c2, c3]` per segment and direction half
/// (0 forward, 1 backward; a unidirectional table has its forward segments in both halves).
pub trait TableStore {
    /// Segment `seg` (< the axis's segment count, checked by the caller) of half `dir`; `pool` is
    /// the group's coefficient pool (unused by [`OwnTable`]).
    fn segment<'a>(&'a self, pool: &'a [[f32; 4]], dir: Direction, seg: u32) -> &'a [f32; 4];
    /// True if axes with this storage may be rotary (turn tracking compiled in).
    const TURNS: bool = false;
    /// The sensors' settings kept in the axis itself (see [`crate::AxisCompensator`]'s `thermo`).
    type Sensors: core::fmt::Debug + Clone;
    /// [`TableStore::Sensors`] of the identity (all zero bytes).
    const NO_SENSORS: Self::Sensors;
}

/// The single-axis table storage: forward segments at `0..n`, backward at
/// `MAX_SEGMENTS..MAX_SEGMENTS + n`.
#[derive(Debug, Clone)]
pub struct OwnTable(pub(crate) [[f32; 4]; 2 * MAX_SEGMENTS]);

impl TableStore for OwnTable {
    type Sensors = [SensorRt; MAX_SENSORS];
    const NO_SENSORS: Self::Sensors = [SensorRt::ZERO; MAX_SENSORS];
    #[inline(always)]
    fn segment<'a>(&'a self, _pool: &'a [[f32; 4]], dir: Direction, seg: u32) -> &'a [f32; 4] {
        // (The direction's byte, 0 or 128, times MAX_SEGMENTS / 128: the backward half's offset.)
        const _: () = assert!(MAX_SEGMENTS % 128 == 0);
        let half = dir as u8 as usize * (MAX_SEGMENTS / 128);
        &self.0[(seg as usize + half) & (2 * MAX_SEGMENTS - 1)]
    }
}

/// A group axis's table in the group's pool: the first segment of each direction half.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PoolTable {
    pub(crate) base: [u32; 2],
}

const ZERO_SEGMENT: [f32; 4] = [0.0; 4];

impl TableStore for PoolTable {
    const TURNS: bool = true;
    // In `Group::sensors`.
    type Sensors = ();
    const NO_SENSORS: () = ();
    #[inline(always)]
    fn segment<'a>(&'a self, pool: &'a [[f32; 4]], dir: Direction, seg: u32) -> &'a [f32; 4] {
        // In range for a loaded group (checked at load). The remainder is a no-op for valid
        // indices; with the pool's length known at the call (a power of two), it is a mask and
        // the bounds check folds away. The fallbacks keep the path panic-free.
        let i = self.base[dir.half()] as usize + seg as usize;
        i.checked_rem(pool.len())
            .and_then(|j| pool.get(j))
            .unwrap_or(&ZERO_SEGMENT)
    }
}
