//! What each board has, as constants outside the board modules (which build only for the chip): the
//! board's drive checks every image against them ([`crate::drive::group::GroupDrive::offer_image`]),
//! and the host (`axcomp image build`, `image inspect`) runs the same check with the same values on
//! an image before it reaches a board.
//!
//! Glossary:
//! - **caps** ([`BoardCaps`]): counter width, axis ids wired (one per scale input), sensors wired.
//! - **sensor inputs**: the board's readings by name and unit ([`BoardInput`]); an image's sensor
//!   is wired to the input of its name at load.
//! - **pool**: table segments of the group engine per A/B slot, shared by the group's axes.

/// The STM32G474RE board (NUCLEO-G474RE wiring, `board::stm32g474`).
pub mod stm32g474 {
    use crate::drive::BoardCaps;
    use axcomp_core::wiring::{BoardInput, InputUnit};

    /// Number of RTD channels wired on this board.
    pub const RTD_COUNT: usize = 2;
    /// Scale inputs (timers in encoder mode) wired on this board.
    pub const SCALE_INPUTS: usize = 3;
    /// Axis id of each scale input (and its position in the setpoint frame): set them to the machine's.
    pub const AXIS_IDS: [u16; SCALE_INPUTS] = [1, 2, 3];
    /// What this board has: every image is checked against it before it is applied.
    pub const CAPS: BoardCaps = BoardCaps {
        counter_bits: 16,
        axis_ids: &AXIS_IDS,
        sensors: RTD_COUNT as u16,
    };
    /// The board's sensor inputs by name and unit, in reading order (RTD on chip select PB0, PB1): an
    /// image's sensors are wired to them by name at load, and a sensor none of them can feed (e.g. a
    /// `warmup` input: this board has no drive-enable input wired) is refused
    /// ([`crate::drive::ImageRefusal::SensorNotOnBoard`]). Like [`AXIS_IDS`], name them after what is
    /// wired on the machine (the replays name them `spindle`, `column`:
    /// [`crate::drive::link_trace::REPLAY_SENSOR_INPUTS`]).
    pub const SENSOR_INPUTS: [BoardInput<'static>; RTD_COUNT] = [
        BoardInput {
            name: "rtd0",
            unit: InputUnit::DegC,
        },
        BoardInput {
            name: "rtd1",
            unit: InputUnit::DegC,
        },
    ];
    /// Table segments of the group engine per A/B slot, shared by its axes: 2 × 2048 × 16 B = 64 KiB,
    /// as the single-axis engine's two 1024-segment bidirectional slots were.
    pub const POOL: usize = 2048;
}
