//! The validated runtime object ([`Compensator`]), its per-axis [`State`] and the per-cycle call.
//!
//! Coefficients live in `&self` (loaded once from an image), everything that changes per cycle or
//! per sensor reading lives in `&mut State`. The per-cycle path ([`Compensator::cycle`]) uses no
//! i64 multiplication/division and no i64↔f32 conversion, indexes arrays through masks or
//! validated indices and never panics.
//!
//! The stages it composes are values held in the compensator's fields, each defined by what it is
//! and naming neither the compensator nor another stage: `counter` ([`crate::counter`]: counter
//! extension, direction), `table` ([`crate::table`]: positioning table, with the segments in
//! `segments`), `thermo` ([`crate::thermo`]: thermo-force term), `limits` ([`crate::limits`]:
//! clamp, slew, rounding to counts). [`AxisCompensator::cycle_in`] calls them in that order,
//! passing each its own part of the axis's `State` (`st.counter`, `st.table`, `st.thermo`,
//! `st.limits`); the few steps that need two stages (a reversal voiding the segment cache:
//! [`crate::state::on_reversal`]; the segment cache's miss path: counter extension redone, turn
//! position, table refill in the counter's direction) are composed here and in [`crate::state`].
//! The accessors of the stages' settings are here as the compensator's public API.

use crate::ImageError;
use crate::counts::{CounterShift, Direction};
use crate::hint::cold_path;
use crate::io::{CycleInput, CycleOutput, Flags};
use crate::runtime::{AxisCompensator, Compensator, OwnTable, PoolSource, TableStore};
use crate::sensor::{ForceSource, ProcessParams, SensorRt};
use crate::spec::{
    ExpansionSpec, ForceSpec, LimitSpec, OutsideStroke, SensorSpec, ThermoReference,
};
use crate::state::{State, on_reversal};
use crate::table::{Lookup, cubic};
use crate::{MAX_FORCES, MAX_SEGMENTS, MAX_SENSORS};

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

    /// Forward segments (empty without a table), as the cycle evaluates them: coefficients in
    /// the remainder r (counts from the knot), c0 + r·(c1 + r·(c2 + r·c3)) — the image's
    /// coefficients in t = r/L divided by L^k at load (see the module's glossary).
    pub fn forward_segments(&self) -> &[[f32; 4]] {
        let n = (self.table.n_segments as usize).min(MAX_SEGMENTS);
        self.segments.0.get(..n).unwrap_or(&[])
    }
    /// Backward segments (empty for a unidirectional table), in the form of
    /// [`Compensator::forward_segments`].
    pub fn backward_segments(&self) -> &[[f32; 4]] {
        let n = if self.table.bidirectional {
            (self.table.n_segments as usize).min(MAX_SEGMENTS)
        } else {
            0
        };
        self.segments
            .0
            .get(MAX_SEGMENTS..MAX_SEGMENTS + n)
            .unwrap_or(&[])
    }

    /// Settings of sensor `i`.
    pub fn sensor(&self, i: usize) -> Option<SensorSpec> {
        self.thermo.sensor(i)
    }
    /// b_i of sensor `i`, µm/K.
    pub fn b_um_per_k(&self, i: usize) -> Option<f32> {
        self.thermo.b_um_per_k(i)
    }
    /// Rise bounds `(rise_min_k, rise_max_k)` of sensor `i`'s range guard (None without the
    /// guard or sensor).
    pub fn rise_bounds_k(&self, i: usize) -> Option<(f32, f32)> {
        self.thermo.rise_bounds_k(i)
    }
    /// Lag coefficient α of sensor `i` (1 = no lag).
    pub fn lag_alpha(&self, i: usize) -> Option<f32> {
        self.thermo.lag_alpha(i)
    }
    /// Sensor-rate update: health checks, lags, and the cached thermal contribution.
    ///
    /// `readings[i]` is sensor i in °C; NaN (or a missing entry) = no reading. Call it every
    /// `sensor_period_ms` (the lag coefficients assume that period), also when the image has no
    /// sensors: the cycle adds a cached b0 + Σ b_i·ΔT_i + Σ χ_j·F_j(predicted), refreshed here
    /// and in [`AxisCompensator::set_process`] (a fresh [`State`] contributes 0 until then). Rules:
    /// - a reading is accepted if finite, within `[min_degc, max_degc]` and, after the first
    ///   accepted one, within `max_rate_degc_per_s · (now − time of the last accepted reading)` of
    ///   the last accepted value; otherwise it is rejected (counted) and the last good value held;
    /// - ΔT is taken against the sensor's `reference_degc`, or, with the reference at switch-on
    ///   ([`crate::ThermoReference::SwitchOn`]), against its first accepted reading since the
    ///   image was loaded or the state reset (ΔT then starts at 0);
    /// - each lag advances once per call with the last accepted value as input; it starts at the
    ///   first accepted reading (no transient from 0);
    /// - with the range guard, a sensor whose unlagged rise (last accepted value − its reference)
    ///   is outside its rise bounds is left out of Σ b_i·ΔT_i ([`Flags::THERMAL_GUARDED`]); it
    ///   stays healthy and its lag keeps running;
    /// - a sensor without an accepted reading for more than `stale_timeout_ms` (counted from the
    ///   first call for a sensor that never reported) is stale; it recovers after
    ///   [`crate::RECOVERY_READINGS`] consecutive accepted readings;
    /// - the thermal contribution (Σ b_i·ΔT_i and the expansion coefficient) is recomputed only
    ///   while every sensor has reported and none is stale; otherwise it stays frozen at the last
    ///   good value (THERMAL_FROZEN); SENSOR_FAULT while any sensor is stale or its last reading
    ///   was rejected.
    pub fn update_temperatures(&self, st: &mut State, now_ms: u32, readings: &[f32]) {
        self.update_temperatures_with(&self.thermo.sensors, st, now_ms, readings);
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
        self.table.segment = None;
        self.table.n_segments = 0;
        self.thermo.reset();
        self.axis_id = 0;
        self.counter.counter_bits = 0;
        self.counter.sext_shift = CounterShift::S0;
        self.limits.um_per_count = 0.0;
        self.counts_per_rev = 0;
        self.limits.half_um_per_count = 0.0;
        self.limits.fast_max_key = 0;
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
        self.limits.um_per_count
    }
    /// Counter width (0 for the identity, which extends a 32-bit counter).
    pub fn counter_bits(&self) -> u8 {
        self.counter.counter_bits
    }
    /// The limits (all 0 for the identity).
    pub fn limits(&self) -> LimitSpec {
        LimitSpec {
            max_correction_um: self.limits.max_correction_um,
            max_slew_um_per_cycle: self.limits.max_slew_um_per_cycle(),
            direction_hysteresis_counts: self.counter.hysteresis_counts,
        }
    }
    /// True if a positioning table is loaded.
    pub fn has_table(&self) -> bool {
        self.table.has_table()
    }
    /// Position of knot 0.
    pub fn table_start_counts(&self) -> i64 {
        self.table.start_counts
    }
    /// Knot spacing.
    pub fn segment_counts(&self) -> u32 {
        self.table.segment_counts()
    }
    /// Behaviour beyond the stroke.
    pub fn outside(&self) -> OutsideStroke {
        self.table.outside()
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
        // The stage's `value`, with the segment taken from the field here (see
        // `TableStage::locate`).
        // A unidirectional table has its forward segments in the backward half too (see `load`).
        match self.table.locate(position_counts) {
            Lookup::Inside { seg, rem } => {
                let c = self.segments.segment(pool, direction, seg);
                (cubic(c, rem), false)
            }
            Lookup::NoTable => (0.0, false),
            Lookup::Outside => {
                cold_path();
                self.table.outside_um(direction, position_counts)
            }
        }
    }

    /// True if a thermo-force term is loaded.
    pub fn has_thermo(&self) -> bool {
        self.thermo.has_thermo()
    }
    /// Sensor period of the thermo-force term, ms.
    pub fn sensor_period_ms(&self) -> u32 {
        self.thermo.sensor_period_ms()
    }
    /// Number of sensors.
    pub fn sensor_count(&self) -> usize {
        self.thermo.sensor_count()
    }
    /// Constant term b0, µm.
    pub fn b0_um(&self) -> f32 {
        self.thermo.b0_um()
    }
    /// The expansion term, if any.
    pub fn expansion(&self) -> Option<ExpansionSpec> {
        self.thermo.expansion()
    }
    /// What each ΔT is taken against.
    pub fn thermo_reference(&self) -> ThermoReference {
        self.thermo.thermo_reference()
    }
    /// True if the image has the range guard (per-sensor rise bounds).
    pub fn has_rise_guard(&self) -> bool {
        self.thermo.has_rise_guard()
    }
    /// Number of force terms.
    pub fn force_count(&self) -> usize {
        self.thermo.force_count()
    }
    /// Force term `j`.
    pub fn force(&self, j: usize) -> Option<ForceSpec> {
        self.thermo.force(j)
    }
    /// Where force `j` comes from.
    pub fn force_source(&self, j: usize) -> Option<ForceSource> {
        self.thermo.force_source(j)
    }
    /// Predicted forces from the process parameters (F = k·ap^x·fz^y·n^z via `libm::powf`),
    /// computed here only. A non-finite or implausible prediction is replaced by 0 N and flagged
    /// (FORCE_INVALID) until the next call.
    pub fn set_process(&self, st: &mut State, p: &ProcessParams) {
        self.thermo.set_process(self.loaded, &mut st.thermo, p);
    }
    /// [`Compensator::update_temperatures`] with the sensors' settings `cfgs` (the axis's
    /// own, or its group's array: [`crate::group::Group::update_temperatures`]).
    pub(crate) fn update_temperatures_with(
        &self,
        cfgs: &[SensorRt; MAX_SENSORS],
        st: &mut State,
        now_ms: u32,
        readings: &[f32],
    ) {
        if self.loaded {
            self.thermo
                .update_temperatures(cfgs, &mut st.thermo, now_ms, readings);
        }
    }
    /// The thermo-force stage ([`crate::thermo::ThermoForceStage::thermo_um`]).
    #[inline(always)]
    pub(crate) fn thermo_um(
        &self,
        st: &State,
        pos: i64,
        forces_n: &[f32; MAX_FORCES],
        flags: &mut Flags,
        total: f32,
    ) -> f32 {
        self.thermo
            .thermo_um(&st.thermo, pos, forces_n, flags, total)
    }

    /// The counter stage ([`crate::counter::CounterStage::track`]) for this storage: with turn
    /// tracking where the axis may be rotary.
    #[inline(always)]
    pub(crate) fn track(&self, st: &mut State, raw: u32) -> (i64, i32) {
        let (counter, table) = (&mut st.counter, &mut st.table);
        if S::TURNS {
            self.counter
                .track::<true>(counter, raw, on_reversal::<true>(table))
        } else {
            self.counter
                .track::<false>(counter, raw, on_reversal::<false>(table))
        }
    }

    /// [`crate::counter::CounterStage::track_primed`] for this storage (see
    /// [`AxisCompensator::track`]).
    #[inline(always)]
    pub(crate) fn track_primed(&self, st: &mut State, raw: u32) -> (i64, i32) {
        let (counter, table) = (&mut st.counter, &mut st.table);
        if S::TURNS {
            self.counter
                .track_primed::<true>(counter, raw, on_reversal::<true>(table))
        } else {
            self.counter
                .track_primed::<false>(counter, raw, on_reversal::<false>(table))
        }
    }

    /// [`crate::counter::CounterStage::track_unprimed`] for this storage (see
    /// [`AxisCompensator::track`]).
    #[inline(always)]
    pub(crate) fn track_unprimed(&self, st: &mut State, raw: u32, delta: i32) -> (i64, i32) {
        let (counter, table) = (&mut st.counter, &mut st.table);
        if S::TURNS {
            self.counter
                .track_unprimed::<true>(counter, raw, delta, on_reversal::<true>(table))
        } else {
            self.counter
                .track_unprimed::<false>(counter, raw, delta, on_reversal::<false>(table))
        }
    }

    /// [`crate::counter::CounterStage::turn_position`] with this axis's counts per revolution.
    #[inline(always)]
    pub(crate) fn turn_position(&self, st: &mut State, pos: i64, delta: i32) -> u32 {
        self.counter
            .turn_position(&mut st.counter, self.counts_per_rev, pos, delta)
    }

    /// The segment cache's miss path of the group pipelines (one out-of-line call): on a state
    /// that was not primed, the counter extension redone ([`AxisCompensator::track_unprimed`]:
    /// the caller reads the extended position back from `st`); for a rotary axis (`ROTARY`) the
    /// last cycle's turn position settled from the cache (if it held it) and followed by this
    /// cycle's step; then [`crate::table::TableStage::refill`] at the table position. `(pos,
    /// delta)` is what [`AxisCompensator::track_primed`] returned with the counter value `raw`.
    #[cold]
    #[inline(never)]
    pub(crate) fn table_um_miss<const ROTARY: bool>(
        &self,
        pool: &[[f32; 4]],
        st: &mut State,
        mut pos: i64,
        mut delta: i32,
        raw: u32,
    ) -> (f32, bool) {
        if !st.counter.primed {
            (pos, delta) = self.track_unprimed(st, raw, delta);
        }
        let dir = st.counter.direction;
        if ROTARY {
            st.settle_turn((pos as u32).wrapping_sub(delta as u32));
            let turn = self.turn_position(st, pos, delta);
            self.table.refill(
                &self.segments,
                pool,
                &mut st.table,
                turn as i64,
                pos as u32,
                dir,
            )
        } else {
            self.table
                .refill(&self.segments, pool, &mut st.table, pos, pos as u32, dir)
        }
    }

    /// The limits stage ([`crate::limits::LimitStage::finish`]): the last stage of the axis.
    #[inline(always)]
    pub(crate) fn finish(
        &self,
        st: &mut State,
        pos: i64,
        total: f32,
        command: i64,
        flags: Flags,
    ) -> CycleOutput {
        self.limits
            .finish(&mut st.limits, pos, total, command, flags)
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
            st.table.void();
            return CycleOutput {
                position_counts: pos,
                corrected_command_counts: input.command_counts,
                correction_counts: 0,
                correction_um: 0.0,
                flags: Flags(st.counter.direction.with_flag(Flags::IDENTITY.0)),
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
        self.limits
            .finish(&mut st.limits, pos, total, input.command_counts, flags)
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
        // [`crate::table::TableStage::refill`]): within the last cycle's segment, the remainder
        // from the segment's start and the cached coefficients; otherwise the full lookup, which
        // refills the cache.
        // Without it (the single-axis call, whose reference workload crosses a 1000-count
        // segment every 6.4 cycles: there the refills cost more than the cache saves), the full
        // lookup every cycle. Both give the same value bit for bit.
        let r = (pos as u32).wrapping_sub(st.table.seg_start);
        // BACKWARD is bit 7, TABLE_OUTSIDE bit 0; each path builds the flags after its lookup
        // (the cached ones know TABLE_OUTSIDE is clear), so that no flag register is live
        // across it.
        // (The cached paths: the direction's flag as the refill stored it; the cache is voided
        // on a reversal.)
        let backward = |st: &State| Flags(st.table.seg_flags);
        let with_outside = |st: &State, (v, outside): (f32, bool)| {
            (v, Flags(st.counter.direction.with_flag(outside as u16)))
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
            if r < st.table.seg_limit {
                // Within one segment of the turn (no wrap): the turn position is the segment's
                // start within the turn + r, not stored (see `State::turn_in`).
                (self.table.cached_um(&st.table, r), backward(st))
            } else {
                cold_path();
                let v = self.table_um_miss::<true>(pool.pool(), st, pos, delta, raw);
                // (Redone by the miss path on a state that was not primed.)
                pos = st.counter.position;
                with_outside(st, v)
            }
        } else if r < st.table.seg_limit {
            (self.table.cached_um(&st.table, r), backward(st))
        } else {
            cold_path();
            let v = self.table_um_miss::<false>(pool.pool(), st, pos, delta, raw);
            pos = st.counter.position;
            with_outside(st, v)
        };
        if thermo_known.unwrap_or(self.thermo.has_thermo) {
            total = self.thermo_um(st, pos, forces_n, &mut flags, total);
        }
        (pos, total, flags)
    }
}
