//! axcomp-thermal: thermo-force error models for precision axes.
//!
//! Glossary:
//! - **sensor**: a temperature channel (`NAME_degC`), **rise** ΔT: its change against a reference reading.
//! - **lag**: first-order delay of a temperature with time constant τ, as the structure follows it
//!   ([`axcomp_numeric::lag`]).
//! - **selection**: choosing a few sensors out of many collinear ones: the reference method fuzzy c-means +
//!   grey relational analysis ([`fcm`], [`gra`]) and forward selection scored by cross-validation
//!   ([`select`]).
//! - **thermal model**: `e = b0 + Σ b ΔT + Σ χ F`, fitted by QR least squares ([`axcomp_numeric::lsq`], [`thermal`]).
//! - **force law**: `F = K·ap^x·fz^y·n^z` ([`force`]); **cutting coefficients** Ktc, Krc, Kac (cutting) and
//!   Kte, Kre, Kae (edge) of a milling cutter from mean forces ([`milling`]).

pub mod blocks;
pub mod choice;
pub mod fcm;
pub mod force;
pub mod force_data;
pub mod gra;
pub mod input;
pub mod milling;
pub mod model_file;
pub mod predict;
mod prepare;
pub mod quality;
pub mod report;
pub mod request;
pub mod runs;
pub mod select;
pub mod thermal;

pub use thermal::{
    CandidateReport, ForceTerm, Reference, Ridge, Selection, SensorTerm, Series, ThermalError,
    ThermalFit, ThermalInput, ThermalModel, ThermalOptions, ValidationReport, fit_thermal,
};
