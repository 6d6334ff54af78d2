//! Typed errors of the table image (parse and write).

use core::fmt;

use crate::axis::AxisName;

/// The image field an [`ImageError::NonFinite`] or [`ImageError::OutOfRange`] refers to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Field {
    /// Header: scale resolution.
    UmPerCount,
    /// Header: counter width.
    CounterBits,
    /// Header: reserved bytes/flags that must be zero.
    Reserved,
    /// Table: start position.
    StartCounts,
    /// Table: knot spacing.
    SegmentCounts,
    /// Table: outside-stroke kind or taper length.
    Outside,
    /// Table: a forward coefficient (index = segment).
    ForwardCoefficient,
    /// Table: a backward coefficient (index = segment).
    BackwardCoefficient,
    /// Thermo: sensor period.
    SensorPeriod,
    /// Thermo: sensor reference temperature (index = sensor).
    ReferenceDegc,
    /// Thermo: sensor plausible range (index = sensor).
    SensorRange,
    /// Thermo: sensor max rate (index = sensor).
    MaxRate,
    /// Thermo: lag time constant (index = sensor).
    LagTau,
    /// Thermo: stale timeout (index = sensor).
    StaleTimeout,
    /// Thermo: constant term b0.
    B0,
    /// Thermo: b_i (index = sensor).
    BUmPerK,
    /// Thermo: expansion sensor index.
    ExpansionSensor,
    /// Thermo: expansion coefficient c or x_ref.
    Expansion,
    /// Thermo: compliance χ (index = force).
    Chi,
    /// Thermo: force law coefficient or exponent (index = force).
    ForceLaw,
    /// Limits: max correction.
    MaxCorrection,
    /// Limits: max slew.
    MaxSlew,
    /// Limits: direction hysteresis.
    Hysteresis,
    /// Group: counts per revolution of a rotary axis (index = group slot).
    CountsPerRev,
    /// Rotary stage: a location error or squareness term (index 0..11 in the order of
    /// [`crate::rotary::RotaryLocationSpec::all_constants`]).
    RotaryLocation,
    /// Rotary stage: pivot position (index = X, Y, Z).
    Pivot,
    /// Rotary stage: tool length.
    ToolLength,
    /// Probe settings: minimum pulse width of the trigger filter.
    ProbeMinPulse,
    /// Probe settings: latency of the trigger signal.
    ProbeLatency,
    /// Probe settings: lockout window after a trigger.
    ProbeLockout,
    /// Probe settings: speed above which an unarmed trigger counts as one during a move.
    ProbeMovingSpeed,
    /// Rotary stage: machine kind code (1 ac-trunnion, 2 bc-trunnion, 3 bc-head).
    RotaryMachine,
    /// Thermo: `thermo_flags` has a bit this build does not know.
    ThermoFlags,
    /// Thermo: a sensor's rise bounds of the range guard (index = sensor).
    RiseBounds,
    /// Rotary stage: a wobble coefficient (index in the order of
    /// [`crate::rotary::RotaryWobble::coefficients`]).
    RotaryWobble,
}

impl Field {
    /// Name of the field as used in the image spec.
    pub const fn name(self) -> &'static str {
        match self {
            Field::UmPerCount => "um_per_count",
            Field::CounterBits => "counter_bits",
            Field::Reserved => "reserved",
            Field::StartCounts => "table.start_counts",
            Field::SegmentCounts => "table.segment_counts",
            Field::Outside => "table.outside",
            Field::ForwardCoefficient => "table.forward",
            Field::BackwardCoefficient => "table.backward",
            Field::SensorPeriod => "thermo.sensor_period_ms",
            Field::ReferenceDegc => "thermo.sensors.reference_degc",
            Field::SensorRange => "thermo.sensors.min_degc/max_degc",
            Field::MaxRate => "thermo.sensors.max_rate_degc_per_s",
            Field::LagTau => "thermo.sensors.lag_tau_s",
            Field::StaleTimeout => "thermo.sensors.stale_timeout_ms",
            Field::B0 => "thermo.b0_um",
            Field::BUmPerK => "thermo.b_um_per_k",
            Field::ExpansionSensor => "thermo.expansion.sensor",
            Field::Expansion => "thermo.expansion",
            Field::Chi => "thermo.forces.chi_um_per_n",
            Field::ForceLaw => "thermo.forces.law",
            Field::MaxCorrection => "limits.max_correction_um",
            Field::MaxSlew => "limits.max_slew_um_per_cycle",
            Field::Hysteresis => "limits.direction_hysteresis_counts",
            Field::CountsPerRev => "axes.counts_per_rev",
            Field::RotaryLocation => "rotary.location_errors",
            Field::Pivot => "rotary.pivot_counts",
            Field::ToolLength => "rotary.tool_length_um",
            Field::ProbeMinPulse => "probe.min_pulse_us",
            Field::ProbeLatency => "probe.latency_ns",
            Field::ProbeLockout => "probe.lockout_us",
            Field::ProbeMovingSpeed => "probe.moving_um_per_s",
            Field::RotaryMachine => "rotary.machine",
            Field::ThermoFlags => "thermo.flags",
            Field::RiseBounds => "thermo.rise_bounds_k",
            Field::RotaryWobble => "rotary.wobble",
        }
    }
}

/// Why an image was rejected (parse) or could not be written (spec validation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
// Discriminants start at 1 so that `Option<ImageError>::None` is a zero byte (the `Engine` const
// stays all zeros and lands in `.bss`).
#[repr(u8)]
pub enum ImageError {
    /// Fewer bytes than the header or the declared total length.
    TooShort = 1,
    /// Output buffer smaller than [`crate::image_len`].
    BufferTooSmall {
        /// Bytes needed.
        needed: u32,
    } = 2,
    /// Magic is not `AXCI`.
    BadMagic = 3,
    /// Schema version not supported by this build.
    UnsupportedVersion {
        /// Version found in the image.
        found: u16,
    } = 4,
    /// Header length, total length or a section offset/length is inconsistent.
    BadLength = 5,
    /// CRC-32 over the image does not match the stored value.
    BadCrc = 6,
    /// More than [`crate::MAX_SEGMENTS`] segments per direction, or none.
    TooManySegments = 7,
    /// Backward table is neither empty nor as long as the forward one.
    DirectionLengthMismatch = 8,
    /// More than [`crate::MAX_SENSORS`] sensors.
    TooManySensors = 9,
    /// More than [`crate::MAX_FORCES`] force terms.
    TooManyForces = 10,
    /// `b_um_per_k` does not have one entry per sensor.
    SensorCountMismatch = 11,
    /// A value is NaN or infinite.
    NonFinite {
        /// Which field.
        field: Field,
        /// Element index (segment, sensor or force; 0 for scalars).
        index: u16,
    } = 12,
    /// A value is outside its allowed range.
    OutOfRange {
        /// Which field.
        field: Field,
        /// Element index (segment, sensor or force; 0 for scalars).
        index: u16,
    } = 13,
    /// A group needs 1..=[`crate::group::MAX_AXES`] axes.
    AxisCount = 14,
    /// Two axes of a group have the same name.
    DuplicateAxis {
        /// The axis ([`crate::group::AxisName`] code).
        axis: u8,
    } = 15,
    /// A section or stage refers to an axis the group lacks (or of the wrong kind).
    AxisNotInGroup {
        /// The axis ([`crate::group::AxisName`] code).
        axis: u8,
    } = 16,
    /// An axis's knot grid does not match its stroke (a rotary axis: 0..counts per revolution).
    GridMismatch {
        /// The axis ([`crate::group::AxisName`] code).
        axis: u8,
    } = 17,
    /// The group's coefficient pool is too small for the tables.
    PoolTooSmall {
        /// Segments needed.
        needed: u32,
    } = 18,
    /// Bytes follow the image's declared end.
    TrailingBytes = 19,
    /// A mandatory section of a type this build does not know.
    UnknownSection {
        /// The section type.
        kind: u16,
    } = 20,
    /// A mandatory section of a known type (or version) this build does not support yet.
    UnsupportedSection {
        /// The section type.
        kind: u16,
    } = 21,
    /// A section's offset/length is out of the image, overflows, overlaps or is malformed.
    SectionBounds {
        /// Directory index.
        index: u16,
    } = 22,
    /// A section's CRC-32 does not match.
    SectionCrc {
        /// Directory index.
        index: u16,
    } = 23,
    /// The image was built for another counter width than the board's.
    CounterWidthMismatch {
        /// Counter bits in the image.
        image: u8,
        /// Counter bits of the board.
        board: u8,
    } = 24,
    /// The image is for an axis id the board does not drive.
    AxisIdMismatch {
        /// Axis id in the image.
        image: u16,
    } = 25,
    /// The image needs more temperature inputs than the board has wired.
    TooFewSensorInputs {
        /// Sensors the image needs.
        needed: u8,
        /// Inputs wired on the board.
        wired: u8,
    } = 26,
    /// Sensor names missing, not one per sensor, empty or not UTF-8.
    SensorNames {
        /// The axis ([`crate::group::AxisName`] code).
        axis: u8,
    } = 27,
    /// Two axes of a group image carry the same axis id: one scale input cannot feed both.
    AxisIdTwice {
        /// The axis id.
        axis_id: u16,
    } = 28,
    /// The rotary model's pivot lies outside a linear axis's stroke by more than that stroke's
    /// length: a unit or sign error (a pivot is on the machine, near its travel).
    PivotOutsideStroke {
        /// The linear axis's code (0 X, 1 Y, 2 Z).
        axis: u8,
    } = 29,
    /// A provenance block (group section kind 6, or the `PROV`/`SNAM` header extension of a
    /// schema-1 image) is malformed ([`crate::provenance`]).
    Provenance = 40,
    /// The geometric model (section kind 2) was refused.
    Geometric(crate::geometric::GeometricError) = 41,
}

impl fmt::Display for ImageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            ImageError::TooShort => f.write_str("image too short"),
            ImageError::BufferTooSmall { needed } => {
                write!(f, "output buffer too small: {needed} bytes needed")
            }
            ImageError::BadMagic => f.write_str("bad magic (not an axcomp table image)"),
            ImageError::UnsupportedVersion { found } => {
                write!(f, "unsupported image schema version {found}")
            }
            ImageError::BadLength => f.write_str("inconsistent header/section lengths"),
            ImageError::BadCrc => f.write_str("CRC-32 mismatch"),
            ImageError::TooManySegments => {
                f.write_str("table must have 1..=1024 segments per direction")
            }
            ImageError::DirectionLengthMismatch => {
                f.write_str("backward table must be empty or as long as the forward table")
            }
            ImageError::TooManySensors => f.write_str("more than 16 sensors"),
            ImageError::TooManyForces => f.write_str("more than 3 force terms"),
            ImageError::SensorCountMismatch => {
                f.write_str("thermo.b_um_per_k must have one entry per sensor")
            }
            ImageError::NonFinite { field, index } => {
                write!(f, "{}[{index}] is not finite", field.name())
            }
            ImageError::OutOfRange { field, index } => {
                write!(f, "{}[{index}] is out of range", field.name())
            }
            ImageError::AxisCount => f.write_str("a group needs 1..=5 axes"),
            ImageError::DuplicateAxis { axis } => {
                write!(f, "axis {} appears twice in the group", axis_letter(axis))
            }
            ImageError::AxisNotInGroup { axis } => write!(
                f,
                "axis {} is not in the group (or is not of the kind needed)",
                axis_letter(axis)
            ),
            ImageError::GridMismatch { axis } => write!(
                f,
                "the knot grid of axis {} does not match its stroke",
                axis_letter(axis)
            ),
            ImageError::PoolTooSmall { needed } => write!(
                f,
                "the tables need {needed} segments, more than this build's group pool holds"
            ),
            ImageError::TrailingBytes => f.write_str("bytes follow the end of the image"),
            ImageError::UnknownSection { kind } => {
                write!(f, "unknown mandatory section type {kind}")
            }
            ImageError::UnsupportedSection { kind } => {
                write!(
                    f,
                    "mandatory section type {kind} is not supported by this build"
                )
            }
            ImageError::SectionBounds { index } => {
                write!(
                    f,
                    "section {index} is out of bounds, overlapping or malformed"
                )
            }
            ImageError::SectionCrc { index } => write!(f, "section {index}: CRC-32 mismatch"),
            ImageError::CounterWidthMismatch { image, board } => write!(
                f,
                "the image is for a {image}-bit counter, the board's counters have {board} bits"
            ),
            ImageError::AxisIdMismatch { image } => {
                write!(
                    f,
                    "the image is for axis id {image}, which this board does not drive"
                )
            }
            ImageError::TooFewSensorInputs { needed, wired } => write!(
                f,
                "the image needs {needed} temperature inputs, the board has {wired} wired"
            ),
            ImageError::AxisIdTwice { axis_id } => write!(
                f,
                "axis id {axis_id} is on two axes of the group (one scale input cannot feed both)"
            ),
            ImageError::PivotOutsideStroke { axis } => write!(
                f,
                "the rotary pivot's {} lies outside the {} stroke by more than the stroke's length (a unit or \
                 sign error?)",
                axis_letter(axis),
                axis_letter(axis)
            ),
            ImageError::SensorNames { axis } => write!(
                f,
                "axis {}: sensor names must be one non-empty UTF-8 name per sensor",
                axis_letter(axis)
            ),
            ImageError::Provenance => {
                f.write_str("the provenance block or header extension is malformed")
            }
            ImageError::Geometric(e) => write!(f, "{e}"),
        }
    }
}

impl core::error::Error for ImageError {}

impl From<crate::geometric::GeometricError> for ImageError {
    fn from(e: crate::geometric::GeometricError) -> Self {
        ImageError::Geometric(e)
    }
}

/// Letter of an axis code (`?` for an unknown code).
fn axis_letter(code: u8) -> char {
    crate::axis::AxisName::from_code(code).map_or('?', |a| a.letter())
}

/// Why a group was refused: the error and the axis it concerns (None: the group as a whole or
/// its stage).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GroupError {
    /// The axis whose image or settings were refused.
    pub axis: Option<AxisName>,
    /// Why.
    pub error: ImageError,
}

impl core::fmt::Display for GroupError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.axis {
            Some(a) => write!(f, "axis {}: {}", a.letter(), self.error),
            None => write!(f, "{}", self.error),
        }
    }
}

impl core::error::Error for GroupError {}

impl From<ImageError> for GroupError {
    fn from(error: ImageError) -> Self {
        GroupError { axis: None, error }
    }
}
