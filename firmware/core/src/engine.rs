//! The replay engine: two [`Compensator`] slots (A/B), the axis [`State`] and statistics.
//!
//! The QEMU firmware and the host replay both feed trace records to [`Engine::step`], so their
//! output records are bit-identical.

use crate::trace::{
    OutputRecord, Record, STATUS_IMAGE_ACCEPTED, STATUS_IMAGE_REJECTED, STATUS_NO_IMAGE,
};
use crate::{Compensator, ImageError, ProcessParams, State};

/// Counters of an [`Engine`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct EngineStats {
    /// Cycle records processed.
    pub cycles: u32,
    /// Temperature records processed.
    pub temperature_updates: u32,
    /// Images accepted (A/B swaps).
    pub images_accepted: u32,
    /// Images rejected (the running one kept).
    pub images_rejected: u32,
    /// Why the last rejected image was rejected.
    pub last_image_error: Option<ImageError>,
}

/// Two compensator slots + state + statistics. Large (two tables): build it with the `const`
/// [`Engine::new`] in a `static` (all zero bytes → `.bss`) or reset one in place with
/// [`Engine::init`].
#[derive(Debug, Clone)]
pub struct Engine {
    slots: [Compensator; 2],
    active: u8,
    state: State,
    stats: EngineStats,
    pending_status: u8,
    process: Option<ProcessParams>,
}

impl Default for Engine {
    fn default() -> Self {
        Engine::new()
    }
}

impl Engine {
    /// Identity in slot A (active), identity in slot B, fresh state.
    pub const fn new() -> Engine {
        Engine {
            slots: [Compensator::IDENTITY, Compensator::IDENTITY],
            active: 0,
            state: State::new(),
            stats: EngineStats {
                cycles: 0,
                temperature_updates: 0,
                images_accepted: 0,
                images_rejected: 0,
                last_image_error: None,
            },
            pending_status: 0,
            process: None,
        }
    }

    /// Back to [`Engine::new`] in place (no large temporary on the stack).
    pub fn init(&mut self) {
        for s in self.slots.iter_mut() {
            s.clear();
        }
        self.active = 0;
        self.state = State::new();
        self.stats = EngineStats::default();
        self.pending_status = 0;
        self.process = None;
    }

    /// Load `image` into the spare slot; on success it becomes active (A/B swap), the state is
    /// told ([`State::on_new_image`]) and the last process parameters are applied to it. On
    /// error the running slot is untouched.
    pub fn load_image(&mut self, image: &[u8]) -> Result<(), ImageError> {
        let spare = (self.active ^ 1) as usize & 1;
        match self.slots[spare].load(image) {
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
                self.stats.images_rejected = self.stats.images_rejected.wrapping_add(1);
                self.stats.last_image_error = Some(e);
                self.pending_status |= STATUS_IMAGE_REJECTED;
                Err(e)
            }
        }
    }

    /// Process one record; `Some` for `Cycle` records.
    pub fn step(&mut self, record: &Record) -> Option<OutputRecord> {
        let a = (self.active as usize) & 1;
        match record {
            Record::Cycle(input) => {
                let out = self.slots[a].cycle(&mut self.state, input);
                let mut status = self.pending_status;
                if !self.slots[a].is_loaded() {
                    status |= STATUS_NO_IMAGE;
                }
                self.pending_status = 0;
                let rec = OutputRecord {
                    cycle: self.stats.cycles,
                    position_counts: out.position_counts,
                    corrected_command_counts: out.corrected_command_counts,
                    correction_counts: out.correction_counts,
                    correction_um_bits: out.correction_um.to_bits(),
                    flags: out.flags.bits(),
                    slot: a as u8,
                    status,
                };
                self.stats.cycles = self.stats.cycles.wrapping_add(1);
                Some(rec)
            }
            Record::Temperatures(t) => {
                self.slots[a].update_temperatures(&mut self.state, t.now_ms, t.readings());
                self.stats.temperature_updates = self.stats.temperature_updates.wrapping_add(1);
                None
            }
            Record::Process(p) => {
                self.process = Some(*p);
                self.slots[a].set_process(&mut self.state, p);
                None
            }
            Record::Image(bytes) => {
                let _ = self.load_image(bytes);
                None
            }
            Record::Reset { scale_raw } => {
                self.state.reset(*scale_raw);
                if let Some(p) = self.process {
                    self.slots[a].set_process(&mut self.state, &p);
                }
                None
            }
            // Group records are for a `GroupEngine`.
            Record::GroupCycle { .. }
            | Record::AxisTemperatures { .. }
            | Record::GroupReset { .. }
            | Record::Crc(_)
            | Record::End => None,
        }
    }

    /// The running compensator.
    pub fn active(&self) -> &Compensator {
        &self.slots[(self.active as usize) & 1]
    }
    /// Index of the running slot (0 = A, 1 = B).
    pub fn active_slot(&self) -> u8 {
        self.active
    }
    /// The axis state.
    pub fn state(&self) -> &State {
        &self.state
    }
    /// Mutable axis state (e.g. for homing).
    pub fn state_mut(&mut self) -> &mut State {
        &mut self.state
    }
    /// Statistics.
    pub fn stats(&self) -> &EngineStats {
        &self.stats
    }
}
