//! One module per subcommand. Each turns its raw `Args` into a validated configuration, then runs.
//!
//! This module holds the subcommand tree ([`Cli`], which names each command's `Args`) and the dispatch;
//! the command modules import no other command and not this module: what they share is in
//! [`crate::cli`] (argument types) and [`common`] (helpers).

pub mod common;
pub mod demo;
pub mod demo_all;
pub mod diagnose;
pub mod diagnose_lines;
pub mod diagnose_probe;
pub mod diagnose_rtest;
pub mod diagnose_shared;
pub mod export;
pub mod fit_force;
pub mod fit_geometry;
pub mod fit_positioning;
pub mod fit_probe;
pub mod fit_rtest;
pub mod fit_thermal;
pub mod image;
pub mod image_group;
pub mod plan_geometry;
pub mod plan_rtest;
pub mod predict;
pub mod replay;
pub mod sim;
pub mod sim_five_axis;
pub mod sim_probe;
pub mod trace;
pub mod validate_diagnosis;

use clap::{Parser, Subcommand};

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
    Demo(demo::Args),
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
    Replay(replay::Args),
    /// Write a binary trace (scale, command, temperatures, forces over time) for replay on the host or in QEMU.
    Trace(trace::Args),
    /// Export a fitted model in the format a controller loads (positioning: LinuxCNC comp file, CSV; geometry:
    /// TwinCAT TF5280, Heidenhain .COM/.CMA; rotary: LinuxCNC xyzac/xyzbc-trt-kins values).
    Export(export::Args),
    /// Simulate an axis (the digital twin) and write measurement CSV.
    Sim(crate::cli::SimArgs),
    /// Diagnose the gap between a model and measurements: where it lies, which unmodelled effect explains it.
    Diagnose(diagnose_shared::Args),
    /// Check the diagnosis on many twin campaigns with one effect withheld (detection, attribution, false alarms).
    ValidateDiagnosis(validate_diagnosis::Args),
    /// Apply a fitted model file (positioning table, thermal model, geometry model, rotary-axis model, probe calibration, force law) to the rows of a CSV and write them with the predictions added.
    Predict(predict::Args),
    /// Simulate touches of the twin's touch-trigger probe (calibration sphere, or a sphere, ring gauge and plane) as a touch CSV.
    SimProbe(sim_probe::SimArgs),
}

#[derive(Debug, Subcommand)]
pub enum FitCommand {
    /// Fit a positioning-error table (linear, piecewise linear, cubic spline) from ISO 230-2 runs.
    Positioning(fit_positioning::Args),
    /// Fit a thermal (thermo-force) error model from temperature/force/error time series.
    Thermal(fit_thermal::Args),
    /// Fit cutting-force laws F = K·ap^x·fz^y·n^z and milling force coefficients.
    Force(fit_force::Args),
    /// Calibrate a touch-trigger probe on a reference sphere: effective stylus radius and pretravel by direction and speed.
    Probe(fit_probe::Args),
    /// Identify the 21 ISO 230-1 geometric errors of a three-axis machine from laser line measurements.
    Geometry(fit_geometry::Args),
    /// Fit a five-axis machine's rotary-axis location errors (ISO 230-7) from R-test readings or probed sphere centres.
    Rtest(fit_rtest::Args),
}

#[derive(Debug, Subcommand)]
pub enum PlanCommand {
    /// Propose laser lines that make all 21 geometric errors identifiable, with predicted uncertainties.
    Geometry(plan_geometry::Args),
    /// Which R-test paths (added to K4) make the 11 location errors identifiable, and with what uncertainty.
    Rtest(plan_rtest::Args),
}

#[derive(Debug, Subcommand)]
pub enum ImageCommand {
    /// Build a table image from fitted models.
    Build(image::BuildArgs),
    /// Validate an image (single-axis or group) and print its contents.
    Inspect(image::InspectArgs),
    /// Build a group image (schema 2) from axis images of `image build` (and a rotary model).
    ///
    /// One error, one source: a group in which an axis table and the geometric model's positioning
    /// component of that axis (EXX, EYY, EZZ), or the rotary model's and the geometric model's
    /// squareness (EC0Y, EB0Z, EA0Z), would both correct the same error is refused (naming both, writing
    /// nothing); `--exclude-geometric` leaves the geometric components out.
    Group(image_group::GroupArgs),
}

pub fn dispatch(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Demo(a) if a.all => {
            let out = a.out.unwrap_or_else(demo_all::default_out);
            demo_all::run_all(&out, a.seed)
        }
        Command::Demo(a) => demo::run(a),
        Command::Fit(FitCommand::Positioning(a)) => fit_positioning::run(a),
        Command::Fit(FitCommand::Thermal(a)) => fit_thermal::run(a),
        Command::Fit(FitCommand::Force(a)) => fit_force::run(a),
        Command::Fit(FitCommand::Probe(a)) => fit_probe::run(a),
        Command::Fit(FitCommand::Geometry(a)) => fit_geometry::run(a),
        Command::Plan(PlanCommand::Geometry(a)) => plan_geometry::run(a),
        Command::Fit(FitCommand::Rtest(a)) => fit_rtest::run(a),
        Command::Plan(PlanCommand::Rtest(a)) => plan_rtest::run(a),
        Command::Image(ImageCommand::Build(a)) => image::build(a),
        Command::Image(ImageCommand::Inspect(a)) => image::inspect(a),
        Command::Image(ImageCommand::Group(a)) => image_group::group(a),
        Command::Replay(a) => replay::run(a),
        Command::Trace(a) => trace::run(a),
        Command::Export(a) => export::run(a),
        Command::Sim(a) if a.machine.is_some() => sim_five_axis::run(a),
        Command::Sim(a) => sim::run(a),
        Command::Diagnose(a) => diagnose_by_kind(a),
        Command::ValidateDiagnosis(a) => validate_diagnosis::run(a),
        Command::Predict(a) => predict::run(a),
        Command::SimProbe(a) => sim_probe::sim_probe(a),
    }
}

/// `axcomp diagnose`: the file's columns say which kind of data it is (contract: "Effect kinds for
/// geometry, rotary-axis and probe data"); each kind has its own command module.
fn diagnose_by_kind(args: diagnose_shared::Args) -> anyhow::Result<()> {
    use axcomp_effects::DataKind;
    let ds = common::load_dataset(&args.data)?;
    match DataKind::detect(&ds.column_names()) {
        Some(DataKind::LaserLines) => diagnose_lines::run(&args, ds),
        Some(DataKind::RTest) => diagnose_rtest::run(&args, ds),
        Some(DataKind::ProbeTouches) => diagnose_probe::run(&args, ds),
        Some(DataKind::Axis) | None => diagnose::run(args, ds),
    }
}
