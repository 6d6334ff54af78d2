//! The validated runtime object ([`Compensator`]), its per-axis [`State`] and the per-cycle call.
//!
//! Coefficients live in `&self` (loaded once from an image), everything that changes per cycle or
//! per sensor reading lives in `&mut State`. The per-cycle path ([`Compensator::cycle`]) uses no
//! i64 multiplication/division and no i64↔f32 conversion, indexes arrays through masks or
//! validated indices and never panics.
//!
//! The stages it composes live by what they are: [`crate::counter`] (counter extension,
//! direction), [`crate::table`] (positioning table), [`crate::thermo`] (thermo-force term),
//! [`crate::limits`] (clamp, slew, rounding to counts).

use crate::ImageError;
use crate::counts::{CounterShift, Direction};
use crate::hint::cold_path;
use crate::io::{CycleInput, CycleOutput, Flags};
use crate::runtime::{AxisCompensator, Compensator, OwnTable, PoolSource, State, TableStore};
use crate::sensor::MeasuredSet;
use crate::spec::LimitSpec;
use crate::{MAX_FORCES, MAX_SEGMENTS};

impl Default for Compensator {
    fn default() -> Self {
        Compensator::IDENTITY
    }
}

impl Compensator {
    /// Zero correction, valid. All zero bytes.
    pub const IDENTITY: Compensator =
        AxisCompensator::identity_with(OwnTable([[0.0; 4]; 2 * MAX_SEGMENTS]));

    /// Parse and validate `image`, then copy it into `self`. On `Err`, `self` is untouched.
    ///
    /// Works in place: no copy of the table on the stack. `image` must be exactly the image:
    /// bytes after its declared length are refused ([`ImageError::TrailingBytes`]; cut an image
    /// out of a flash slot with [`crate::declared_image_len`]).
    pub fn load(&mut self, image: &[u8]) -> Result<(), ImageError> {
        let layout = crate::image::validate(image)?;
        if image.len() > layout.len {
            return Err(ImageError::TrailingBytes);
        }
        crate::image::copy_into(&layout, image, self);
        Ok(())
    }

    /// The per-cycle call: counter extension, direction, table + thermo-force, clamp, slew, counts.
    ///
    /// See [`AxisCompensator::cycle_in`] (the same call for an axis of a group).
    pub fn cycle(&self, st: &mut State, input: &CycleInput) -> CycleOutput {
        self.cycle_in(&[], st, input)
    }

    /// Positioning-table value (µm) at `position_counts` for `direction`, and whether the position
    /// was outside the stroke. 0 without a table.
    #[inline]
    pub fn table_um(&self, direction: Direction, position_counts: i64) -> (f32, bool) {
        self.table_um_in(&[], direction, position_counts)
    }
}

impl<S: TableStore> AxisCompensator<S> {
    /// Back to the identity (in place, no large temporary).
    pub fn clear(&mut self) {
        self.loaded = false;
        self.segment = None;
        self.has_thermo = false;
        self.n_segments = 0;
        self.n_sensors = 0;
        self.n_forces = 0;
        self.chi_um_per_n = [0.0; MAX_FORCES];
        self.force_predicted = [false; MAX_FORCES];
        self.measured_mask = 0;
        self.chi_measured = [0.0; MAX_FORCES];
        self.measured = MeasuredSet::None;
        self.thermo_flags_xor = 0;
        self.axis_id = 0;
        self.counter_bits = 0;
        self.sext_shift = CounterShift::S0;
        self.um_per_count = 0.0;
        self.counts_per_rev = 0;
        self.half_um_per_count = 0.0;
        self.fast_max_key = 0;
    }

    /// True once an image has been loaded (false for the identity).
    pub fn is_loaded(&self) -> bool {
        self.loaded
    }
    /// Axis the loaded image belongs to (0 for the identity).
    pub fn axis_id(&self) -> u16 {
        self.axis_id
    }
    /// Scale resolution (0 for the identity).
    pub fn um_per_count(&self) -> f32 {
        self.um_per_count
    }
    /// Counter width (0 for the identity, which extends a 32-bit counter).
    pub fn counter_bits(&self) -> u8 {
        self.counter_bits
    }
    /// The limits (all 0 for the identity).
    pub fn limits(&self) -> LimitSpec {
        LimitSpec {
            max_correction_um: self.max_correction_um,
            max_slew_um_per_cycle: self.max_slew_um_per_cycle(),
            direction_hysteresis_counts: self.hysteresis_counts,
        }
    }
    /// The per-cycle call: counter extension, direction, table + thermo-force, clamp, slew, counts.
    ///
    /// No library calls, no i64 multiplication/division, no i64↔f32 conversion, no panic path.
    /// Cost on a Cortex-M4F (QEMU count by `.ci/bench`, firmware bin `axcomp-qemu-bench`): about
    /// 118 instructions for the [`crate::bench`] workload (table + 8-sensor thermo-force + 3
    /// forces), about 85 with the table only. The common case is laid out as the fall-through
    /// (the rare branches — first cycle, clamp/slew acting, command near ±2^63 — are marked
    /// cold) and is sensitive to register pressure: measure any change with `.ci/bench`.
    ///
    /// The thermo-force term adds the contribution cached by [`AxisCompensator::update_temperatures`]
    /// and [`AxisCompensator::set_process`] (b0 + Σ b_i·ΔT_i + predicted forces), the expansion term
    /// (one multiply-add with the cached c·ΔT_s) and the measured forces of this input.
    #[inline(always)]
    pub fn cycle_in(&self, pool: &[[f32; 4]], st: &mut State, input: &CycleInput) -> CycleOutput {
        let (pos, delta) = self.track(st, input.scale_raw);
        if !self.loaded {
            // No table follows the position here: the segment cache is void.
            if S::TURNS {
                st.settle_turn((pos as u32).wrapping_sub(delta as u32));
            }
            st.seg_limit = 0;
            return CycleOutput {
                position_counts: pos,
                corrected_command_counts: input.command_counts,
                correction_counts: 0,
                correction_um: 0.0,
                flags: Flags(st.direction.with_flag(Flags::IDENTITY.0)),
            };
        }
        let (pos, total, flags) = self.axis_error_um(
            pool,
            st,
            (pos, delta),
            input.scale_raw,
            &input.forces_n,
            None,
            None,
            false,
        );
        self.finish(st, pos, total, input.command_counts, flags)
    }

    /// Table (at the extended position, or a rotary axis's position within the turn) +
    /// thermo-force term (at the extended position), µm before the limits, and
    /// the cycle's flags so far (BACKWARD, TABLE_OUTSIDE, thermo flags), with the extended
    /// position. `(pos, delta)` is what [`AxisCompensator::track`] returned this cycle with the
    /// counter value `raw`; with `segment_cache`, what [`AxisCompensator::track_primed`]
    /// returned: on a state that was not primed (its segment cache is void) the cache miss's
    /// path replaces it by what `track` computes ([`AxisCompensator::track_unprimed`]), so the
    /// returned position is the one to use. (Nine arguments: the hot path takes its
    /// compile-time choices as plain arguments that inlining folds away, not as a struct.)
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(crate) fn axis_error_um(
        &self,
        pool: impl PoolSource,
        st: &mut State,
        (mut pos, delta): (i64, i32),
        raw: u32,
        forces_n: &[f32; MAX_FORCES],
        rotary_known: Option<bool>,
        thermo_known: Option<bool>,
        segment_cache: bool,
    ) -> (i64, f32, Flags) {
        // `rotary_known`, `thermo_known` and `segment_cache` are constants at each call: where
        // the caller knows whether the axis is rotary (a group's pipelines: its kind, set at
        // load from the same counts per revolution) or has a thermo-force term, the check is
        // compiled out.
        let rotary = S::TURNS && rotary_known.unwrap_or(self.counts_per_rev != 0);
        // With `segment_cache` (the group's pipelines), the table through the segment cache (see
        // [`AxisCompensator::table_um_refill`]): within the last cycle's segment, the remainder
        // from the segment's start and the cached coefficients; otherwise the full lookup, which
        // refills the cache.
        // Without it (the single-axis call, whose reference workload crosses a 1000-count
        // segment every 6.4 cycles: there the refills cost more than the cache saves), the full
        // lookup every cycle. Both give the same value bit for bit.
        let r = (pos as u32).wrapping_sub(st.seg_start);
        // BACKWARD is bit 7, TABLE_OUTSIDE bit 0; each path builds the flags after its lookup
        // (the cached ones know TABLE_OUTSIDE is clear), so that no flag register is live
        // across it.
        // (The cached paths: the direction's flag as the refill stored it; the cache is voided
        // on a reversal.)
        let backward = |st: &State| Flags(st.seg_flags);
        let with_outside = |st: &State, (v, outside): (f32, bool)| {
            (v, Flags(st.direction.with_flag(outside as u16)))
        };
        let (mut total, mut flags) = if !segment_cache {
            if rotary {
                let turn = self.turn_position(st, pos, delta);
                let v = self.table_um_in(pool.pool(), st.direction(), turn as i64);
                with_outside(st, v)
            } else {
                let v = self.table_um_in(pool.pool(), st.direction(), pos);
                with_outside(st, v)
            }
        } else if rotary {
            if r < st.seg_limit {
                // Within one segment of the turn (no wrap): the turn position is the segment's
                // start within the turn + r, not stored (see `State::turn_in`).
                (self.segment_um_cached(st, r), backward(st))
            } else {
                cold_path();
                let v = self.table_um_miss::<true>(pool.pool(), st, pos, delta, raw);
                // (Redone by the miss path on a state that was not primed.)
                pos = st.position;
                with_outside(st, v)
            }
        } else if r < st.seg_limit {
            (self.segment_um_cached(st, r), backward(st))
        } else {
            cold_path();
            let v = self.table_um_miss::<false>(pool.pool(), st, pos, delta, raw);
            pos = st.position;
            with_outside(st, v)
        };
        if thermo_known.unwrap_or(self.has_thermo) {
            total = self.thermo_um(st, pos, forces_n, &mut flags, total);
        }
        (pos, total, flags)
    }
}
