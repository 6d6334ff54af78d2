//! Command-line surface of `axcomp` (the contract is `../shared/spec/interfaces.md`).

use clap::{Parser, Subcommand};

use crate::commands;

#[derive(Debug, Parser)]
#[command(name = "axcomp", version, about = "Error compensation for machine axes (positioning tables, thermo-force, 21-term geometry, rotary axes, touch probe): fit, build images, export, simulate, diagnose", long_about = None, after_help = crate::EXIT_CODES_HELP)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
#[allow(clippy::large_enum_variant)] // parsed once per process; boxing would only add noise
pub enum Command {
    /// The whole loop on the twin in seconds: simulate, measure, fit, build the firmware image, apply it through the firmware library, print before/after; one linear axis, or with --all every system (positioning, thermo-force, three-axis geometry, five-axis rotary, touch probe).
    Demo(commands::demo::Args),
    /// Fit a compensation model from measurements.
    #[command(subcommand)]
    Fit(FitCommand),
    /// Plan a measurement campaign.
    #[command(subcommand)]
    Plan(PlanCommand),
    /// Build or inspect the firmware's binary table image.
    #[command(subcommand)]
    Image(ImageCommand),
    /// Run the firmware's compensation logic (under std) over a trace and write the corrected commands.
    Replay(commands::replay::Args),
    /// Write a binary trace (scale, command, temperatures, forces over time) for replay on the host or in QEMU.
    Trace(commands::trace::Args),
    /// Export a fitted model in the format a controller loads (positioning: LinuxCNC comp file, CSV; geometry:
    /// TwinCAT TF5280, Heidenhain .COM/.CMA; rotary: LinuxCNC xyzac/xyzbc-trt-kins values).
    Export(commands::export::Args),
    /// Simulate an axis (the digital twin) and write measurement CSV.
    Sim(commands::sim::Args),
    /// Diagnose the gap between a model and measurements: where it lies, which unmodelled effect explains it.
    Diagnose(commands::diagnose_shared::Args),
    /// Check the diagnosis on many twin campaigns with one effect withheld (detection, attribution, false alarms).
    ValidateDiagnosis(commands::validate_diagnosis::Args),
    /// Apply a fitted model file (positioning table, thermal model, geometry model, rotary-axis model, probe calibration, force law) to the rows of a CSV and write them with the predictions added.
    Predict(commands::predict::Args),
    /// Simulate touches of the twin's touch-trigger probe (calibration sphere, or a sphere, ring gauge and plane) as a touch CSV.
    SimProbe(commands::sim_probe::SimArgs),
}

#[derive(Debug, Subcommand)]
pub enum FitCommand {
    /// Fit a positioning-error table (linear, piecewise linear, cubic spline) from ISO 230-2 runs.
    Positioning(commands::fit_positioning::Args),
    /// Fit a thermal (thermo-force) error model from temperature/force/error time series.
    Thermal(commands::fit_thermal::Args),
    /// Fit cutting-force laws F = K·ap^x·fz^y·n^z and milling force coefficients.
    Force(commands::fit_force::Args),
    /// Calibrate a touch-trigger probe on a reference sphere: effective stylus radius and pretravel by direction and speed.
    Probe(commands::fit_probe::Args),
    /// Identify the 21 ISO 230-1 geometric errors of a three-axis machine from laser line measurements.
    Geometry(commands::fit_geometry::Args),
    /// Fit a five-axis machine's rotary-axis location errors (ISO 230-7) from R-test readings or probed sphere centres.
    Rtest(commands::fit_rtest::Args),
}

#[derive(Debug, Subcommand)]
pub enum PlanCommand {
    /// Propose laser lines that make all 21 geometric errors identifiable, with predicted uncertainties.
    Geometry(commands::plan_geometry::Args),
    /// Which R-test paths (added to K4) make the 11 location errors identifiable, and with what uncertainty.
    Rtest(commands::plan_rtest::Args),
}

#[derive(Debug, Subcommand)]
pub enum ImageCommand {
    /// Build a table image from fitted models.
    Build(commands::image::BuildArgs),
    /// Validate an image (single-axis or group) and print its contents.
    Inspect(commands::image::InspectArgs),
    /// Build a group image (schema 2) from axis images of `image build` (and a rotary model).
    ///
    /// One error, one source: a group in which an axis table and the geometric model's positioning
    /// component of that axis (EXX, EYY, EZZ), or the rotary model's and the geometric model's
    /// squareness (EC0Y, EB0Z, EA0Z), would both correct the same error is refused (naming both, writing
    /// nothing); `--exclude-geometric` leaves the geometric components out.
    Group(commands::image::GroupArgs),
}

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
