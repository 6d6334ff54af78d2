//! The checks of a group's images before anything is loaded: each axis image valid, names unique,
//! rotary grids spanning the turn, tables within the pool, and the cross-axis stages' axes present
//! and grids matching. The loader's part that both the group image parser
//! ([`crate::group_image::parse`]) and [`crate::group::Group::load`] run.

use crate::axis::{AxisName, GroupAxisImage, MAX_AXES};
use crate::error::{Field, GroupError, ImageError};
use crate::geometric::GeometricSpec;
use crate::image::{self, Layout};
use crate::rotary_spec::RotaryLocationSpec;

/// Every check of [`Group::load_stages`]: [`validate_group`] and the geometric stage's (X, Y, Z
/// in the group, a valid model, each grid spanning its axis's table grid if the axis has a
/// table, tables and functions within the pool of `pool` segments). Load-time code, one
/// out-of-line copy for every pool size (the image parser's and each group's).
#[inline(never)]
pub(crate) fn validate_group_stages(
    pool: usize,
    axes: &[GroupAxisImage],
    stage: Option<&RotaryLocationSpec>,
    geometric: Option<&GeometricSpec>,
) -> Result<[Option<Layout>; MAX_AXES], GroupError> {
    let layouts = validate_group(pool, axes, stage)?;
    let Some(spec) = geometric else {
        return Ok(layouts);
    };
    spec.validate().map_err(ImageError::from)?;
    let mut needed = spec.pool_entries();
    for (k, name) in [AxisName::X, AxisName::Y, AxisName::Z]
        .into_iter()
        .enumerate()
    {
        let Some(i) = axes.iter().position(|a| a.name == name) else {
            return Err(ImageError::AxisNotInGroup { axis: name.code() }.into());
        };
        let Some(l) = layouts[i] else { continue };
        if let Some((start, seg, n)) = image::table_grid(&l, axes[i].image) {
            let g = spec.grids[k];
            if start != g.start_counts
                || seg as i128 * n as i128 != g.end_counts() - g.start_counts as i128
            {
                return Err(GroupError {
                    axis: Some(name),
                    error: ImageError::GridMismatch { axis: name.code() },
                });
            }
        }
    }
    for l in layouts.iter().flatten() {
        let halves = if l.bidirectional { 2 } else { 1 };
        needed = needed.saturating_add(halves * l.n_segments as u32);
    }
    if needed as usize > pool {
        return Err(ImageError::PoolTooSmall { needed }.into());
    }
    Ok(layouts)
}

/// Every check of [`Group::load`] for a pool of `pool` segments; the layouts of the axis images
/// by slot.
fn validate_group(
    pool: usize,
    axes: &[GroupAxisImage],
    stage: Option<&RotaryLocationSpec>,
) -> Result<[Option<Layout>; MAX_AXES], GroupError> {
    if axes.is_empty() || axes.len() > MAX_AXES {
        return Err(ImageError::AxisCount.into());
    }
    let mut layouts = [None; MAX_AXES];
    let mut needed = 0u32;
    for (i, a) in axes.iter().enumerate() {
        let at = |error| GroupError {
            axis: Some(a.name),
            error,
        };
        if axes[..i].iter().any(|b| b.name == a.name) {
            return Err(at(ImageError::DuplicateAxis {
                axis: a.name.code(),
            }));
        }
        let l = image::validate(a.image).map_err(at)?;
        let cpr = a.counts_per_rev;
        let cpr_ok = if a.name.is_rotary() {
            (2..=1u32 << 31).contains(&cpr)
        } else {
            cpr == 0
        };
        if !cpr_ok {
            return Err(at(ImageError::OutOfRange {
                field: Field::CountsPerRev,
                index: i as u16,
            }));
        }
        if a.name.is_rotary() {
            if let Some((start, seg, n)) = image::table_grid(&l, a.image) {
                if start != 0 || seg as u64 * n as u64 != cpr as u64 {
                    return Err(at(ImageError::GridMismatch {
                        axis: a.name.code(),
                    }));
                }
            }
        }
        let halves = if l.bidirectional { 2 } else { 1 };
        needed = needed.saturating_add(halves * l.n_segments as u32);
        layouts[i] = Some(l);
    }
    if needed as usize > pool {
        return Err(ImageError::PoolTooSmall { needed }.into());
    }
    if let Some(spec) = stage {
        spec.validate()?;
        for name in [
            AxisName::X,
            AxisName::Y,
            AxisName::Z,
            spec.machine.tilt_axis(),
            AxisName::C,
        ] {
            if !axes.iter().any(|a| a.name == name) {
                return Err(ImageError::AxisNotInGroup { axis: name.code() }.into());
            }
        }
    }
    Ok(layouts)
}
