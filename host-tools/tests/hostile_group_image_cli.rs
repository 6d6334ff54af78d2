//! Hostile inputs to group images (`image group`, `image inspect`; contract: `shared/spec/interfaces.md`,
//! the image sections): what the firmware refuses, the host refuses with the firmware's own reason
//! (`axcomp_core::group_image`). Each test failed before its fix.

use std::path::Path;

use axcomp_core::group::AxisName;
use axcomp_core::group_image::{self, AxisSectionSpec};
use axcomp_core::{ImageSpec, LimitSpec, image_len, write_image};

mod common;
use common::{axcomp_in, fails_untouched_naming, scratch};

/// An axis image for `axis_id` with `table` (None: a bare image) and no thermal term.
fn axis_image(axis_id: u16, table: Option<axcomp_core::TableSpec>) -> Vec<u8> {
    let spec = ImageSpec {
        axis_id,
        um_per_count: 0.1,
        counter_bits: 32,
        table,
        thermo: None,
        limits: LimitSpec {
            max_correction_um: 100.0,
            max_slew_um_per_cycle: 10.0,
            direction_hysteresis_counts: 0,
        },
    };
    let mut buf = vec![0u8; image_len(&spec)];
    let n = write_image(&spec, &mut buf).unwrap();
    buf.truncate(n);
    buf
}

/// A bare axis image (no table, no thermal term) for axis id `axis_id`.
fn bare(axis_id: u16) -> Vec<u8> {
    axis_image(axis_id, None)
}

/// A group image of X and Y with the given axis ids, written by the core's own writer.
fn group_of(dir: &Path, name: &str, ids: [u16; 2]) {
    let imgs = [bare(ids[0]), bare(ids[1])];
    let specs: Vec<AxisSectionSpec> = [AxisName::X, AxisName::Y]
        .into_iter()
        .zip(&imgs)
        .map(|(name, img)| AxisSectionSpec {
            name,
            counts_per_rev: 0,
            stroke_counts: None,
            image: img,
            sensor_names: &[],
        })
        .collect();
    let mut buf = vec![0u8; group_image::group_image_len(&specs, None)];
    let n = group_image::write_group_image(&specs, None, &mut buf).unwrap();
    std::fs::write(dir.join(name), &buf[..n]).unwrap();
}

/// `image group` of two axis images that carry one axis id: must not be written with exit 0, since
/// every board refuses it (one scale input cannot feed two axes). Exit 2 with the firmware's
/// reason, nothing written; distinct ids still group.
#[test]
fn image_group_refuses_one_axis_id_on_two_axes() {
    let dir = scratch("group-ids");
    std::fs::write(dir.join("x.bin"), bare(1)).unwrap();
    std::fs::write(dir.join("y.bin"), bare(1)).unwrap();
    std::fs::write(dir.join("y2.bin"), bare(2)).unwrap();
    fails_untouched_naming(
        &[
            "image", "group", "--axis", "X=x.bin", "--axis", "Y=y.bin", "--out", "g.bin",
        ],
        &dir,
        &["axis id 1 is on two axes"],
    );
    let o = axcomp_in(
        &[
            "image", "group", "--axis", "X=x.bin", "--axis", "Y=y2.bin", "--out", "g.bin",
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// `image inspect` of a group image with one axis id on two axes (written by another tool): not "ok" but
/// exit 2 with the firmware's reason.
#[test]
fn image_inspect_refuses_one_axis_id_on_two_axes() {
    let dir = scratch("inspect-ids");
    group_of(&dir, "twice.bin", [3, 3]);
    group_of(&dir, "fine.bin", [3, 4]);
    fails_untouched_naming(
        &["image", "inspect", "twice.bin"],
        &dir,
        &["axis id 3 is on two axes"],
    );
    let o = axcomp_in(&["image", "inspect", "fine.bin"], &dir);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// An axis image for `axis_id` whose table spans 0..100,000 counts (10 mm at 0.1 µm per count).
fn with_table(axis_id: u16) -> Vec<u8> {
    let seg = [[0.0f32; 4]; 10];
    axis_image(
        axis_id,
        Some(axcomp_core::TableSpec {
            start_counts: 0,
            segment_counts: 10_000,
            forward: &seg,
            backward: &[],
            outside: axcomp_core::OutsideStroke::Hold,
        }),
    )
}

/// `image group --rotary` with the pivot's X 1e10 counts away (mm typed where counts belong, ×10^4):
/// must not be written (the firmware would load it and correct about a pivot 1 km off). Exit 2 with
/// the firmware's reason (`GroupImageView::check_pivot`: X's table spans 0..100,000 counts, so the
/// pivot's X may lie in −100,000..200,000), nothing written; a pivot inside still groups.
#[test]
fn image_group_refuses_a_pivot_far_outside_the_strokes() {
    let dir = scratch("group-pivot");
    std::fs::write(dir.join("x.bin"), with_table(1)).unwrap();
    for (f, id) in [("y.bin", 2), ("z.bin", 3), ("a.bin", 4), ("c.bin", 5)] {
        std::fs::write(dir.join(f), bare(id)).unwrap();
    }
    let rotary = |x: i64| {
        format!(
            "{{\"ex0c_um\": 0, \"ey0c_um\": 0, \"ea0c_urad\": 0, \"eb0c_urad\": 0, \"ey0a_um\": 0, \
             \"ez0a_um\": 0, \"eb0a_urad\": 0, \"ec0a_urad\": 0, \"pivot_counts\": [{x}, 0, 0], \
             \"tool_length_um\": 0}}"
        )
    };
    std::fs::write(dir.join("far.json"), rotary(10_000_000_000)).unwrap();
    std::fs::write(dir.join("near.json"), rotary(150_000)).unwrap();
    let args = |model: &'static str| {
        [
            "image",
            "group",
            "--axis",
            "X=x.bin",
            "--axis",
            "Y=y.bin",
            "--axis",
            "Z=z.bin",
            "--axis",
            "A:3600000=a.bin",
            "--axis",
            "C:3600000=c.bin",
            "--rotary",
            model,
            "--out",
            "g.bin",
        ]
    };
    fails_untouched_naming(
        &args("far.json"),
        &dir,
        &["rotary pivot's X lies outside the X stroke"],
    );
    let o = axcomp_in(&args("near.json"), &dir);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
