//! The group engine ([`GroupEngine`]): two [`Group`] slots (A/B), the group's state and counters,
//! a new image loaded into the spare slot and made active for every axis at once, and the trace
//! records replayed through it.

use crate::axis::{GroupAxisImage, MAX_AXES};
use crate::error::GroupError;
use crate::geometric::GeometricSpec;
use crate::group_cycle::Group;
use crate::group_state::{GroupState, GroupStats};
use crate::io::{GroupInput, GroupOutput};
use crate::rotary_spec::RotaryLocationSpec;
use crate::sensor::ProcessParams;
use crate::trace::{
    OutputRecord, Record, STATUS_IMAGE_ACCEPTED, STATUS_IMAGE_REJECTED, STATUS_NO_IMAGE,
};

/// Two [`Group`] slots (A/B) and the group state: a new group is loaded into the spare slot and
/// becomes active for every axis at once, or not at all (never X new and Y old). All zero bytes
/// when new, so a `static` lands in `.bss`.
#[derive(Debug, Clone)]
pub struct GroupEngine<const POOL: usize> {
    slots: [Group<POOL>; 2],
    active: u8,
    state: GroupState,
    stats: GroupStats,
    process: Option<ProcessParams>,
    pending_status: u8,
}

impl<const POOL: usize> Default for GroupEngine<POOL> {
    fn default() -> Self {
        GroupEngine::new()
    }
}

impl<const POOL: usize> GroupEngine<POOL> {
    /// Identity in both slots, fresh state.
    pub const fn new() -> GroupEngine<POOL> {
        GroupEngine {
            slots: [Group::new(), Group::new()],
            active: 0,
            state: GroupState::new(),
            stats: GroupStats {
                cycles: 0,
                images_accepted: 0,
                images_rejected: 0,
                last_error: None,
                last_error_axis: 0,
            },
            process: None,
            pending_status: 0,
        }
    }

    /// Back to [`GroupEngine::new`] in place.
    pub fn init(&mut self) {
        for s in self.slots.iter_mut() {
            s.clear();
        }
        self.active = 0;
        self.state = GroupState::new();
        self.stats = GroupStats::default();
        self.process = None;
        self.pending_status = 0;
    }

    /// Load a group into the spare slot; on success it becomes active for every axis at once and
    /// the state is told ([`GroupState::on_new_image`]); on error the running group is untouched.
    pub fn load(
        &mut self,
        axes: &[GroupAxisImage],
        stage: Option<&RotaryLocationSpec>,
    ) -> Result<(), GroupError> {
        self.load_stages(axes, stage, None)
    }

    /// [`GroupEngine::load`] with the geometric stage too (see [`Group::load_stages`]).
    pub fn load_stages(
        &mut self,
        axes: &[GroupAxisImage],
        stage: Option<&RotaryLocationSpec>,
        geometric: Option<&GeometricSpec>,
    ) -> Result<(), GroupError> {
        let spare = (self.active ^ 1) as usize & 1;
        match self.slots[spare].load_stages(axes, stage, geometric) {
            Ok(()) => {
                self.active = spare as u8;
                self.state.on_new_image();
                if let Some(p) = self.process {
                    self.slots[spare].set_process(&mut self.state, &p);
                }
                self.stats.images_accepted = self.stats.images_accepted.wrapping_add(1);
                self.pending_status |= STATUS_IMAGE_ACCEPTED;
                Ok(())
            }
            Err(e) => {
                self.stats.record(e);
                self.pending_status |= STATUS_IMAGE_REJECTED;
                Err(e)
            }
        }
    }

    /// [`GroupEngine::load`] from a group image (see [`Group::load_image`]).
    pub fn load_image(&mut self, image: &[u8]) -> Result<(), GroupError> {
        match crate::group_image::parse(image) {
            Ok(view) => {
                let (axes, n) = view.axis_images();
                self.load_stages(&axes[..n], view.rotary.as_ref(), view.geometric.as_ref())
            }
            Err(error) => {
                let e = GroupError { axis: None, error };
                self.stats.record(e);
                self.pending_status |= STATUS_IMAGE_REJECTED;
                Err(e)
            }
        }
    }

    /// Process one trace record (see [`crate::trace`]); for a `GroupCycle` of `n` axes, writes
    /// `n` output records (one per slot, in slot order) into `out` and returns `n`, else 0.
    /// Single-axis `Cycle`, `Temperatures` and `Reset` records are ignored (they are for an
    /// [`crate::Engine`]); `Image` takes a group image or a schema-1 image.
    pub fn step(&mut self, record: &Record, out: &mut [OutputRecord; MAX_AXES]) -> usize {
        match record {
            Record::GroupCycle { n, input } => {
                let n = (*n as usize).clamp(1, MAX_AXES);
                let mut o = GroupOutput::ZERO;
                let a = (self.active as usize) & 1;
                self.slots[a].cycle(&mut self.state, input, &mut o);
                let mut status = self.pending_status;
                if !self.slots[a].is_loaded() {
                    status |= STATUS_NO_IMAGE;
                }
                self.pending_status = 0;
                for (dst, c) in out.iter_mut().zip(o.axes.iter()).take(n) {
                    *dst = OutputRecord {
                        cycle: self.stats.cycles,
                        position_counts: c.position_counts,
                        corrected_command_counts: c.corrected_command_counts,
                        correction_counts: c.correction_counts,
                        correction_um_bits: c.correction_um.to_bits(),
                        flags: c.flags.bits(),
                        slot: a as u8,
                        status,
                    };
                }
                self.stats.cycles = self.stats.cycles.wrapping_add(1);
                n
            }
            Record::AxisTemperatures { slot, t } => {
                self.update_temperatures(*slot as usize, t.now_ms, t.readings());
                0
            }
            Record::Process(p) => {
                self.set_process(p);
                0
            }
            Record::Image(bytes) => {
                let _ = self.load_image(bytes);
                0
            }
            Record::GroupReset { scale_raw, .. } => {
                self.reset(scale_raw);
                0
            }
            Record::Cycle(_)
            | Record::Temperatures(_)
            | Record::Reset { .. }
            | Record::Crc(_)
            | Record::End => 0,
        }
    }

    /// One group cycle with the active group.
    pub fn cycle(&mut self, input: &GroupInput, out: &mut GroupOutput) {
        let a = (self.active as usize) & 1;
        self.slots[a].cycle(&mut self.state, input, out);
        self.stats.cycles = self.stats.cycles.wrapping_add(1);
    }

    /// Sensor-rate update of slot `i` of the active group.
    pub fn update_temperatures(&mut self, i: usize, now_ms: u32, readings: &[f32]) {
        let a = (self.active as usize) & 1;
        self.slots[a].update_temperatures(&mut self.state, i, now_ms, readings);
    }

    /// Process parameters for every axis (kept for later groups).
    pub fn set_process(&mut self, p: &ProcessParams) {
        self.process = Some(*p);
        let a = (self.active as usize) & 1;
        self.slots[a].set_process(&mut self.state, p);
    }

    /// Reset every axis ([`GroupState::reset`]); the process parameters are applied again.
    pub fn reset(&mut self, scale_raw: &[u32; MAX_AXES]) {
        self.state.reset(scale_raw);
        if let Some(p) = self.process {
            let a = (self.active as usize) & 1;
            self.slots[a].set_process(&mut self.state, &p);
        }
    }

    /// The running group.
    pub fn active(&self) -> &Group<POOL> {
        &self.slots[(self.active as usize) & 1]
    }
    /// Index of the running slot (0 = A, 1 = B).
    pub fn active_slot(&self) -> u8 {
        self.active
    }
    /// The group state.
    pub fn state(&self) -> &GroupState {
        &self.state
    }
    /// Mutable group state (e.g. for homing).
    pub fn state_mut(&mut self) -> &mut GroupState {
        &mut self.state
    }
    /// Statistics.
    pub fn stats(&self) -> &GroupStats {
        &self.stats
    }
}
