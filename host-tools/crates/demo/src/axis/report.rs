//! The demo's figures as text: the console summary, `demo.json` and `report.md`.

use std::fmt::Write as _;

use axcomp_positioning::fit::FitResult;
use axcomp_twin::Axis;
use serde_json::json;

use super::evaluated::Evaluated;

/// What the replay of the compensated moves showed.
pub(super) struct ReplayCheck {
    pub trace_bytes: usize,
    pub replayed: axcomp_image::replay::Replay,
    pub bit_for_bit: bool,
    /// Number of measured rows compared.
    pub points: usize,
    /// Largest |replayed correction − the twin's| at the measured rows, µm.
    pub agree_um: f64,
    pub summary: String,
}

/// One row of the ISO 230-2 figures table: the campaign's name, A, E, M, R, B and the RMS, µm.
pub(super) fn figures_row(name: &str, e: &Evaluated) -> Vec<String> {
    let i = &e.iso;
    vec![
        name.to_string(),
        format!("{:.2}", i.a_um),
        format!("{:.2}", i.e_um),
        format!("{:.2}", i.m_um),
        format!("{:.2}", i.r_um),
        format!("{:.2}", i.b_um),
        format!("{:.2}", e.rms_um),
    ]
}

/// The demo's results, for the console, `demo.json` and `report.md`.
pub(super) struct Demo<'a> {
    pub seed: u64,
    pub axis: &'a Axis,
    pub before: &'a Evaluated,
    pub after: &'a Evaluated,
    pub ideal: &'a Evaluated,
    pub fitted: &'a FitResult,
    pub image: &'a [u8],
    pub replay: &'a ReplayCheck,
}

impl Demo<'_> {
    /// The console summary up to the figures table and the reductions (`rows`: the figures' rows).
    pub fn console(&self, rows: &[Vec<String>]) -> String {
        let (axis, before, after, fitted) = (self.axis, self.before, self.after, self.fitted);
        let (image, r) = (self.image, self.replay);
        let reduction = |b: f64, a: f64| 100.0 * (1.0 - a / b);
        let mut console = String::new();
        let _ = writeln!(
            console,
            "axcomp demo: twin `{}` ({:.0}..{:.0} mm), ISO 230-2: {} targets × {} runs × 2 directions",
            axis.name,
            axis.start_mm,
            axis.end_mm,
            before.iso.targets.len(),
            before.data.run().map_or(0, |r| {
                let mut u = r.clone();
                u.sort();
                u.dedup();
                u.len()
            })
        );
        let _ = writeln!(
            console,
            "fit: {} ({}), raw RMS {:.2} µm → cross-validated {:.2} µm ({}); guard: passed",
            fitted.chosen, fitted.reason, fitted.raw_rms_um, fitted.cv_rms_um, fitted.split.method
        );
        let _ = writeln!(
            console,
            "image: {} bytes, {} segments of {:.3} mm per direction",
            image.len(),
            fitted.table.segments(),
            fitted.table.segment_mm
        );
        let _ = write!(
            console,
            "replay of the compensated moves (trace.bin, {} bytes) through axcomp_core::Engine: {}",
            r.trace_bytes, r.summary
        );
        let _ = writeln!(
            console,
            "  replayed bit for bit: {}; correction at the {} measured points vs the twin's: max |diff| {:.4} µm",
            if r.bit_for_bit { "yes" } else { "NO" },
            r.points,
            r.agree_um
        );
        let _ = writeln!(console);
        let _ = writeln!(
            console,
            "{:<24} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8}",
            "", "A µm", "E µm", "M µm", "R µm", "B µm", "RMS µm"
        );
        for row in rows {
            let _ = writeln!(
                console,
                "{:<24} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8}",
                row[0], row[1], row[2], row[3], row[4], row[5], row[6]
            );
        }
        let _ = writeln!(console);
        let _ = writeln!(
            console,
            "accuracy A: {:.2} → {:.2} µm ({:.0} % less); systematic E: {:.2} → {:.2} µm ({:.0} % less)",
            before.iso.a_um,
            after.iso.a_um,
            reduction(before.iso.a_um, after.iso.a_um),
            before.iso.e_um,
            after.iso.e_um,
            reduction(before.iso.e_um, after.iso.e_um)
        );
        console
    }

    /// `demo.json`.
    pub fn summary(&self) -> serde_json::Value {
        let (axis, before, after, ideal, fitted) =
            (self.axis, self.before, self.after, self.ideal, self.fitted);
        let (image, r) = (self.image, self.replay);
        json!({
            "axis": axis.name,
            "seed": self.seed,
            "rows": before.campaign.rows.len(),
            "model": { "chosen": fitted.chosen, "reason": fitted.reason, "cv_method": fitted.split.method,
                       "raw_rms_um": fitted.raw_rms_um, "cv_rms_um": fitted.cv_rms_um,
                       "segments": fitted.table.segments(), "segment_mm": fitted.table.segment_mm },
            "iso230_2_before": before.iso,
            "iso230_2_after": after.iso,
            "iso230_2_ideal": ideal.iso,
            "rms_before_um": before.rms_um,
            "rms_after_um": after.rms_um,
            "rms_ideal_um": ideal.rms_um,
            "image_bytes": image.len(),
            "replay": { "cycles": r.replayed.outputs.len(), "bit_for_bit": r.bit_for_bit,
                        "max_abs_correction_um": r.replayed.outputs.iter().map(|o| o.correction_um().abs() as f64).fold(0.0, f64::max),
                        "max_diff_to_twin_um": r.agree_um, "trace_bytes": r.trace_bytes },
        })
    }

    /// `report.md` (`table_md`: the ISO 230-2 figures table; `image_text`: the image's description).
    pub fn report(&self, table_md: &str, image_text: &str) -> String {
        let (axis, before, fitted, r) = (self.axis, self.before, self.fitted, self.replay);
        let mut md = String::new();
        let _ = writeln!(md, "# axcomp demo\n");
        let _ = writeln!(
            md,
            "Simulated axis `{}` ({:.0}–{:.0} mm; effects: {}), measured with an ISO 230-2 test \
             ({} targets, 5 bidirectional runs, seed {}). A table was fitted on that campaign, built into a \
             firmware image, and a **second campaign with new noise** (seed {}) was driven through the \
             firmware's compensator loaded from that image. The ideal row uses a table built from the twin's \
             known truth: the floor any fitted table could reach.\n",
            axis.name,
            axis.start_mm,
            axis.end_mm,
            axis.kinds()
                .iter()
                .map(|k| k.name())
                .collect::<Vec<_>>()
                .join(", "),
            before.iso.targets.len(),
            self.seed,
            self.seed + 1
        );
        let _ = writeln!(md, "## ISO 230-2 figures (bidirectional, µm)\n\n{table_md}");
        let _ = writeln!(
            md,
            "A = accuracy, E = systematic positional deviation, M = mean bidirectional positional deviation \
             range, R = repeatability, B = reversal value; RMS over all measured deviations.\n"
        );
        let _ = writeln!(
            md,
            "## Fit\n\nChosen model: `{}` — {}.\nRaw RMS {:.3} µm, cross-validated ({}) RMS {:.3} µm. \
             Do-no-harm guard: passed ({}).\nTable: {} segments of {:.3} mm per direction, resampling error \
             ≤ {:.3} µm.\n",
            fitted.chosen,
            fitted.reason,
            fitted.raw_rms_um,
            fitted.split.method,
            fitted.cv_rms_um,
            fitted.guard.rule,
            fitted.table.segments(),
            fitted.table.segment_mm,
            fitted.resampling_max_um
        );
        let _ = writeln!(md, "## Firmware image\n\n```\n{image_text}```\n");
        let _ = writeln!(
            md,
            "## Replay\n\nThe compensated moves, logged as a firmware trace (`trace.bin`: the image record, then one \
             cycle record per control cycle with an ideal servo), replayed through `axcomp_core::Engine` from the \
             file bytes (`axcomp replay --trace trace.bin --out replay.bin`):\n\n```\n{}```\n\
             Replayed bit for bit: {}. Correction at the {} measured points vs the correction the twin applied: \
             max |difference| {:.4} µm.\n",
            r.summary,
            if r.bit_for_bit { "yes" } else { "no" },
            r.points,
            r.agree_um
        );
        let _ = writeln!(
            md,
            "## Plots\n\n![before](deviation_before.svg)\n\n![after](deviation_after.svg)\n\n\
             ![ISO 230-2 before/after](iso230_before_after.svg)\n"
        );
        let _ = writeln!(
            md,
            "## Files\n\n`measurement.csv` (uncompensated campaign), `measurement_compensated.csv`, `table.json` \
             (`axcomp export --table table.json --format linuxcnc1 --step 5 --out x.comp`), `image.bin` \
             (`axcomp image inspect image.bin`), `demo.json` (figures).\n"
        );
        md
    }
}
