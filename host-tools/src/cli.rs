//! Argument types shared by several commands (the contract is `../shared/spec/interfaces.md`). The
//! subcommand tree that names each command's own arguments is [`crate::commands::Cli`]; this module names
//! no command, so every command may import it.

use std::path::PathBuf;

/// Options shared by every command that reads a measurement CSV (see the contract's "Common options").
#[derive(Debug, Clone, clap::Args)]
pub struct DataArgs {
    /// The measurement CSV.
    #[arg(long, value_name = "FILE")]
    pub data: std::path::PathBuf,
    /// Keep only rows where COL equals VALUE (repeatable).
    #[arg(long = "where", value_name = "COL=VALUE")]
    pub where_: Vec<String>,
    /// Rename a column before anything else (repeatable).
    #[arg(long, value_name = "OLD=NEW")]
    pub rename: Vec<String>,
    /// Multiply a column after renaming (repeatable).
    #[arg(long, value_name = "COL=FACTOR")]
    pub scale: Vec<String>,
}

/// Arguments of `axcomp sim`, shared by its two runs: a linear axis (`commands::sim`) and, with
/// `--machine`, a five-axis machine (`commands::sim_five_axis`).
#[derive(Debug, clap::Args)]
pub struct SimArgs {
    /// Where to write the measurement CSV.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Effects of the simulated axis, comma separated (contract names). Default: the linear-motor demo
    /// axis (pitch_error, reversal, cogging, interpolation_error, scale_expansion).
    #[arg(long, value_name = "K1,K2,..", conflicts_with = "axis")]
    pub effects: Option<String>,
    /// Measurement plan: iso230, scan, thermal, load, abbe, survey (all of them on one time line, the
    /// validation harness's plan), or spindle (thermo-force campaign under
    /// cutting load from axcomp-thermal's generator: 16 collinear sensors, spindle_rpm/ap_mm/fz_mm).
    #[arg(long, value_name = "PLAN", default_value = "iso230")]
    pub plan: String,
    /// Seed of the measurement noise (and of the parameters with --random-params).
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub seed: u64,
    /// Measurement noise σ on the deviation, µm [default: 0.5, or the --axis file's].
    #[arg(long = "noise-um", value_name = "SIGMA", allow_negative_numbers = true)]
    pub noise_um: Option<f64>,
    /// Resize the plan to about N rows.
    #[arg(long, value_name = "N")]
    pub rows: Option<usize>,
    /// Also write the truth (effect kinds and parameters, plan, seed) as JSON.
    #[arg(long, value_name = "FILE")]
    pub truth: Option<PathBuf>,
    /// Draw random plausible effect parameters from the seed instead of the typical ones.
    #[arg(long, conflicts_with = "axis")]
    pub random_params: bool,
    /// Simulate the axis described in FILE (the `axis` object of a truth JSON, or a bare axis).
    #[arg(long, value_name = "FILE")]
    pub axis: Option<PathBuf>,
    /// Run the campaign compensated: every move goes through the firmware's compensator
    /// (`axcomp_core::Compensator::cycle`) loaded from this image (`axcomp image build`).
    #[arg(long, value_name = "FILE")]
    pub image: Option<PathBuf>,
    /// Stroke start, mm (ignored with --axis).
    #[arg(
        long = "start-mm",
        value_name = "MM",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub start_mm: f64,
    /// Stroke end, mm (ignored with --axis).
    #[arg(
        long = "end-mm",
        value_name = "MM",
        default_value_t = 200.0,
        allow_negative_numbers = true
    )]
    pub end_mm: f64,
    /// Simulate a five-axis machine instead (ac-trunnion, bc-trunnion, bc-head) with rotary-axis location
    /// errors (offsets 5–50 µm, tilts and squareness 10–100 µrad, from the seed) measured by an R-test:
    /// writes the contract's R-test CSV; --plan rtest (default: K4 run 1, C circles at 0° and at the largest
    /// tilt, K4 run 2), rtest-h2 (the circles again with the sphere 50 mm higher, set-up 2) or k4 (K4 runs 1
    /// and 2); --effects from rotary_positioning, rotary_wobble, radial_runout, linear_geometry,
    /// thermal_drift, setup_drift; noise σ 0.3 µm unless --noise-um. --plan probe-rtest writes a touch
    /// probe's touches instead (the probe's σ 0.5 µm unless --noise-um; the twin's probe, pretravel by direction in the probe's frame, no glitches;
    /// top and four sides of a Ø25 mm sphere per pose, 300 mm/min; B = C = 0 as run 1 and revisited as
    /// run 3, tilts ±1, ±0.6, ±0.2 × --tilt-max-deg [default 50] at C = 0/90/180/270° as run 2), the input
    /// of `axcomp fit probe --machine KIND --group b_deg,c_deg,run --centres-out`.
    #[arg(long, value_name = "KIND", conflicts_with_all = ["axis", "image", "random_params", "rows"])]
    pub machine: Option<String>,
    /// Five-axis bc-head: distance from the B axis to the tool point, mm [default: 250].
    #[arg(long, value_name = "L", requires = "machine")]
    pub pivot_mm: Option<f64>,
    /// Five-axis: the sphere's nominal position, mm (table frame for a trunnion, machine frame for a head)
    /// [default: 150,0,100 for a trunnion, 0,0,0 for a head (150,50,-100 with --plan probe-rtest)].
    #[arg(
        long,
        value_name = "X,Y,Z",
        requires = "machine",
        allow_hyphen_values = true
    )]
    pub sphere_mm: Option<String>,
    /// Five-axis: the tilt axis's largest K4 angle, degrees [default: −60].
    #[arg(
        long,
        value_name = "DEG",
        requires = "machine",
        allow_negative_numbers = true
    )]
    pub tilt_max_deg: Option<f64>,
    /// Five-axis: poses per K4 run [default: 72] (C circles: half of it).
    #[arg(long, value_name = "N", requires = "machine")]
    pub k4_poses: Option<usize>,
}
