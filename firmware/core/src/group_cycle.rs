//! One validated group ([`Group`]): its loading from the axis images and stages, and its cycle —
//! the cross-axis stages, then each axis's inlined pipeline. The glossary and the order of the
//! stages are in [`crate::group`].

use crate::MAX_FORCES;
use crate::MAX_SENSORS;
use crate::axis::{AxisName, GroupAxisImage, MAX_AXES};
use crate::counts::wrap;
use crate::error::GroupError;
use crate::group_state::GroupState;
use crate::io::{GroupInput, GroupOutput};
use crate::runtime::PoolTable;

use crate::geometric::{GeometricSpec, GeometricStage};
use crate::group_check::validate_group_stages;
use crate::image;
use crate::io::{CycleInput, CycleOutput, Flags};
use crate::rotary::{RotaryLocationSpec, RotaryMachine, RotaryStage};
use crate::runtime::{AxisCompensator, PoolSource};
use crate::sensor::{ProcessParams, SensorRt};
use crate::spec::SensorSpec;
use crate::state::State;

/// [`Group`]'s cycle dispatch, set at load. An enum of 0..=6, so that its load carries its range
/// and the dispatch's `match` is a table branch with no range test.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
enum CycleMode {
    /// No group loaded (identity; 0: a new group is all zero bytes).
    None = 0,
    /// Every axis linear without a thermo-force term, no cross-axis stage.
    Plain = 1,
    /// No cross-axis stage, some axis rotary or with a thermo-force term.
    Mixed = 2,
    /// With the cross-axis stage.
    Stage = 3,
    /// With the rotary stage only, the slots in the order X, Y, Z, A, C, no thermo-force term
    /// (every slot index and axis kind a constant of the cycle's code).
    StageXyzac = 4,
    /// With the geometric stage only, the group exactly X, Y, Z (linear) without a thermo-force
    /// term (the fast path [`Group::cycle_geometric_plain`]).
    GeometricPlain = 5,
    /// [`CycleMode::Plain`] with exactly three axes (its fast path: `Group::xyz_pipelines`,
    /// tail-called from the dispatch).
    Plain3 = 6,
}

/// A group as the [`PoolSource`] of its inlined pipelines: the pool's address is formed on the
/// segment cache's miss path only.
#[derive(Clone, Copy)]
struct GroupPool<'a, const POOL: usize>(&'a Group<POOL>);

impl<const POOL: usize> PoolSource for GroupPool<'_, POOL> {
    #[inline(always)]
    fn pool(&self) -> &[[f32; 4]] {
        &self.0.pool
    }
}

/// One validated group (one A/B slot of a [`GroupEngine`]): up to five axis pipelines, the
/// cross-axis stage and the coefficient pool of `POOL` segments. All zero bytes when new.
#[derive(Debug, Clone)]
// In this order (not the compiler's): the pipelines (without their sensors' settings: every
// axis's per-cycle fields within a float load's 8-bit scaled offset of the group's address), the
// dispatch byte and the small fields (no padding before the stages), the sensors' settings, then
// the stages, each within the reach of a load's 12-bit offset from the group's address in the
// cycle's code (where they were before the sensors moved: the geometric stage measured +4
// right after the small fields, +5 after the sensors), then the pool.
#[repr(C)]
pub struct Group<const POOL: usize> {
    axes: [AxisCompensator<PoolTable>; MAX_AXES],
    /// The cycle's dispatch, set at load: [`CycleMode::None`] (no group: all zero bytes when new),
    /// [`CycleMode::Plain`], [`CycleMode::Plain3`], [`CycleMode::Mixed`], [`CycleMode::Stage`], [`CycleMode::StageXyzac`] or
    /// [`CycleMode::GeometricPlain`] (here: one load with an immediate offset).
    mode: CycleMode,
    loaded: bool,
    n_axes: u8,
    has_stage: bool,
    names: [AxisName; MAX_AXES],
    /// Per slot: bit 0 rotary, bit 1 has a thermo-force term (the cycle's dispatch).
    kinds: [u8; MAX_AXES],
    counts_per_rev: [u32; MAX_AXES],
    /// The axes' sensor settings (used at the sensors' rate only), by slot: not in the axes, so
    /// that their per-cycle fields are within short load offsets of the group's address.
    sensors: [[SensorRt; MAX_SENSORS]; MAX_AXES],
    /// The volumetric geometric stage, if loaded (its functions follow the tables in the pool).
    /// `None` is all zero bytes (the niche of the stage's non-zero segment lengths), so a new
    /// group, and a `static` engine holding it, is all zero bytes (`.bss`, nothing copied at boot).
    geometric: Option<GeometricStage>,
    stage: RotaryStage,
    pool: [[f32; 4]; POOL],
}

impl<const POOL: usize> Default for Group<POOL> {
    fn default() -> Self {
        Group::new()
    }
}

impl<const POOL: usize> Group<POOL> {
    /// Identity for every slot.
    pub const fn new() -> Group<POOL> {
        Group {
            loaded: false,
            n_axes: 0,
            names: [AxisName::X; MAX_AXES],
            counts_per_rev: [0; MAX_AXES],
            kinds: [0; MAX_AXES],
            has_stage: false,
            mode: CycleMode::None,
            stage: RotaryStage::ZERO,
            geometric: None,
            sensors: [[SensorRt::ZERO; MAX_SENSORS]; MAX_AXES],
            axes: [const { AxisCompensator::identity_with(PoolTable { base: [0; 2] }) }; MAX_AXES],
            pool: [[0.0; 4]; POOL],
        }
    }

    /// Back to the identity (in place).
    pub fn clear(&mut self) {
        self.loaded = false;
        self.n_axes = 0;
        self.has_stage = false;
        self.geometric = None;
        self.mode = CycleMode::None;
        for a in self.axes.iter_mut() {
            a.clear();
        }
    }

    /// Validate every axis image, the axis set and the stage, then copy them in. On `Err`
    /// `self` is untouched.
    ///
    /// Checks beyond each image's own: 1..=5 axes, each name once; a rotary axis has
    /// 2..=2^31 counts per revolution and a table grid starting at 0 and spanning exactly one
    /// turn; a linear axis has 0 counts per revolution; the tables fit the pool; the stage needs
    /// X, Y, Z linear and the stage's tilt axis (A or B) and C rotary in the group and in-range
    /// constants.
    pub fn load(
        &mut self,
        axes: &[GroupAxisImage],
        stage: Option<&RotaryLocationSpec>,
    ) -> Result<(), GroupError> {
        self.load_stages(axes, stage, None)
    }

    /// [`Group::load`] with the volumetric geometric stage too: it needs X, Y and Z in the group,
    /// a valid model ([`GeometricSpec::validate`]) whose grid of each axis with a table spans
    /// exactly that table's grid, and its functions (14 per segment position) fit the pool
    /// after the tables. On `Err` `self` is untouched.
    pub fn load_stages(
        &mut self,
        axes: &[GroupAxisImage],
        stage: Option<&RotaryLocationSpec>,
        geometric: Option<&GeometricSpec>,
    ) -> Result<(), GroupError> {
        let layouts = validate_group_stages(POOL, axes, stage, geometric)?;
        self.clear();
        let mut next = 0u32;
        for (i, (a, l)) in axes.iter().zip(layouts.iter()).enumerate() {
            let Some(l) = l else { continue };
            let dst = &mut self.axes[i];
            image::copy_params_into(l, a.image, dst);
            image::copy_sensors_into(l, a.image, &mut self.sensors[i]);
            let n = l.n_segments as u32;
            let halves = if l.bidirectional { 2 } else { 1 };
            for d in 0..halves {
                for s in 0..l.n_segments {
                    if let Some(seg) = self.pool.get_mut((next + d * n) as usize + s) {
                        *seg = image::table_segment_per_count(l, a.image, d as usize, s);
                    }
                }
            }
            dst.segments = PoolTable {
                base: [next, next + (halves - 1) * n],
            };
            next += halves * n;
            dst.counts_per_rev = a.counts_per_rev;
            self.kinds[i] = (a.counts_per_rev != 0) as u8 | (dst.has_thermo() as u8) << 1;
            self.names[i] = a.name;
            self.counts_per_rev[i] = a.counts_per_rev;
        }
        self.n_axes = axes.len() as u8;
        if let Some(spec) = stage {
            let slot = |name: AxisName| {
                axes.iter()
                    .position(|a| a.name == name)
                    .map_or(0, |p| p as u8)
            };
            let slots = [
                slot(AxisName::X),
                slot(AxisName::Y),
                slot(AxisName::Z),
                slot(spec.machine.tilt_axis()),
                slot(AxisName::C),
            ];
            let upc = |k: usize| self.axes[slots[k] as usize].um_per_count();
            let cpr = |k: usize| self.counts_per_rev[slots[k] as usize];
            self.stage = RotaryStage::new(spec, [upc(0), upc(1), upc(2)], [cpr(3), cpr(4)], slots);
            self.has_stage = true;
        }
        if let Some(spec) = geometric {
            let slot = |k: usize| {
                axes.iter()
                    .position(|a| a.name.code() as usize == k)
                    .map_or(0, |p| p as u8)
            };
            let slots = [slot(0), slot(1), slot(2)];
            let upc = slots.map(|s| self.axes[s as usize].um_per_count());
            self.geometric = Some(GeometricStage::load(spec, upc, slots, &mut self.pool, next));
        }
        self.loaded = true;
        let n = axes.len().min(MAX_AXES);
        let has_geometric = self.geometric.is_some();
        self.mode = if has_geometric && !self.has_stage && self.kinds[..n].iter().all(|&k| k == 0) {
            // X, Y, Z alone (the geometric stage needs all three), no thermo-force term.
            CycleMode::GeometricPlain
        } else if self.has_stage || has_geometric {
            // The inlined X, Y, Z, A, C cycle knows each axis's kind: none has a thermo-force
            // term (kinds 0 for X, Y, Z and 1 for A, C); anything else (a wobble too) takes the general path.
            if self.has_stage
                && !has_geometric
                && self.stage.slot == [0, 1, 2, 3, 4]
                && self.kinds == [0, 0, 0, 1, 1]
                && self.stage.machine == RotaryMachine::AcTrunnion.code()
                && !self.stage.has_wobble()
            {
                CycleMode::StageXyzac
            } else {
                CycleMode::Stage
            }
        } else if self.kinds[..n].iter().all(|&k| k == 0) {
            if n == 3 {
                CycleMode::Plain3
            } else {
                CycleMode::Plain
            }
        } else {
            CycleMode::Mixed
        };
        Ok(())
    }

    /// Parse a group image (schema 2, or a schema-1 single-axis image as axis X) with
    /// [`crate::group_image::parse`] and load it. On `Err` `self` is untouched.
    pub fn load_image(&mut self, image: &[u8]) -> Result<(), GroupError> {
        let view = crate::group_image::parse(image)?;
        let (axes, n) = view.axis_images();
        self.load_stages(&axes[..n], view.rotary.as_ref(), view.geometric.as_ref())
    }

    /// True once a group image is loaded.
    pub fn is_loaded(&self) -> bool {
        self.loaded
    }
    /// Number of axes (0 for the identity).
    pub fn axis_count(&self) -> usize {
        self.n_axes as usize
    }
    /// Name of slot `i`.
    pub fn axis_name(&self, i: usize) -> Option<AxisName> {
        (i < self.n_axes as usize).then(|| self.names[i])
    }
    /// Slot of axis `name`.
    pub fn slot_of(&self, name: AxisName) -> Option<usize> {
        self.names[..(self.n_axes as usize).min(MAX_AXES)]
            .iter()
            .position(|&n| n == name)
    }
    /// Counts per revolution of slot `i` (0 for a linear axis).
    pub fn counts_per_rev(&self, i: usize) -> u32 {
        self.counts_per_rev.get(i).copied().unwrap_or(0)
    }
    /// True if the rotary location-error stage is loaded.
    pub fn has_rotary_stage(&self) -> bool {
        self.has_stage
    }
    /// True if the volumetric geometric stage is loaded.
    pub fn has_geometric_stage(&self) -> bool {
        self.geometric.is_some()
    }
    /// The geometric stage's model error e (µm, reached − commanded, the deviation the stage adds
    /// to X, Y, Z; the correction is −e) at commanded positions of X, Y, Z (counts); None without
    /// the stage.
    pub fn geometric_error_um(&self, commands_xyz: [i64; 3]) -> Option<[f32; 3]> {
        let geometric = self.geometric.as_ref()?;
        let mut by_slot = [0i64; MAX_AXES];
        for (k, c) in commands_xyz.into_iter().enumerate() {
            if let Some(s) = self.slot_of(AxisName::ALL[k]) {
                by_slot[s] = c;
            }
        }
        let d = geometric.deviation_by_slot(&self.pool, |i| by_slot[i.min(MAX_AXES - 1)]);
        let at = |k: usize| self.slot_of(AxisName::ALL[k]).map_or(0.0, |s| d[s]);
        Some([at(0), at(1), at(2)])
    }
    /// The pipeline of slot `i` (its table lives in the pool: use [`Group::table_um`]).
    pub fn axis(&self, i: usize) -> Option<&AxisCompensator<PoolTable>> {
        self.axes.get(i)
    }
    /// Table value of slot `i` at `position_counts` (the turn position for a rotary axis).
    pub fn table_um(
        &self,
        i: usize,
        direction: crate::Direction,
        position_counts: i64,
    ) -> (f32, bool) {
        self.axes.get(i).map_or((0.0, false), |a| {
            a.table_um_in(&self.pool, direction, position_counts)
        })
    }
    /// Sensor-rate update of slot `i` ([`AxisCompensator::update_temperatures`]).
    pub fn update_temperatures(
        &self,
        st: &mut GroupState,
        i: usize,
        now_ms: u32,
        readings: &[f32],
    ) {
        if let (Some(a), Some(s), Some(cfgs)) =
            (self.axes.get(i), st.axes.get_mut(i), self.sensors.get(i))
        {
            a.update_temperatures_with(cfgs, s, now_ms, readings);
        }
    }
    /// Settings of sensor `j` of slot `i` (what [`AxisCompensator::sensor`] is for one axis).
    pub fn sensor(&self, i: usize, j: usize) -> Option<SensorSpec> {
        let (a, cfgs) = (self.axes.get(i)?, self.sensors.get(i)?);
        crate::sensor::sensor_spec(cfgs, a.thermo.n_sensors, j)
    }
    /// b_j (µm/K) of sensor `j` of slot `i`.
    pub fn b_um_per_k(&self, i: usize, j: usize) -> Option<f32> {
        let (a, cfgs) = (self.axes.get(i)?, self.sensors.get(i)?);
        crate::sensor::sensor_b_alpha(cfgs, a.thermo.n_sensors, j).map(|(b, _)| b)
    }
    /// Lag coefficient α of sensor `j` of slot `i` (1 = no lag).
    pub fn lag_alpha(&self, i: usize, j: usize) -> Option<f32> {
        let (a, cfgs) = (self.axes.get(i)?, self.sensors.get(i)?);
        crate::sensor::sensor_b_alpha(cfgs, a.thermo.n_sensors, j).map(|(_, al)| al)
    }
    /// Process parameters for every axis ([`AxisCompensator::set_process`]).
    pub fn set_process(&self, st: &mut GroupState, p: &ProcessParams) {
        for (a, s) in self.axes.iter().zip(st.axes.iter_mut()) {
            a.set_process(s, p);
        }
    }

    /// One group cycle (see the module's order of stages). Writes the group's slots of `out`
    /// (every slot, as identity outputs, while no group is loaded); slots beyond the group's
    /// axes are left as they are.
    pub fn cycle(&self, st: &mut GroupState, input: &GroupInput, out: &mut GroupOutput) {
        // One call per mode (each out of line): the cost of one mode does not depend on how
        // the others are compiled.
        match self.mode {
            // Every axis linear without a thermo-force term (the common case): each axis's
            // whole pipeline with both checks compiled out, no per-axis dispatch.
            // Three axes (the common three-axis machine): `xyz_pipelines` with a deviation of
            // −0.0, which leaves every error exactly as it is (x + (−0.0) = x for every x, −0.0
            // and +0.0 included; +0.0 would turn a −0.0 error into +0.0). A tail call from here
            // (no function of its own that loads the −0.0 and tail-calls it: group3 −4).
            CycleMode::Plain3 => self.xyz_pipelines(st, input, out, -0.0, -0.0, -0.0),
            CycleMode::Plain => self.cycle_plain(st, input, out),
            CycleMode::Mixed => self.cycle_mixed(st, input, out),
            CycleMode::StageXyzac => self.cycle_with_stage::<true>(st, input, out),
            CycleMode::Stage => self.cycle_with_stage::<false>(st, input, out),
            CycleMode::GeometricPlain => self.cycle_geometric_plain(st, input, out),
            CycleMode::None => self.identity_cycle(st, input, out),
        }
    }

    /// Slots 0, 1, 2 linear without a thermo-force term: the three pipelines inlined with
    /// constant slots (no per-axis call), `dx`, `dy`, `dz` added to the axes' errors before its limits. One
    /// copy of this code serves three plain axes and three axes with the geometric stage.
    #[inline(never)]
    fn xyz_pipelines(
        &self,
        st: &mut GroupState,
        input: &GroupInput,
        out: &mut GroupOutput,
        dx: f32,
        dy: f32,
        dz: f32,
    ) {
        self.xyz_inline(st, input, out, [dx, dy, dz]);
    }

    /// The three pipelines of slots 0, 1, 2 (linear, no thermo-force term) with the deviation `d`
    /// added before their limits: the body of [`Group::xyz_pipelines`] and the first part of
    /// [`Group::xyzac_pipelines`].
    #[inline(always)]
    fn xyz_inline(
        &self,
        st: &mut GroupState,
        input: &GroupInput,
        out: &mut GroupOutput,
        d: [f32; 3],
    ) {
        let (pool, inp) = (GroupPool(self), &input.axes);
        let (ax, s, o) = (&self.axes, &mut st.axes, &mut out.axes);
        axis_pipeline::<false, true>(&ax[0], pool, &mut s[0], &inp[0], &mut o[0], d[0]);
        axis_pipeline::<false, true>(&ax[1], pool, &mut s[1], &inp[1], &mut o[1], d[1]);
        axis_pipeline::<false, true>(&ax[2], pool, &mut s[2], &inp[2], &mut o[2], d[2]);
    }

    /// [`CycleMode::Plain`] with any other number of axes: one pipeline call per axis.
    #[inline(never)]
    fn cycle_plain(&self, st: &mut GroupState, input: &GroupInput, out: &mut GroupOutput) {
        let n = (self.n_axes as usize).min(MAX_AXES);
        for i in 0..n {
            axis_cycle::<POOL, false, false>(
                &self.axes[i],
                &self.pool,
                &mut st.axes[i],
                &input.axes[i],
                &mut out.axes[i],
            );
        }
    }

    /// [`CycleMode::Mixed`]: one pipeline call per axis, chosen by its kind.
    #[inline(never)]
    fn cycle_mixed(&self, st: &mut GroupState, input: &GroupInput, out: &mut GroupOutput) {
        let n = (self.n_axes as usize).min(MAX_AXES);
        for i in 0..n {
            let (ax, s, inp, o) = (
                &self.axes[i],
                &mut st.axes[i],
                &input.axes[i],
                &mut out.axes[i],
            );
            match self.kinds[i] {
                0 => axis_cycle::<POOL, false, false>(ax, &self.pool, s, inp, o),
                1 => axis_cycle::<POOL, true, false>(ax, &self.pool, s, inp, o),
                _ => axis_cycle::<POOL, true, true>(ax, &self.pool, s, inp, o),
            }
        }
    }

    /// [`Group::cycle`] without a group: every slot is an identity axis.
    #[cold]
    #[inline(never)]
    fn identity_cycle(&self, st: &mut GroupState, input: &GroupInput, out: &mut GroupOutput) {
        for i in 0..MAX_AXES {
            out.axes[i] = self.axes[i].cycle_in(&self.pool, &mut st.axes[i], &input.axes[i]);
        }
    }

    /// [`Group::cycle`] of a group with the cross-axis stage: the stage first (it reads only the
    /// commanded positions), then each axis's whole pipeline, the stage's deviation added to the
    /// axis's error before its limits (the same sum, in the same order, as adding it between the
    /// error and the limits). A group with the stage is exactly X, Y, Z (linear) and A, C
    /// (rotary). In the order X, Y, Z, A, C (`XYZAC`) the stage's refresh is inlined here and the
    /// five pipelines, with constant slots and the kind of each known (no per-axis call or
    /// dispatch), are tail-called ([`Group::xyzac_pipelines`]); any other slot
    /// order runs them in slot order through the per-axis calls that [`CycleMode::Mixed`] uses (one
    /// inlined copy only, for code size). Each pipeline reads and writes only its own slot, so
    /// the order changes no output.
    #[inline(never)]
    fn cycle_with_stage<const XYZAC: bool>(
        &self,
        st: &mut GroupState,
        input: &GroupInput,
        out: &mut GroupOutput,
    ) {
        // XYZAC implies the rotary stage (set at load): no run-time test on that path.
        let d = if XYZAC || self.has_stage {
            self.rotary_stage::<XYZAC>(st, input)
        } else {
            [0.0; 3]
        };
        let (pool, inp) = (&self.pool, &input.axes);
        let (ax, s, o) = (&self.axes, &mut st.axes, &mut out.axes);
        if XYZAC {
            return self.xyzac_pipelines(st, input, out, d[0], d[1], d[2]);
        }
        // The deviation by slot: the geometric stage's (X, Y, Z), plus the rotary stage's (X, Y,
        // Z; A, C: none).
        let mut by_slot = match &self.geometric {
            Some(g) => Self::geometric_by_slot(g, &self.pool, input),
            None => [0.0f32; MAX_AXES],
        };
        if self.has_stage {
            for (k, &dk) in d.iter().enumerate() {
                by_slot[self.stage_slot::<false>(k)] += dk;
            }
        }
        let n = (self.n_axes as usize).min(MAX_AXES);
        for i in 0..n {
            let (a, st_i, in_i, out_i) = (&ax[i], &mut s[i], &inp[i], &mut o[i]);
            match self.kinds[i] {
                0 => axis_cycle_with::<POOL, false, false>(a, pool, st_i, in_i, out_i, by_slot[i]),
                1 => axis_cycle::<POOL, true, false>(a, pool, st_i, in_i, out_i),
                2 => axis_cycle_with::<POOL, false, true>(a, pool, st_i, in_i, out_i, by_slot[i]),
                _ => axis_cycle::<POOL, true, true>(a, pool, st_i, in_i, out_i),
            }
        }
    }

    /// [`Group::cycle`] with the geometric stage only, every axis linear without a
    /// thermo-force term: each axis's plain pipeline with its deviation, no per-axis dispatch.
    #[inline(never)]
    fn cycle_geometric_plain(
        &self,
        st: &mut GroupState,
        input: &GroupInput,
        out: &mut GroupOutput,
    ) {
        // The group is exactly X, Y, Z: slots 0..3. The stage is there in this mode (set at
        // load); the test takes the place of the dispatch's former test of a second flag.
        let Some(g) = &self.geometric else {
            return self.identity_cycle(st, input, out);
        };
        let d = g.deviation_xyz_slots(&self.pool, &input.axes);
        self.xyz_pipelines(st, input, out, d[0], d[1], d[2]);
    }

    /// The five pipelines of the X, Y, Z, A, C cycle (slots 0–4 in that order), the rotary stage's
    /// deviation `dx`, `dy`, `dz` added to X, Y, Z before their limits: a function of its own,
    /// tail-called by the stage ([`Group::cycle_with_stage`]), so that none of the stage's
    /// registers is live across the pipelines and the stage's refresh can be inlined (group5
    /// 530.6 → 526.2 with the stage reading the commands without `black_box`, then 505.2 → 488.2
    /// with the refresh inlined).
    #[inline(never)]
    fn xyzac_pipelines(
        &self,
        st: &mut GroupState,
        input: &GroupInput,
        out: &mut GroupOutput,
        dx: f32,
        dy: f32,
        dz: f32,
    ) {
        self.xyz_inline(st, input, out, [dx, dy, dz]);
        self.ac_cycle(st, input, out)
    }

    /// Slots 3 and 4 of the X, Y, Z, A, C cycle: [`Group::ac_pipelines`] on their fields.
    #[inline(always)]
    fn ac_cycle(&self, st: &mut GroupState, input: &GroupInput, out: &mut GroupOutput) {
        // (Constant chunks of constant-length arrays: the `None` arms are never taken.)
        let (Some((_, ax)), Some((_, s)), Some((_, inp)), Some((_, o))) = (
            self.axes.split_last_chunk::<2>(),
            st.axes.split_last_chunk_mut::<2>(),
            input.axes.split_last_chunk::<2>(),
            out.axes.split_last_chunk_mut::<2>(),
        ) else {
            return;
        };
        Self::ac_pipelines(ax, GroupPool(self), s, inp, o);
    }

    /// Slots 3 and 4 of the X, Y, Z, A, C cycle (A and C, rotary), inlined into the cycle. (Out of
    /// line while each axis held its sensors' settings: C's fields were then beyond a float
    /// load's reach of the group's address; with the settings in `Group::sensors` every axis's
    /// are within it, and the call's entry, exit and argument setup cost more: 542.6 out of line,
    /// 534.6 inlined.)
    #[inline(always)]
    fn ac_pipelines(
        ax: &[AxisCompensator<PoolTable>; 2],
        pool: impl PoolSource,
        s: &mut [State; 2],
        inp: &[CycleInput; 2],
        o: &mut [CycleOutput; 2],
    ) {
        axis_pipeline::<true, false>(&ax[0], pool, &mut s[0], &inp[0], &mut o[0], 0.0);
        axis_pipeline::<true, false>(&ax[1], pool, &mut s[1], &inp[1], &mut o[1], 0.0);
    }

    /// The geometric stage's deviation by slot (out of line: the rotary stage's code beside it
    /// stays as it is without it).
    #[inline(never)]
    fn geometric_by_slot(
        g: &GeometricStage,
        pool: &[[f32; 4]; POOL],
        input: &GroupInput,
    ) -> [f32; MAX_AXES] {
        g.deviation_by_slot(pool, |i| input.axes[i].command_counts)
    }

    /// Slot of the stage's axis `k` (0..5: X, Y, Z, A, C): `k` itself when the slots are in that
    /// order, else the slot set at load (< MAX_AXES; `min` keeps the indexing check-free).
    #[inline(always)]
    fn stage_slot<const XYZAC: bool>(&self, k: usize) -> usize {
        if XYZAC {
            k
        } else {
            (self.stage.slot[k % 5] as usize).min(MAX_AXES - 1)
        }
    }

    /// The rotary location-error stage: commanded angles within the turn, cached angle terms;
    /// returns the deviation of X, Y, Z.
    #[inline(always)]
    fn rotary_stage<const XYZAC: bool>(&self, st: &mut GroupState, input: &GroupInput) -> [f32; 3] {
        let g = &self.stage;
        let slot = |k: usize| self.stage_slot::<XYZAC>(k);
        // In the general cycle (pipelines in this function) through `black_box`, so that the
        // compiler reads the commands again in the pipelines instead of keeping the stage's copies
        // live across them (spilled: 4 more per cycle); the X, Y, Z, A, C cycle's pipelines are a
        // function of their own (`xyzac_pipelines`), which reads them anyway.
        let axes = if XYZAC {
            &input.axes
        } else {
            core::hint::black_box(&input.axes)
        };
        let cmd = |k: usize| axes[slot(k)].command_counts;
        let c = &mut st.rotary;
        // The pivot differences after the tracking, on each path (not live across it nor across the
        // fold's call: with them before it, group5 measured 505.2 instead of 488.2).
        let moved = g.track(c, [cmd(3), cmd(4)]);
        if moved {
            let n = g.counts_from_pivot([cmd(0), cmd(1), cmd(2)]);
            st.angle_refreshes = st.angle_refreshes.wrapping_add(1);
            // The X, Y, Z, A, C mode is an AC trunnion's (set at load): no kind test.
            if XYZAC {
                return g.refresh_deviation_ac(c, n);
            }
            let d = g.refresh_deviation(c, n[0], n[1], n[2]);
            return [d.x, d.y, d.z];
        }
        if c.unfolded {
            g.fold_angles(c);
        }
        let n = g.counts_from_pivot([cmd(0), cmd(1), cmd(2)]);
        RotaryStage::deviation_um(c, n)
    }
}

/// The loop's correction at given positions (for a probe latch, [`crate::probe`]).
impl<const POOL: usize> Group<POOL> {
    /// The error (µm) the loop corrects for every slot if the axes stood at `positions_counts`
    /// (extended counts, by slot), with each axis's present direction and cached thermal state:
    /// table (a rotary axis at its position within the turn) + thermo-force term (cached
    /// b0 + Σ b_i·ΔT_i + predicted forces + expansion at this position; no measured force) +
    /// the cross-axis stages' deviation (geometric + rotary) with these positions taken as the
    /// commanded ones, in the cycle's order, then clamped to ±`max_correction_um` as the loop clamps (no slew: that
    /// limits a change over time, not a position). The second value is true if a slot was
    /// clamped or not finite (a non-finite error is reported as 0). All zero for the identity.
    pub fn error_at(
        &self,
        st: &GroupState,
        positions_counts: &[i64; MAX_AXES],
    ) -> ([f32; MAX_AXES], bool) {
        let mut e = [0.0f32; MAX_AXES];
        if !self.loaded {
            return (e, false);
        }
        let mut d = if let Some(g) = &self.geometric {
            g.deviation_by_slot(&self.pool, |i| positions_counts[i.min(MAX_AXES - 1)])
        } else {
            [0.0; MAX_AXES]
        };
        if self.has_stage {
            for (a, b) in d.iter_mut().zip(self.stage_deviation_at(positions_counts)) {
                *a += b;
            }
        }
        let mut limited = false;
        let n = (self.n_axes as usize).min(MAX_AXES);
        for i in 0..n {
            let (ax, s, pos) = (&self.axes[i], &st.axes[i], positions_counts[i]);
            let cpr = self.counts_per_rev[i];
            let table_pos = if cpr != 0 { wrap(pos, cpr) as i64 } else { pos };
            let dir = s.direction();
            let (mut total, _) = ax.table_um_in(&self.pool, dir, table_pos);
            if ax.has_thermo() {
                let mut flags = Flags::NONE;
                total = ax.thermo_um(s, pos, &[0.0; MAX_FORCES], &mut flags, total);
            }
            total += d[i];
            let max = ax.limits.max_correction_um;
            e[i] = if !total.is_finite() {
                limited = true;
                0.0
            } else if total > max {
                limited = true;
                max
            } else if total < -max {
                limited = true;
                -max
            } else {
                total
            };
        }
        (e, limited)
    }

    /// The rotary stage's deviation by slot with `positions_counts` as the commanded positions
    /// (a fresh angle cache: nothing of the cycle's cache is changed).
    fn stage_deviation_at(&self, positions_counts: &[i64; MAX_AXES]) -> [f32; MAX_AXES] {
        let g = &self.stage;
        let slot = |k: usize| (g.slot[k] as usize).min(MAX_AXES - 1);
        let angle = |k: usize| wrap(positions_counts[slot(k)], self.counts_per_rev[slot(k)]);
        let mut cache = g.cache_at([angle(3), angle(4)]);
        let q = g.counts_from_pivot([
            positions_counts[slot(0)],
            positions_counts[slot(1)],
            positions_counts[slot(2)],
        ]);
        let d = g.refresh_deviation(&mut cache, q[0], q[1], q[2]);
        let d = [d.x, d.y, d.z];
        let mut by_slot = [0.0f32; MAX_AXES];
        for (k, dk) in d.into_iter().enumerate() {
            by_slot[slot(k)] = dk;
        }
        by_slot
    }
}

/// One axis's whole pipeline of a loaded group (not inlined: each axis gets the register
/// allocation of the single-axis call). Without `THERMO`, `ROTARY` is the axis's kind (bit 0 of
/// `Group::kinds`, set at load from its counts per revolution): no run-time test; with `THERMO`
/// (the callers' catch-all for kinds 2 and 3) the counts per revolution are tested.
#[inline(never)]
fn axis_cycle<const POOL: usize, const ROTARY: bool, const THERMO: bool>(
    ax: &AxisCompensator<PoolTable>,
    pool: &[[f32; 4]; POOL],
    st: &mut State,
    input: &CycleInput,
    out: &mut CycleOutput,
) {
    // The test of `primed` in the segment cache's miss path (see `axis_error_um`).
    let tracked = ax.track_primed(st, input.scale_raw);
    // THERMO false: known to have none, and ROTARY is the kind; true: both checked at run time.
    let thermo = if THERMO { None } else { Some(false) };
    let rotary = if THERMO { None } else { Some(ROTARY) };
    let raw = input.scale_raw;
    let (pos, e, f) = ax.axis_error_um(
        pool,
        st,
        tracked,
        raw,
        &input.forces_n,
        rotary,
        thermo,
        true,
    );
    *out = ax.finish(st, pos, e, input.command_counts, f);
}

/// One axis's whole pipeline of a group with the cross-axis stage in another slot order
/// (`ROTARY` false: called for kinds 0 and 2 only, linear):
/// `stage_um` (the stage's deviation, linear axes only) is added to the axis's error before its
/// limits.
#[inline(never)]
fn axis_cycle_with<const POOL: usize, const ROTARY: bool, const THERMO: bool>(
    ax: &AxisCompensator<PoolTable>,
    pool: &[[f32; 4]; POOL],
    st: &mut State,
    input: &CycleInput,
    out: &mut CycleOutput,
    stage_um: f32,
) {
    let tracked = ax.track(st, input.scale_raw);
    let thermo = if THERMO { None } else { Some(false) };
    // Without the segment cache: here (beside the geometric stage's registers) it measured
    // 8 instructions more per cycle than the full lookup on the group3_geometry workload.
    let (pos, mut e, f) = ax.axis_error_um(
        pool,
        st,
        tracked,
        input.scale_raw,
        &input.forces_n,
        Some(ROTARY),
        thermo,
        false,
    );
    e += stage_um;
    *out = ax.finish(st, pos, e, input.command_counts, f);
}

/// One axis's whole pipeline in a group with the cross-axis stage (inlined into the group's
/// cycle): `ROTARY` known, no thermo-force term (the X, Y, Z, A, C path is chosen at load only
/// for axes without one); with `STAGE`, `stage_um`
/// (the stage's deviation, linear axes) is added to the axis's error before its limits (without
/// it nothing is added: `e + 0.0` would turn a −0.0 error into +0.0).
#[inline(always)]
fn axis_pipeline<const ROTARY: bool, const STAGE: bool>(
    ax: &AxisCompensator<PoolTable>,
    pool: impl PoolSource,
    st: &mut State,
    input: &CycleInput,
    out: &mut CycleOutput,
    stage_um: f32,
) {
    // The test of `primed` in the segment cache's miss path (see `axis_error_um`).
    let tracked = ax.track_primed(st, input.scale_raw);
    // The position out at once, so that it is not live across the lookup and the limits (its high
    // word was spilled and reloaded: group5 −6); written again below in the one case it changes,
    // the cache miss's path redoing the first cycle of an unprimed state.
    out.position_counts = tracked.0;
    // No thermo-force term (checked at load for this path).
    let (pos, mut e, f) = ax.axis_error_um(
        pool,
        st,
        tracked,
        input.scale_raw,
        &input.forces_n,
        Some(ROTARY),
        Some(false),
        true,
    );
    if pos != tracked.0 {
        crate::hint::cold_path();
        out.position_counts = pos;
    }
    if STAGE {
        e += stage_um;
    }
    let o = ax.finish(st, pos, e, input.command_counts, f);
    out.corrected_command_counts = o.corrected_command_counts;
    out.correction_counts = o.correction_counts;
    out.correction_um = o.correction_um;
    out.flags = o.flags;
}
