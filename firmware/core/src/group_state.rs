//! What changes while a group runs: each axis's [`State`] with the rotary stage's angle cache
//! ([`GroupState`]) and the engine's counters ([`GroupStats`]). Below [`crate::group`], which
//! re-exports both.

use crate::axis::{AxisName, MAX_AXES};
use crate::error::{GroupError, ImageError};
use crate::rotary::RotaryCache;
use crate::state::State;

/// Everything that changes while a group runs: each axis's [`State`] and the rotary stage's
/// commanded angles and angle cache.
#[derive(Debug, Clone, PartialEq)]
// The rotary stage's fields first (then within the reach of a load's 8-bit scaled offset: the
// paired loads and stores of the commanded angles, the angle terms without a base register).
#[repr(C)]
pub struct GroupState {
    pub(crate) rotary: RotaryCache,
    /// Times the stage's angle terms were recomputed (sin/cos calls / 2).
    pub(crate) angle_refreshes: u32,
    /// Per slot.
    pub axes: [State; MAX_AXES],
}

impl Default for GroupState {
    fn default() -> Self {
        GroupState::new()
    }
}

impl GroupState {
    /// Fresh state for every axis.
    pub const fn new() -> GroupState {
        GroupState {
            axes: [const { State::new() }; MAX_AXES],
            rotary: RotaryCache::NEW,
            angle_refreshes: 0,
        }
    }
    /// Reset every axis ([`State::reset`]) with its counter value at reset; turn positions and the
    /// angle cache restart.
    pub fn reset(&mut self, scale_raw: &[u32; MAX_AXES]) {
        for (s, &r) in self.axes.iter_mut().zip(scale_raw.iter()) {
            s.reset(r);
        }
        self.rotary = RotaryCache::NEW;
    }
    /// A new group image became active ([`State::on_new_image`] for every axis, angle cache
    /// dropped).
    pub fn on_new_image(&mut self) {
        for s in self.axes.iter_mut() {
            s.on_new_image();
        }
        self.rotary = RotaryCache::NEW;
    }
    /// Position within the turn of rotary slot `i` (None before its first cycle or for a
    /// linear slot).
    pub fn turn_position(&self, i: usize) -> Option<u32> {
        self.axes.get(i).and_then(|s| s.turn_in())
    }
    /// How often the stage recomputed sin/cos (once per change of a commanded angle).
    pub fn angle_refreshes(&self) -> u32 {
        self.angle_refreshes
    }
}

/// Counters of a [`GroupEngine`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct GroupStats {
    /// Group cycles run.
    pub cycles: u32,
    /// Group images accepted (A/B swaps).
    pub images_accepted: u32,
    /// Group images rejected (the running one kept).
    pub images_rejected: u32,
    /// Why the last rejected one was rejected (`Option<ImageError>`: `None` is a zero byte, so a
    /// new engine is all zero bytes and a `static` lands in `.bss`).
    pub last_error: Option<ImageError>,
    /// The axis of the last rejection: its code + 1, 0 for none or the group as a whole.
    pub last_error_axis: u8,
}

impl GroupStats {
    /// The last rejection with its axis.
    pub fn last_group_error(&self) -> Option<GroupError> {
        self.last_error.map(|error| GroupError {
            axis: self
                .last_error_axis
                .checked_sub(1)
                .and_then(AxisName::from_code),
            error,
        })
    }
    pub(crate) fn record(&mut self, e: GroupError) {
        self.images_rejected = self.images_rejected.wrapping_add(1);
        self.last_error = Some(e.error);
        self.last_error_axis = e.axis.map_or(0, |a| a.code() + 1);
    }
}
