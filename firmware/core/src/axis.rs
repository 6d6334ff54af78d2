//! The names of a group's axes and how many a group has. A leaf: the image formats, the stages and
//! the engines name axes with these.

/// Axes in a group.
pub const MAX_AXES: usize = 5;

/// Name (and kind) of a group axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
#[repr(u8)]
pub enum AxisName {
    /// Linear X.
    #[default]
    X = 0,
    /// Linear Y.
    Y = 1,
    /// Linear Z.
    Z = 2,
    /// Rotary A (about X).
    A = 3,
    /// Rotary B (about Y).
    B = 4,
    /// Rotary C (about Z).
    C = 5,
}

impl AxisName {
    /// Every name, in code order.
    pub const ALL: [AxisName; 6] = [
        AxisName::X,
        AxisName::Y,
        AxisName::Z,
        AxisName::A,
        AxisName::B,
        AxisName::C,
    ];
    /// From its code (0..=5).
    pub const fn from_code(code: u8) -> Option<AxisName> {
        match code {
            0 => Some(AxisName::X),
            1 => Some(AxisName::Y),
            2 => Some(AxisName::Z),
            3 => Some(AxisName::A),
            4 => Some(AxisName::B),
            5 => Some(AxisName::C),
            _ => None,
        }
    }
    /// Its code.
    pub const fn code(self) -> u8 {
        self as u8
    }
    /// `'X'` … `'C'`.
    pub const fn letter(self) -> char {
        match self {
            AxisName::X => 'X',
            AxisName::Y => 'Y',
            AxisName::Z => 'Z',
            AxisName::A => 'A',
            AxisName::B => 'B',
            AxisName::C => 'C',
        }
    }
    /// From `'X'` … `'C'` (either case).
    pub const fn from_letter(c: char) -> Option<AxisName> {
        match c {
            'X' | 'x' => Some(AxisName::X),
            'Y' | 'y' => Some(AxisName::Y),
            'Z' | 'z' => Some(AxisName::Z),
            'A' | 'a' => Some(AxisName::A),
            'B' | 'b' => Some(AxisName::B),
            'C' | 'c' => Some(AxisName::C),
            _ => None,
        }
    }
    /// True for A, B, C.
    pub const fn is_rotary(self) -> bool {
        matches!(self, AxisName::A | AxisName::B | AxisName::C)
    }
}

/// One axis of a group as loaded: its name, its counts per revolution (rotary axes only, 0 for
/// a linear one) and its single-axis image (schema 1: table, thermo-force term, limits).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroupAxisImage<'a> {
    /// Which axis.
    pub name: AxisName,
    /// Rotary: counts per revolution (2..=2^31); linear: 0.
    pub counts_per_rev: u32,
    /// The axis's image bytes.
    pub image: &'a [u8],
}
