//! Which board input feeds each sensor of an image: matched by name, so a reading is never fed to a
//! sensor of another quantity (e.g. a board's RTD at 22 °C fed to a warm-up input whose
//! range is −0.5…1.5 would leave the sensor stale and freeze the thermal term).
//!
//! # Glossary
//! - **board input**: a reading the board delivers ([`BoardInput`]): a name (`rtd0`) and a unit
//!   ([`InputUnit`]). The board declares them in its reading order: reading `k` of a set is input `k`.
//! - **sensor name**: the image's name of sensor `j` of an axis (group sensor-names section, or the
//!   `SNAM` block of a schema-1 image's header extension, [`crate::provenance`]).
//! - **wiring** ([`SensorWiring`]): for each sensor `j` of an axis, the board input it reads.
//!   - A **named** sensor reads the input of the same name (exact, case-sensitive); a name no input
//!     has is refused ([`WiringError::NotOnBoard`]).
//!   - An image **without names** (written before names existed) is wired by position: sensor `j` =
//!     input `j`, only onto temperature inputs (°C); more sensors than inputs is refused
//!     ([`WiringError::NotWired`]), as is an unnamed sensor on an input of another unit
//!     ([`WiringError::UnitMismatch`]).

use crate::MAX_SENSORS;
use crate::group_image::AxisSection;

/// What a board input measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputUnit {
    /// A temperature in °C (an RTD, a thermocouple).
    DegC,
    /// A normalised warm-up state (0 cold … 1 warm, e.g. from a drive-enable input).
    WarmupState,
}

impl InputUnit {
    /// Unit text for inspection output.
    pub const fn name(self) -> &'static str {
        match self {
            InputUnit::DegC => "°C",
            InputUnit::WarmupState => "warm-up state (0..1)",
        }
    }
}

/// One input a board delivers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoardInput<'a> {
    /// The name images use for it.
    pub name: &'a str,
    /// What it measures.
    pub unit: InputUnit,
}

/// For each sensor of an axis, the board input (index into the board's inputs) it reads.
pub type SensorWiring = [u8; MAX_SENSORS];

/// The positional wiring (sensor `j` = input `j`).
pub const POSITIONAL: SensorWiring = {
    let mut w = [0u8; MAX_SENSORS];
    let mut j = 0;
    while j < MAX_SENSORS {
        w[j] = j as u8;
        j += 1;
    }
    w
};

/// Why an axis's sensors cannot be wired to a board.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WiringError {
    /// Sensor `sensor` has a name none of the board's inputs has.
    NotOnBoard {
        /// Sensor index in the axis.
        sensor: u8,
    },
    /// The image (without names) needs more inputs than the board has.
    NotWired {
        /// Sensors the axis has.
        needed: u8,
        /// Inputs of the board.
        wired: u8,
    },
    /// An unnamed sensor would read an input that is not a temperature.
    UnitMismatch {
        /// Sensor index in the axis.
        sensor: u8,
    },
}

impl core::fmt::Display for WiringError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            WiringError::NotOnBoard { sensor } => write!(
                f,
                "sensor {sensor}'s name is not an input of this board (it would read another quantity or nothing)"
            ),
            WiringError::NotWired { needed, wired } => write!(
                f,
                "the image needs {needed} sensor inputs, the board has {wired}"
            ),
            WiringError::UnitMismatch { sensor } => write!(
                f,
                "unnamed sensor {sensor} would read a board input that is not a temperature"
            ),
        }
    }
}

impl core::error::Error for WiringError {}

/// The wiring of `n_sensors` sensors of `axis` onto `inputs` (see the module docs).
pub fn wire_axis(
    axis: &AxisSection,
    n_sensors: usize,
    inputs: &[BoardInput],
) -> Result<SensorWiring, WiringError> {
    let mut w = POSITIONAL;
    let named = !axis.sensor_names.is_empty();
    if !named && n_sensors > inputs.len() {
        return Err(WiringError::NotWired {
            needed: n_sensors.min(255) as u8,
            wired: inputs.len().min(255) as u8,
        });
    }
    for (j, slot) in w.iter_mut().enumerate().take(n_sensors.min(MAX_SENSORS)) {
        if named {
            let name = axis.sensor_name(j).unwrap_or("");
            let k = inputs
                .iter()
                .position(|i| i.name == name)
                .ok_or(WiringError::NotOnBoard { sensor: j as u8 })?;
            *slot = k as u8;
        } else if inputs.get(j).map(|i| i.unit) != Some(InputUnit::DegC) {
            return Err(WiringError::UnitMismatch { sensor: j as u8 });
        }
    }
    Ok(w)
}
