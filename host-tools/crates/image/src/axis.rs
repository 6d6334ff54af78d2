//! One axis of a group as `image group` is given it (a leaf: the section builders and the group writer
//! both name it).

use axcomp_core::group::AxisName;

/// One axis of a group: its name, counts per revolution (0 for a linear axis), its single-axis image
/// and how the user gave it (e.g. `X=x.bin`, for messages).
#[derive(Debug, Clone)]
pub struct GroupAxis {
    pub name: AxisName,
    pub counts_per_rev: u32,
    pub image: Vec<u8>,
    pub given_as: String,
}
