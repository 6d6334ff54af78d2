//! One module per subcommand. Each turns its raw `Args` into a validated configuration, then runs.

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
pub mod image_board;
pub mod plan_geometry;
pub mod plan_rtest;
pub mod predict;
pub mod replay;
pub mod sim;
pub mod sim_probe;
pub mod trace;
pub mod validate_diagnosis;

use crate::cli::{Cli, Command, FitCommand, ImageCommand, PlanCommand};

pub fn dispatch(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
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
        Command::Image(ImageCommand::Group(a)) => image::group(a),
        Command::Replay(a) => replay::run(a),
        Command::Trace(a) => trace::run(a),
        Command::Export(a) => export::run(a),
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
