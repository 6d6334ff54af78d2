//! A thermo-force fit as the command line asks for it: the options checked before anything is read, the
//! columns of a measurement file turned into a [`ThermalInput`], the rows' quality, and the fit's summary,
//! JSON and model file. `axcomp fit thermal` parses into a [`ThermalRequest`], calls these methods and
//! [`crate::fit_thermal`], and writes.
//!
//! Glossary:
//! - **target**: the `*_um` error channel modelled; **sensors**: every `*_degC` column (or the chosen subset);
//!   **forces**: every `*_N` column (unless left out), fitted jointly as χ·F terms.
//! - **target offset**: the mean of the target's first N rows, subtracted (`--zero-at-start N`) so the target
//!   is the change since the start; the model file records it.
//! - **notice**: a note or warning line for the user (`note: …`, `warning: …`), in the order it arises.

use std::path::PathBuf;

use axcomp_data::{DataError, Dataset, HoldoutSpec, groups};
use serde_json::Value;

use crate::model_file::{ModelForceLaw, ThermalModelFile};
use crate::quality::{Glitches, Stopped};
use crate::runs::RunIndex;
use crate::thermal::{
    Ridge, Selection, Series, ThermalError, ThermalFit, ThermalInput, ThermalOptions,
};

/// Why a request cannot be run: a message naming the option, file, line or column at fault.
#[derive(Debug, thiserror::Error)]
pub enum RequestError {
    #[error("{0}")]
    Input(String),
    #[error(transparent)]
    Data(#[from] DataError),
    #[error(transparent)]
    Thermal(#[from] ThermalError),
}

fn input(msg: String) -> RequestError {
    RequestError::Input(msg)
}

/// The options of `axcomp fit thermal` (see its help for each).
#[derive(Debug, Clone, Default)]
pub struct ThermalRequest {
    pub data: PathBuf,
    pub target: String,
    pub holdout: Option<String>,
    pub runs: Option<String>,
    pub cv: Option<String>,
    /// `COL=LAW.json` force laws to attach to force terms.
    pub force_law: Vec<String>,
    pub lags: bool,
    pub no_lags: bool,
    pub ridge: Option<String>,
    pub select: String,
    pub max_sensors: usize,
    pub sensors: Vec<String>,
    pub no_forces: bool,
    pub zero_at_start: Option<usize>,
    pub sensor_period_ms: u32,
}

/// The fit's input read from the file, and what reading it decided.
#[derive(Debug)]
pub struct ReadInput {
    pub input: ThermalInput,
    /// The value subtracted from the target (`--zero-at-start`; 0 without).
    pub target_offset_um: f64,
    /// Why the lagged candidates were left out, when the file has no time column.
    pub lags_note: Option<String>,
    /// Force columns constant on the training rows, left out of the model.
    pub excluded_forces: Vec<String>,
}

/// Glitches and stopped stretches of the target and the sensors (reported; the fit keeps every row).
#[derive(Debug)]
pub struct RowQuality {
    pub glitches: Vec<Glitches>,
    pub stopped: Vec<Stopped>,
}

impl ThermalRequest {
    /// The fit options, checked before anything is read.
    pub fn options(&self) -> Result<ThermalOptions, RequestError> {
        let forced_selection = self.select != "auto";
        let ridge = match self.ridge.as_deref() {
            None if forced_selection => Ridge::Off,
            None => Ridge::Auto,
            Some("auto") => Ridge::Auto,
            Some(s) => match s.parse::<f64>() {
                Ok(l) if l >= 0.0 && l.is_finite() => Ridge::Fixed(l),
                _ => {
                    return Err(input(format!(
                        "--ridge `{s}`: expected a number >= 0 or `auto`"
                    )));
                }
            },
        };
        let selection = match self.select.as_str() {
            "auto" => Selection::Auto,
            "fcm-gra" | "fcm_gra" => Selection::FcmGra,
            "forward" => Selection::Forward,
            "all" => Selection::All,
            "greedy" => Selection::Greedy,
            s => {
                return Err(input(format!(
                    "--select `{s}`: expected auto, fcm-gra, forward, greedy or all"
                )));
            }
        };
        if self.sensor_period_ms == 0 {
            return Err(input("--sensor-period-ms must be > 0".into()));
        }
        if let Some(0) = self.zero_at_start {
            return Err(input("--zero-at-start 0: must be at least 1".into()));
        }
        Ok(ThermalOptions {
            // The default choice always compares lagged candidates (unless --no-lags), and so does greedy (the
            // reference with lags); another forced selection fits lags only with --lags.
            lags: if forced_selection && selection != Selection::Greedy {
                self.lags
            } else {
                !self.no_lags
            },
            ridge,
            max_sensors: self.max_sensors,
            selection,
            reference_rows: self.zero_at_start.unwrap_or(1),
            ..ThermalOptions::default()
        }
        .build()?)
    }

    /// The holdout rule, parsed.
    pub fn holdout_spec(&self) -> Result<Option<HoldoutSpec>, RequestError> {
        Ok(self
            .holdout
            .as_deref()
            .map(HoldoutSpec::parse)
            .transpose()?)
    }

    /// The `--force-law COL=LAW.json` files, read and checked.
    pub fn force_laws(&self) -> Result<Vec<(String, ModelForceLaw)>, RequestError> {
        self.force_law
            .iter()
            .map(|s| {
                let (col, path) = s
                    .split_once('=')
                    .ok_or_else(|| input(format!("--force-law `{s}`: expected COL=LAW.json")))?;
                let text = std::fs::read_to_string(path)
                    .map_err(|e| input(format!("--force-law: reading {path}: {e}")))?;
                let law: ModelForceLaw = serde_json::from_str(&text).map_err(|e| {
                    input(format!(
                        "--force-law: {path} is not a force-law file (k, x_ap, y_fz, z_n): {e}"
                    ))
                })?;
                if ![law.k, law.x_ap, law.y_fz, law.z_n]
                    .iter()
                    .all(|v| v.is_finite())
                    || law.k <= 0.0
                {
                    return Err(input(format!(
                        "--force-law: {path}: k must be > 0 and all values finite"
                    )));
                }
                Ok((col.trim().to_string(), law))
            })
            .collect()
    }

    /// The fit's input from `ds`: target (less its offset), time, sensors, forces, groups and held-out rows.
    /// `opts.lags` is switched off when the file has no time column. `time_hint` completes a message about a
    /// missing time column; `notice` receives each note as it arises.
    pub fn read_input(
        &self,
        ds: &Dataset,
        holdout: Option<&HoldoutSpec>,
        laws: &[(String, ModelForceLaw)],
        opts: &mut ThermalOptions,
        time_hint: &str,
        notice: &mut dyn FnMut(String),
    ) -> Result<ReadInput, RequestError> {
        let n = ds.n_rows();
        if n == 0 {
            return Err(input(format!(
                "{}: no rows (after --where)",
                self.data.display()
            )));
        }
        let (target, target_offset_um) = self.read_target(ds)?;
        let (time_s, lags_note) = self.read_time(ds, opts, time_hint, notice)?;
        let sensors = self.read_sensors(ds)?;
        let forces = self.read_forces(ds)?;
        let labels_of = |col: &Option<String>| -> Result<Option<Vec<String>>, RequestError> {
            let Some(col) = col else { return Ok(None) };
            let (ids, labels) = groups(ds, col)?;
            Ok(Some(ids.into_iter().map(|i| labels[i].clone()).collect()))
        };
        let conditions = labels_of(&self.cv)?;
        for (col, _) in laws {
            if !forces.iter().any(|f| &f.name == col) {
                return Err(input(format!(
                    "--force-law {col}: not a force column of the model (have: {})",
                    forces
                        .iter()
                        .map(|f| f.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                )));
            }
        }
        let held = holdout.map(|h| h.mask(ds)).transpose()?;
        let runs = labels_of(&self.runs)?;
        self.check_finite(ds, &target, &time_s, &sensors, &forces)?;
        let (forces, excluded_forces) =
            self.drop_constant_forces(forces, held.as_deref(), laws, notice)?;
        Ok(ReadInput {
            input: ThermalInput {
                time_s,
                sensors,
                forces,
                target,
                conditions,
                holdout: held,
                runs,
            },
            target_offset_um,
            lags_note,
            excluded_forces,
        })
    }

    /// The target column, less the mean of its first N rows with `--zero-at-start N`.
    fn read_target(&self, ds: &Dataset) -> Result<(Vec<f64>, f64), RequestError> {
        let n = ds.n_rows();
        let mut target = ds.numeric(&self.target)?.to_vec();
        let mut target_offset = 0.0;
        if let Some(k) = self.zero_at_start {
            if k == 0 || k > n {
                return Err(input(format!("--zero-at-start {k}: must be 1..={n}")));
            }
            target_offset = target[..k].iter().sum::<f64>() / k as f64;
            target.iter_mut().for_each(|v| *v -= target_offset);
        }
        Ok((target, target_offset))
    }

    /// The time of each row. Without it a lag's time constant would be in rows, not seconds (and `predict`
    /// and the firmware read it as seconds): the default choice then has no lagged candidates.
    fn read_time(
        &self,
        ds: &Dataset,
        opts: &mut ThermalOptions,
        time_hint: &str,
        notice: &mut dyn FnMut(String),
    ) -> Result<(Vec<f64>, Option<String>), RequestError> {
        if let Some(t) = ds.time_s() {
            return Ok((t.to_vec(), None));
        }
        if ds.has("time_s") {
            ds.numeric("time_s")?;
        }
        if self.lags {
            return Err(input(format!(
                "--lags needs a `time_s` column (or a `time` column of timestamps) in {}{}",
                self.data.display(),
                time_hint
            )));
        }
        let mut lags_note = None;
        if opts.lags {
            opts.lags = false;
            let note = format!(
                "{}: no `time_s` column (nor a `time` column of timestamps){}: lagged candidates left out \
                 (a time constant needs the time of each row)",
                self.data.display(),
                time_hint
            );
            notice(format!("note: {note}"));
            lags_note = Some(note);
        }
        Ok(((0..ds.n_rows()).map(|i| i as f64).collect(), lags_note))
    }

    /// The `*_degC` sensors (or the `--sensors` subset).
    fn read_sensors(&self, ds: &Dataset) -> Result<Vec<Series>, RequestError> {
        let mut names = ds.sensors();
        if !self.sensors.is_empty() {
            for s in &self.sensors {
                if !names.contains(s) {
                    return Err(input(format!(
                        "--sensors: `{s}` is not a sensor of {} (have: {})",
                        self.data.display(),
                        names.join(", ")
                    )));
                }
            }
            names.retain(|s| self.sensors.contains(s));
        }
        if names.is_empty() {
            return Err(input(format!(
                "{}: no `*_degC` sensor columns",
                self.data.display()
            )));
        }
        names
            .iter()
            .map(|s| {
                Ok(Series {
                    name: s.clone(),
                    values: ds.numeric(&format!("{s}_degC"))?.to_vec(),
                })
            })
            .collect()
    }

    /// The `*_N` force columns (none with `--no-forces`; at most 3, as the firmware takes).
    fn read_forces(&self, ds: &Dataset) -> Result<Vec<Series>, RequestError> {
        let forces: Vec<Series> = if self.no_forces {
            vec![]
        } else {
            ds.column_names()
                .into_iter()
                .filter(|c| c.len() > 2 && c.ends_with("_N"))
                .map(|c| {
                    Ok(Series {
                        name: c.to_string(),
                        values: ds.numeric(c)?.to_vec(),
                    })
                })
                .collect::<Result<Vec<_>, RequestError>>()?
        };
        if forces.len() > 3 {
            return Err(input(format!(
                "{} force columns (`*_N`); the firmware takes at most 3 (use --no-forces or --rename)",
                forces.len()
            )));
        }
        Ok(forces)
    }

    /// An explicit NaN or inf is no value the fit can use: named by file, line and column here (the fit
    /// itself only knows the data row).
    fn check_finite(
        &self,
        ds: &Dataset,
        target: &[f64],
        time_s: &[f64],
        sensors: &[Series],
        forces: &[Series],
    ) -> Result<(), RequestError> {
        let mut used: Vec<(String, &[f64])> = vec![(self.target.clone(), target)];
        if ds.time_s().is_some() {
            used.push(("time_s".into(), time_s));
        }
        used.extend(
            sensors
                .iter()
                .map(|s| (format!("{}_degC", s.name), s.values.as_slice())),
        );
        used.extend(forces.iter().map(|f| (f.name.clone(), f.values.as_slice())));
        for (col, values) in &used {
            if let Some(row) = values.iter().position(|v| !v.is_finite()) {
                return Err(input(format!(
                    "{}: `{}` is not a finite number; remove the row or fill in the value",
                    ds.locate(col, row),
                    values[row]
                )));
            }
        }
        Ok(())
    }

    /// A force column that does not vary on the training rows (e.g. a `force_N` of zeros in a record
    /// without load) cannot be told from the intercept: it is left out with a note, as a constant sensor is.
    fn drop_constant_forces(
        &self,
        mut forces: Vec<Series>,
        held: Option<&[bool]>,
        laws: &[(String, ModelForceLaw)],
        notice: &mut dyn FnMut(String),
    ) -> Result<(Vec<Series>, Vec<String>), RequestError> {
        let mut excluded: Vec<String> = Vec::new();
        forces.retain(|f| {
            let train = f
                .values
                .iter()
                .enumerate()
                .filter(|(i, _)| !held.is_some_and(|h| h[*i]))
                .map(|(_, v)| *v);
            let (lo, hi) = train.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            });
            let constant = hi - lo <= 1e-9 * hi.abs().max(lo.abs()).max(1.0);
            if constant {
                excluded.push(f.name.clone());
            }
            !constant
        });
        for name in &excluded {
            if laws.iter().any(|(col, _)| col == name) {
                return Err(input(format!(
                    "--force-law {name}: the force column `{name}` is constant on the training rows, so the \
                     model has no force term to attach the law to"
                )));
            }
            notice(format!(
                "note: {}: force column `{name}` is constant on the training rows: left out of the model",
                self.data.display()
            ));
        }
        Ok((forces, excluded))
    }

    /// Single-sample glitches and stretches where the target stops while the temperatures move; each
    /// reported to `notice` as a warning naming file, line and column.
    pub fn row_quality(
        &self,
        ds: &Dataset,
        input: &ThermalInput,
        notice: &mut dyn FnMut(String),
    ) -> RowQuality {
        let quality_runs = RunIndex::new(input.runs.as_deref(), ds.n_rows());
        let mut quality_cols: Vec<(&str, &[f64])> = vec![(self.target.as_str(), &input.target)];
        quality_cols.extend(
            input
                .sensors
                .iter()
                .map(|s| (s.name.as_str(), s.values.as_slice())),
        );
        let glitches = crate::quality::glitches(&quality_cols, &quality_runs);
        for g in &glitches {
            let col = if g.column == self.target {
                g.column.clone()
            } else {
                format!("{}_degC", g.column)
            };
            notice(format!(
                "warning: {}: `{}` has {} single-sample glitch(es) (first: {})",
                self.data.display(),
                g.column,
                g.rows.len(),
                ds.locate(col.as_str(), g.rows[0] - 1)
            ));
        }
        let sensor_refs: Vec<&[f64]> = input.sensors.iter().map(|s| s.values.as_slice()).collect();
        let stopped =
            crate::quality::stopped(&input.target, &sensor_refs, &input.time_s, &quality_runs);
        if let Some(s) = stopped.first() {
            notice(format!(
                "warning: {}: `{}` holds still while the temperatures move on {} stretch(es) (first: \
                 data rows {}–{}, {:.0} s, a sensor moved {:.1} K): a stopped measurement? (e.g. --where to keep \
                 the rows where the machine runs)",
                self.data.display(),
                self.target,
                stopped.len(),
                s.from_row,
                s.to_row,
                s.duration_s,
                s.sensor_change_k
            ));
        }
        RowQuality { glitches, stopped }
    }

    /// The fit's JSON: the fit, the data, the target and its offset, whether the model is written, the notes
    /// and the row quality.
    pub fn json(
        &self,
        fit: &ThermalFit,
        read: &ReadInput,
        quality: &RowQuality,
        model_written: bool,
    ) -> Result<Value, serde_json::Error> {
        let mut v = serde_json::to_value(fit)?;
        let o = v.as_object_mut().expect("fit serializes to an object");
        o.insert("data".into(), self.data.display().to_string().into());
        o.insert("target".into(), self.target.clone().into());
        o.insert("target_offset_um".into(), read.target_offset_um.into());
        o.insert("model_written".into(), model_written.into());
        if let Some(note) = &read.lags_note {
            o.insert("lags_note".into(), note.clone().into());
        }
        o.insert(
            "excluded_forces".into(),
            read.excluded_forces.clone().into(),
        );
        o.insert(
            "row_quality".into(),
            serde_json::json!({ "glitches": quality.glitches, "stopped_target": quality.stopped }),
        );
        Ok(v)
    }

    /// The model file of the fit: target offset, runs column and the force laws attached; validated.
    pub fn model_file(
        &self,
        fit: &ThermalFit,
        read: &ReadInput,
        laws: &[(String, ModelForceLaw)],
    ) -> Result<ThermalModelFile, RequestError> {
        let mut file =
            ThermalModelFile::from_fit(fit, &read.input, &self.target, self.sensor_period_ms);
        if self.zero_at_start.is_some() {
            file.target_offset_um = Some(read.target_offset_um);
        }
        file.runs_column = self.runs.clone();
        for (col, law) in laws {
            let f = file
                .forces
                .iter_mut()
                .find(|f| &f.column == col)
                .expect("checked before fitting");
            f.law = Some(*law);
        }
        file.validate()
            .map_err(|e| input(format!("model not written: {e}")))?;
        Ok(file)
    }
}

/// The fit's result as printed: formula, sensors and method, the candidates and references with their
/// validation RMS, the held-out or training RMS, the CV RMS, the condition number and the guard.
pub fn summary(fit: &ThermalFit, target: &str) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(s, "target {target}: {}", fit.formula);
    let _ = writeln!(
        s,
        "sensors: {} (method {}: {})",
        fit.sensors.join(", "),
        fit.chosen_method,
        fit.why
    );
    for c in &fit.candidates {
        let _ = writeln!(
            s,
            "  candidate {:<13} validation RMS {:>10.4} µm{}{}{}",
            c.name,
            c.validation_rms_um,
            if !c.eligible {
                "  (reported only)"
            } else if c.beats_reference {
                "  (below plain LS)"
            } else {
                ""
            },
            c.holdout_rms_um
                .map_or(String::new(), |h| format!("  (held-out {h:.4} µm)")),
            if c.chosen { "  ← chosen" } else { "" }
        );
    }
    for r in &fit.references {
        let _ = writeln!(
            s,
            "  reference {:<13} validation RMS {:>10.4} µm{}",
            r.name,
            r.validation_rms_um,
            r.holdout_rms_um
                .map_or(String::new(), |h| format!("  (held-out {h:.4} µm)"))
        );
    }
    let _ = match fit.holdout_rms_um {
        Some(h) => writeln!(
            s,
            "held-out RMS: raw {:.3} µm → {:.3} µm ({} rows; raw = target − {:.3} µm, its reference value)",
            fit.raw_rms_um, h, fit.holdout_rows, fit.raw_reference_um
        ),
        None => writeln!(
            s,
            "RMS: raw {:.3} µm, training residual {:.3} µm",
            fit.raw_rms_um, fit.train_rms_um
        ),
    };
    if let Some(cv) = fit.cv_rms_um {
        let _ = writeln!(
            s,
            "leave-one-group-out CV RMS (conditions or runs): {cv:.3} µm"
        );
    }
    let _ = writeln!(
        s,
        "condition number {:.1}; guard: {}",
        fit.condition_number, fit.guard.reason
    );
    s
}
